"""DELETE /jobs/{id}: a queued calibration is cancelled at once, a running one by stopping its worker, a
running capture between pairs; a finished job cannot be cancelled."""

from __future__ import annotations

import time

from api_helpers import Server, gone, perturbed_truth, simulated_dataset, wait_job, wait_running, worker_pid


def test_cancel_queued_and_running_jobs(tmp_path):
    data = tmp_path / "data"
    dataset = simulated_dataset(data, "ds", pairs=3)
    server = Server(data).start()
    try:
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
            # The sensors are free again.
            again = client.post("/capture", json={"dataset": "cut", "n": 1})
            assert again.status_code == 202
            wait_job(client, again.json()["id"])
    finally:
        server.stop()
