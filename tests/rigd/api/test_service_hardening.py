"""A careless or hostile client (issues 15, 33): text that is not Unicode, bodies nested hundreds of levels
deep, values beyond physical bounds, symlinks out of the data directory, bodies that never arrive, a full
queue, a second service on the same data directory, a deleted data directory, a camera without its SDK
layout."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
import time

import pytest
import yaml
from api_helpers import (
    REPO,
    App,
    Server,
    free_port,
    gone,
    perturbed_truth,
    simulated_dataset,
    wait_job,
    wait_running,
    worker_pid,
)
from hypothesis import given
from hypothesis import strategies as st

from rigd.api.main import json_nesting
from rigd.api.models import CalibrateIn
from rigd.calibration.request import MAX_NESTING, PriorIn, ToleranceIn, body_problem
from rigd.cli.exit_codes import ERROR

JSON = {"Content-Type": "application/json"}
IDENTITY = {"rpy_deg": [0, 0, 0], "xyz_m": [0, 0, 0]}
BODY_TIMEOUT_S = 1.5


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    data = tmp_path_factory.mktemp("hardening") / "data"
    simulated_dataset(data, "ds", pairs=1)
    server = Server(data, env={"RIGD_BODY_TIMEOUT_S": str(BODY_TIMEOUT_S)}).start()
    yield server
    server.stop()


@pytest.mark.parametrize("path, body", [
    ("/calibrate", b'{"dataset": "\\ud800", "init": "rig"}'),  # refused by the id pattern, which echoes it
    ("/calibrate", b'{"dataset": "ds", "\\udfff": 1}'),  # an unknown key, named in the error
    ("/extrinsics/versions", b'{"T_camera_lidar": {"rpy_deg": [0, 0, 0], "xyz_m": [0, 0, 0]}, "note": "a\\ud800b"}'),
])
def test_lone_surrogates_are_refused_not_a_server_error(server, path, body):
    with server.client() as client:
        response = client.post(path, content=body, headers=JSON)
        assert response.status_code == 422, response.text
        assert "\\ud800" in response.text or "\\udfff" in response.text or "surrogate" in response.text
        # Nothing was stored that could not be read back.
        listed = client.get("/extrinsics/versions")
        assert listed.status_code == 200 and all(v["parameters"].get("note") != "a\ud800b" for v in listed.json())


def nested(depth: int) -> str:
    """JSON ``depth`` levels deep, arrays and objects in turn."""
    return "".join('[' if i % 2 else '{"a": ' for i in range(depth)) + "0" + "".join(
        ']' if i % 2 else '}' for i in reversed(range(depth)))


@pytest.mark.parametrize("path, body", [
    ("/calibrate", '{"dataset": "ds", "init": "rig", "x": ' + "[" * 330 + "]" * 330 + "}"),  # issue 33's 1 KB body
    ("/calibrate", '{"dataset": "ds", "init": {"matrix": ' + "[" * 900 + "]" * 900 + "}}"),
    ("/extrinsics/versions", '{"T_camera_lidar": ' + nested(3000) + "}"),
    ("/check", "[" * 30000 + "]" * 30000),  # 60 KB: within the body limit, too deep for Python's JSON parser
    ("/capture", '{"dataset": "x", "n": ' + nested(17) + "}"),
])
def test_deeply_nested_bodies_are_refused_not_a_server_error(server, path, body):
    with server.client() as client:
        jobs = len(client.get("/jobs").json())
        response = client.post(path, content=body.encode(), headers=JSON)
        assert response.status_code == 422, response.text[:300]
        assert f"at most {MAX_NESTING} are accepted" in response.json()["detail"]
        assert len(client.get("/jobs").json()) == jobs
    assert "Traceback" not in server.log_path.read_text()


def test_brackets_in_text_and_bodies_at_the_nesting_limit_are_not_refused_for_depth(server):
    with server.client() as client:
        note = "[{" * 200 + '\\"' + "]" * 3
        stored = client.post("/extrinsics/versions", json={"T_camera_lidar": IDENTITY, "note": note})
        assert stored.status_code == 201, stored.text
        assert stored.json()["parameters"]["note"] == note
        limit = client.post("/calibrate", content=('{"dataset": "ds", "x": ' + nested(MAX_NESTING - 1) + "}").encode(),
                            headers=JSON)
        assert limit.status_code == 422 and limit.json()["detail"][0]["type"] == "extra_forbidden", limit.text


def depth(value: object) -> int:
    if isinstance(value, dict | list):
        return 1 + max(map(depth, value.values() if isinstance(value, dict) else value), default=0)
    return 0


JSON_VALUES = st.recursive(st.none() | st.booleans() | st.floats(allow_nan=False) | st.text(alphabet='[]{}"\\ab'),
                           lambda inner: st.lists(inner, max_size=3) | st.dictionaries(
                               st.text(alphabet='[]{}"\\ab'), inner, max_size=3), max_leaves=30)


@given(JSON_VALUES)
def test_json_nesting_counts_the_levels_of_objects_and_arrays(value):
    assert json_nesting(json.dumps(value).encode()) == depth(value)
    assert json_nesting(json.dumps(value, ensure_ascii=False).encode()) == depth(value)


def test_the_models_bound_the_nesting_without_recursion():
    deep: list = []
    for _ in range(100_000):
        deep = [deep]
    problem = body_problem({"a": deep})
    assert problem is not None and f"nested more than {MAX_NESTING} levels deep" in problem


IDENTITY_BODY = {"dataset": "ds", "init": IDENTITY}


@pytest.mark.parametrize("path, body, field, bounds", [
    ("/calibrate", {**IDENTITY_BODY, "tolerance": {"rotation_deg": 1e-300}}, "rotation_deg", "0.001 .. 10 deg"),
    ("/calibrate", {**IDENTITY_BODY, "tolerance": {"translation_cm": 1e-300}}, "translation_cm", "0.01 .. 100 cm"),
    ("/calibrate", {**IDENTITY_BODY, "tolerance": {"rotation_deg": 45}}, "rotation_deg", "0.001 .. 10 deg"),
    ("/check", {"dataset": "ds", "against": IDENTITY, "threshold": {"rotation_deg": 1e-300, "translation_cm": 1}},
     "rotation_deg", "0.001 .. 10 deg"),
    ("/check", {"dataset": "ds", "against": IDENTITY, "threshold": {"translation_cm": 500}}, "translation_cm",
     "0.01 .. 100 cm"),
    ("/calibrate", {**IDENTITY_BODY, "prior": {"xyz_m": [0, 0, 0], "sigma_cm": 1e-300}}, "sigma_cm",
     "0.01 .. 1000 cm"),
    ("/calibrate", {**IDENTITY_BODY, "prior": {"rpy_deg": [0, 0, 0], "sigma_deg": 1e-300}}, "sigma_deg",
     "0.001 .. 180 deg"),
    ("/calibrate", {**IDENTITY_BODY, "sigmas_deg": [5.0, 1e-300]}, "sigmas_deg", "0.1 .. 30 deg"),
])
def test_values_beyond_physical_bounds_are_refused_naming_the_range(server, path, body, field, bounds):
    with server.client() as client:
        jobs = len(client.get("/jobs").json())
        response = client.post(path, json=body)
        assert response.status_code == 422, response.text
        errors = [e for e in response.json()["detail"] if field in e["loc"]]
        assert errors and f"must be within {bounds}" in errors[0]["msg"], response.text
        assert len(client.get("/jobs").json()) == jobs


def test_the_bounds_themselves_are_accepted():
    assert ToleranceIn(rotation_deg=0.001, translation_cm=0.01) and ToleranceIn(rotation_deg=10, translation_cm=100)
    assert PriorIn(xyz_m=[0, 0, 0], sigma_cm=0.01, rpy_deg=[0, 0, 0], sigma_deg=0.001)
    assert CalibrateIn(dataset="ds", sigmas_deg=[0.1, 30.0])


def test_symlinks_out_of_the_datasets_folder_are_refused(server, tmp_path):
    outside = simulated_dataset(tmp_path, "outside", pairs=1)
    (server.data_dir / "datasets" / "linked").symlink_to(outside, target_is_directory=True)
    inner = server.data_dir / "datasets" / "inner"
    shutil.copytree(server.data_dir / "datasets" / "ds", inner)
    image = next((inner / "pairs" / "0000").glob("image.*"))
    image.unlink()
    image.symlink_to(next((outside / "pairs" / "0000").glob("image.*")))
    before = sorted(p.relative_to(outside) for p in outside.rglob("*"))
    with server.client() as client:
        for dataset in ("linked", "inner"):
            detail = client.get(f"/datasets/{dataset}")
            assert detail.status_code == 422, detail.text
            assert "is a symbolic link" in detail.json()["detail"]
            assert "datasets must be folders and files inside" in detail.json()["detail"]
            calibrate = client.post("/calibrate", json={"dataset": dataset, "init": IDENTITY})
            assert calibrate.status_code == 422, calibrate.text
            capture = client.post("/capture", json={"dataset": dataset, "source": "sim", "n": 1})
            assert capture.status_code == 422, capture.text
        assert "datasets/linked is a symbolic link" in client.get("/datasets/linked").json()["detail"]
        assert "pairs/0000/image.png is a symbolic link" in client.get("/datasets/inner").json()["detail"]
        listed = {d["id"]: d for d in client.get("/datasets").json()}
        assert listed["linked"]["error"] and listed["inner"]["error"] and listed["ds"]["error"] is None
    assert sorted(p.relative_to(outside) for p in outside.rglob("*")) == before  # nothing written out there


def raw_request(server: Server, body: bytes, length: int, pause_s: float = 0.0) -> tuple[bytes, float]:
    """POST a version with ``Content-Length: length``, sending ``body`` in two halves ``pause_s`` apart; the
    whole answer (read until the server closes, at most 10 s) and the seconds it took."""
    head = (f"POST /extrinsics/versions HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            f"Content-Length: {length}\r\nConnection: close\r\n\r\n").encode()
    with socket.create_connection(("127.0.0.1", server.port), timeout=10.0) as sock:
        start = time.monotonic()
        sock.sendall(head + body[:len(body) // 2])
        time.sleep(pause_s)
        sock.sendall(body[len(body) // 2:])
        answer = b""
        while chunk := sock.recv(65536):  # socket.timeout (a failure) if the server holds the connection
            answer += chunk
        return answer, time.monotonic() - start


def test_a_body_that_does_not_arrive_gets_408(server):
    answer, seconds = raw_request(server, b'{"note": "', length=100)
    assert answer.startswith(b"HTTP/1.1 408 "), answer
    assert b"the request body did not arrive within 1.5 s" in answer
    assert BODY_TIMEOUT_S <= seconds < BODY_TIMEOUT_S + 3


def test_a_slow_body_within_the_timeout_is_served(server):
    body = b'{"T_camera_lidar": {"rpy_deg": [0, 0, 0], "xyz_m": [0, 0, 0]}, "note": "slow"}'
    answer, _ = raw_request(server, body, length=len(body), pause_s=BODY_TIMEOUT_S / 3)
    assert answer.startswith(b"HTTP/1.1 201 "), answer


def test_the_queue_is_bounded_and_an_identical_request_gets_the_same_job(tmp_path):
    data = tmp_path / "data"
    dataset = simulated_dataset(data, "ds", pairs=3)
    server = App(data, env={"RIGD_MAX_QUEUED_JOBS": "2"}).start()  # the runner's queue: no process needed
    try:
        with server.client() as client:
            body = {"dataset": "ds", "init": perturbed_truth(dataset)}
            first = client.post("/calibrate", json=body)
            again = client.post("/calibrate", json=body)
            assert first.status_code == 202 and again.status_code == 200, again.text
            assert again.json()["id"] == first.json()["id"]
            assert again.headers["Location"] == first.headers["Location"]

            # Different requests (other sigmas): two may wait behind the first, the rest are refused. The first
            # leaves the queue when it starts running, which on a loaded machine may fall within these requests.
            responses = [client.post("/calibrate", json={**body, "sigmas_deg": [float(s)]}) for s in range(1, 7)]
            codes = [r.status_code for r in responses]
            accepted = codes.count(202)
            assert codes[0] == 202 and 1 <= accepted <= 3 and codes.count(429) == 6 - accepted, codes
            refused = next(r for r in reversed(responses) if r.status_code == 429)
            assert int(refused.headers["Retry-After"]) > 0
            assert "2 calibrations are queued already" in refused.json()["detail"]

            unfinished = [j["id"] for j in client.get("/jobs").json() if j["status"] in ("queued", "running")]
            assert len(unfinished) == 1 + accepted  # the refused ones left no job behind
            for job_id in unfinished:
                client.delete(f"/jobs/{job_id}")
            for job_id in unfinished:
                wait_job(client, job_id)
            # Once the first one has finished, the same request is a new job.
            later = client.post("/calibrate", json=body)
            assert later.status_code == 202 and later.json()["id"] > max(unfinished)
            client.delete(f"/jobs/{later.json()['id']}")
    finally:
        server.stop()


def test_a_second_service_on_the_same_data_dir_exits(server):
    """On the module's service. That a stopped service releases the directory to the next start is shown by every
    restart: test_service_flow.py's and test_service_crash.py's."""
    data = server.data_dir
    guess = perturbed_truth(data / "datasets" / "ds")
    with server.client() as client:
        job = client.post("/calibrate", json={"dataset": "ds", "init": guess}).json()
        second = subprocess.run([sys.executable, "-m", "rigd", "serve", "--port", str(free_port())],
                                env=server.env, cwd=REPO, capture_output=True, text=True, timeout=30)
        assert second.returncode == ERROR, second.stderr
        assert f"rigd: error: data directory {data} is in use by another rigd serve (pid {server.proc.pid})" in (
            second.stderr)
        assert "Traceback" not in second.stderr
        # The first one's job was left alone: it was not marked interrupted, and it completes.
        done = wait_job(client, job["id"])
        assert done["status"] == "succeeded", done
        assert client.get(done["result_link"]).json()["job_id"] == job["id"]


@pytest.mark.parametrize("replace", [False, True], ids=["deleted", "replaced"])
def test_a_deleted_data_dir_answers_503_and_acknowledges_no_write(tmp_path, replace):
    data = tmp_path / "data"
    server = App(data).start()  # the store's answers: in this process
    try:
        with server.client() as client:
            stored = client.post("/extrinsics/versions", json={"T_camera_lidar": IDENTITY})
            assert stored.status_code == 201
            shutil.rmtree(data)
            if replace:  # e.g. a backup restored under the running service
                data.mkdir()
                (data / "rigd.db").write_bytes(b"")
            write = client.post("/extrinsics/versions", json={"T_camera_lidar": IDENTITY, "note": "lost"})
            assert write.status_code == 503, write.text  # never 201 for a version nobody will read back
            assert "restart rigd serve" in write.json()["detail"]
            status = client.get("/status")
            assert status.status_code == 503, status.text
            assert f"{data / 'rigd.db'}: the database was deleted or replaced" in status.json()["detail"]
            assert client.get("/extrinsics/versions").status_code == 503
        assert not (data / "rigd.db").exists() or (data / "rigd.db").stat().st_size == 0  # nothing recreated
    finally:
        server.kill()


def test_a_data_dir_deleted_under_a_calibration_stops_its_worker_and_keeps_the_service_up(tmp_path):
    data = tmp_path / "data"
    dataset = simulated_dataset(data, "ds", pairs=3)
    server = Server(data).start()
    try:
        with server.client() as client:
            job = client.post("/calibrate", json={"dataset": "ds", "init": perturbed_truth(dataset)}).json()
            pid = worker_pid(wait_running(client, job["id"])["log_tail"])
            shutil.rmtree(data)
            deadline = time.monotonic() + 30
            while not gone(pid):  # its next progress cannot be recorded: the runner stops it
                assert time.monotonic() < deadline, f"worker {pid} still runs with nowhere to store its result"
                time.sleep(0.1)
            assert server.proc.poll() is None
            status = client.get("/status")
            assert status.status_code == 503 and "deleted or replaced" in status.json()["detail"]
        said = f"rigd: job {job['id']} stopped, its record cannot be written"
        deadline = time.monotonic() + 10  # logged just after the worker was reaped
        while said not in (log := server.log_path.read_text()):
            assert time.monotonic() < deadline, log
            time.sleep(0.1)
        assert str(data / "rigd.db") in log
    finally:
        server.kill()


def test_a_capture_without_the_sdk_layout_says_how_to_get_it(tmp_path):
    layout = tmp_path / "etc" / "ladybug_layout.yaml"  # the capture's error: in this process
    rig = tmp_path / "rig.yaml"
    rig.write_text(yaml.safe_dump({
        "camera": {"model": "equirectangular", "width": 256, "height": 128, "source": "sdk",
                   "sdk": {"layout": str(layout)}},
        "lidar": {"model": "VLP-16", "source": f"udp:127.0.0.1:{free_port()}"},  # silent: the camera fails first
    }))
    server = App(tmp_path / "data", env={"RIGD_CONFIG": str(rig)}).start()
    try:
        with server.client() as client:
            job = client.post("/capture", json={"dataset": "live", "n": 1}).json()
            error = wait_job(client, job["id"], timeout_s=60)["error"]
    finally:
        server.stop()
    assert str(layout) in error  # the file ...
    # ... and the fix: where the file comes from, and the setting that names it.
    assert "install FLIR's Ladybug SDK" in error
    assert f"rigd camera sdk-layout --include /usr/include/ladybug --out {layout}" in error
    assert "camera.sdk.layout" in error
