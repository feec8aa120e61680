"""DELETE /jobs/{id}: a queued calibration is cancelled at once, a running one by stopping its worker and the
processes it started (in whatever stage it is), a running capture between pairs; a finished job cannot be
cancelled.

One real ``rigd serve`` for the module: every test leaves no job of its own unfinished and stores no version."""

from __future__ import annotations

import time
from typing import Any

import httpx
import pytest
from api_helpers import (
    FINISHED,
    POOL,
    Server,
    gone,
    perturbed_truth,
    process_group,
    simulated_dataset,
    wait_job,
    wait_running,
    worker_pid,
)

CANCEL_S = 5.0  # a cancelled job is cancelled within this, whatever its stage


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """(server, dataset): a server with room for a check behind a calibration, and a 2-pair dataset."""
    data = tmp_path_factory.mktemp("cancel") / "data"
    dataset = simulated_dataset(data, "ds", pairs=2)
    server = Server(data, env={"RIGD_MAX_QUEUED_JOBS": "8", **POOL}).start()
    yield server, dataset
    server.stop()


def test_cancel_queued_and_running_jobs(served):
    server, dataset = served
    with server.client() as client:
        body = {"dataset": "ds", "init": perturbed_truth(dataset)}
        first = client.post("/calibrate", json=body).json()
        # waits behind the first (other sigmas: the same request would be the first job again)
        second = client.post("/calibrate", json={**body, "sigmas_deg": [3.0, 1.5]}).json()
        assert second["id"] != first["id"]
        cancelled = client.delete(f"/jobs/{second['id']}")
        assert cancelled.status_code == 202 and cancelled.json()["status"] == "cancelled"

        running = wait_running(client, first["id"], "worker process")
        assert client.delete(f"/jobs/{first['id']}").status_code == 202
        done = wait_job(client, first["id"])
        assert done["status"] == "cancelled" and done["result"] is None
        pid = worker_pid(running["log_tail"])
        deadline = time.monotonic() + 10
        while not gone(pid):
            assert time.monotonic() < deadline, f"worker {pid} still runs after the cancel"
            time.sleep(0.05)
        assert client.get("/extrinsics/versions").json() == []  # neither stored a version
        assert client.delete(f"/jobs/{first['id']}").status_code == 409  # already finished
        assert wait_job(client, second["id"])["started_at"] is None  # it never ran

        capture = client.post("/capture", json={"dataset": "cut", "n": 5}).json()
        wait_running(client, capture["id"], "waiting_for_stop")
        assert client.delete(f"/jobs/{capture['id']}").status_code == 202
        stopped = wait_job(client, capture["id"], timeout_s=60)
        assert stopped["status"] == "cancelled"
        assert stopped["result"]["pairs_written"] < 5
        # The sensors are free again (that capture is cancelled too: taking its pair shows nothing more).
        again = client.post("/capture", json={"dataset": "cut", "n": 1})
        assert again.status_code == 202
        client.delete(f"/jobs/{again.json()['id']}")
        wait_job(client, again.json()["id"])


def wait_stage(client: httpx.Client, job_id: int, stage: str, timeout_s: float = 120.0) -> dict[str, Any]:
    """The job once its stage holds ``stage``."""
    deadline = time.monotonic() + timeout_s
    while stage not in (job := client.get(f"/jobs/{job_id}").json())["stage"]:
        assert job["status"] not in FINISHED and time.monotonic() < deadline, (stage, job)
        time.sleep(0.02)
    return job


@pytest.mark.parametrize("stage, request_", [  # the stage to cancel in; the request (each its own sigmas)
    ("hashing the dataset", {"sigmas_deg": [6.0, 3.0]}),
    ("global search", {"init": "search"}),
    ("optimising level", {"sigmas_deg": [5.0, 2.5]}),
    ("writing overlays", {"sigmas_deg": [4.0, 2.0]}),  # a short ladder: to the overlays sooner
], ids=["hashing", "search", "optimising", "overlays"])
def test_a_calibration_is_cancelled_within_seconds_in_every_stage_and_the_queue_moves_on(served, stage, request_):
    """Issue 33: the pool processes held the worker's pipe, so a cancel left the job cancelling and every later
    job queued for minutes. A check waits behind each calibration: it starts once the calibration is cancelled,
    and behind the last stage's it runs to the end."""
    server, dataset = served
    guess = perturbed_truth(dataset)
    with server.client() as client:
        job = client.post("/calibrate", json={"dataset": "ds", "init": guess, **request_}).json()
        check = client.post("/check", json={"dataset": "ds", "against": guess}).json()  # queued behind it
        assert check["status"] == "queued"
        pid = worker_pid(wait_running(client, job["id"])["log_tail"])
        wait_stage(client, job["id"], stage)
        if stage != "hashing the dataset":  # the worker, its two pool processes (and their tracker)
            assert len(process_group(pid)) >= 3, (stage, process_group(pid))
        asked = time.monotonic()
        cancelling = client.delete(f"/jobs/{job['id']}")
        assert cancelling.status_code == 202, cancelling.text
        done = wait_job(client, job["id"], timeout_s=CANCEL_S)
        print(f"cancel in {stage!r}: {time.monotonic() - asked:.2f} s")
        assert done["status"] == "cancelled" and done["result"] is None, done
        assert process_group(pid) == [], f"processes of worker {pid} outlived the cancel in {stage!r}"
        if stage == "writing overlays":
            assert wait_job(client, check["id"])["status"] == "succeeded"
        else:  # the queue moved on: the check's worker started; cancelled there, it shows nothing more
            wait_running(client, check["id"])
            client.delete(f"/jobs/{check['id']}")
            assert wait_job(client, check["id"])["status"] == "cancelled"
        assert client.get("/extrinsics/versions").json() == []
