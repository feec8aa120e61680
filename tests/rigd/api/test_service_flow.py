"""The service end to end over HTTP: capture (simulated rig) -> calibrate -> job polling -> versions ->
activate -> export, field recalibration from the active version, and a restart that keeps versions and jobs.

Tests on data directories of their own, so that none runs more than one calibration: the capture and the first
calibration of what it captured, and the calibrations from an active version, on rigd's app in this process
(route behaviour); activation, exports and the restart on a real ``rigd serve`` (a process stopped with SIGTERM
and started again)."""

from __future__ import annotations

import json
import signal
import time

import cv2
import numpy as np
import pytest
import yaml
from api_helpers import RIG_GUESS, App, Server, matrix, perturbed_truth, simulated_dataset, wait_job
from scipy.spatial.transform import Rotation

from calib.geometry import Transform
from rigd.dataset import open_dataset
from rigd.store.datasets import content_hash

AUTO_ACTIVATE = {"RIGD_AUTO_ACTIVATE_MIN_PAIRS": "2"}


@pytest.fixture
def app(tmp_path):
    app = App(tmp_path / "data", env=AUTO_ACTIVATE).start()
    yield app
    app.stop()


def calibrate(client, body):
    response = client.post("/calibrate", json=body)
    assert response.status_code == 202, response.text
    job = response.json()
    assert response.headers["Location"] == f"/jobs/{job['id']}"
    assert job["status"] in {"queued", "running"} and job["kind"] == "calibrate"
    return wait_job(client, job["id"])


def capture(client):
    """Capture 2 pairs from the simulated rig (the rig file's sources) into dataset "field"."""
    response = client.post("/capture", json={"dataset": "field", "n": 2, "still_seconds": 0.5})
    assert response.status_code == 202, response.text
    job = response.json()
    assert response.headers["Location"] == f"/jobs/{job['id']}" and job["kind"] == "capture"
    # The sensors are taken: a second capture is refused, the first one shows in the status.
    assert client.post("/capture", json={"dataset": "other"}).status_code == 409
    status = client.get("/status").json()
    assert [j["id"] for j in status["running_jobs"]] == [job["id"]]
    assert status["sensors"]["lidar"]["source"].startswith("sim:")
    # Once its rig.yaml is written the dataset is listed, and cannot be calibrated until complete.
    while (listed := client.get("/datasets").json()) == [] and client.get(f"/jobs/{job['id']}").json()[
            "status"] == "running":
        time.sleep(0.1)
    if listed and listed[0]["capturing"]:
        assert client.post("/calibrate", json={"dataset": "field", "init": "rig"}).status_code == 409
    done = wait_job(client, job["id"])
    assert done["status"] == "succeeded", done
    assert done["result"]["pairs_written"] == 2 and done["result_link"] == "/datasets/field"
    again = client.post("/capture", json={"dataset": "field", "n": 2})  # the sensors are free again ...
    assert again.status_code == 202
    assert wait_job(client, again.json()["id"])["result"]["pairs_written"] == 0  # ... and the dataset complete
    return done


def test_capture_then_calibrate_the_captured_dataset(app):
    with app.client() as client:
        capture(client)
        dataset = client.get("/datasets/field").json()
        assert dataset["pair_count"] == 2 and [p["number"] for p in dataset["pairs"]] == [0, 1]
        assert np.allclose(dataset["initial_guess"]["rpy_deg"], RIG_GUESS["rpy_deg"])  # the rig file's guess
        truth = Transform.from_matrix(matrix(dataset["ground_truth"]))

        # No version yet: "active" cannot be the start.
        assert client.post("/calibrate", json={"dataset": "field", "init": "active"}).status_code == 409
        first = calibrate(client, {"dataset": "field", "init": "rig"})
        assert first["status"] == "succeeded", first
        assert first["fraction"] == 1.0 and first["started_at"] and first["finished_at"]
        assert any("stored extrinsics version 1" in line for line in first["log_tail"])
        assert first["result_link"] == "/extrinsics/versions/1"
        v1 = client.get(first["result_link"]).json()
        # The first version becomes active by itself (there was none) only if its own verdict trusts it; an
        # untrusted one waits for a person to activate it.
        assert v1["supersedes"] is None and v1["change"] is None
        assert v1["status"] == ("active" if v1["verdict"]["status"] == "trusted" else "candidate")
        if v1["status"] == "candidate":
            assert client.post("/extrinsics/versions/1/activate").json()["status"] == "active"
        # Its quality figures describe its own transform: the error against the simulator's truth, recomputed.
        R = matrix(v1["T_camera_lidar"])[:3, :3]
        error = v1["quality"]["error_vs_ground_truth"]
        rotation_error_deg = np.degrees(Rotation.from_matrix(R.T @ truth.rotation).magnitude())
        assert error["rotation_deg"] == pytest.approx(rotation_error_deg)
        assert error["translation_cm"] == pytest.approx(
            100 * np.linalg.norm(matrix(v1["T_camera_lidar"])[:3, 3] - truth.translation_m))
        request = v1["parameters"]["request"]
        assert request["start"] == "rig" and np.allclose(
            Transform.from_matrix(np.array(request["initial"]["matrix"])).rpy_deg, RIG_GUESS["rpy_deg"])
        assert v1["quality"]["start"] == {"source": "rig", "choice": "the rig file's initial guess", "why": "asked for"}
        assert v1["dataset_id"] == "field" and v1["dataset_hash"].startswith("sha256:")
        assert v1["job_id"] == first["id"] and v1["code_version"]
        check_overlays(client, v1)


@pytest.fixture
def field(app):
    """(app, dataset "field", version 1): a simulated dataset, and a version measured elsewhere as the active one
    that calibrations start from and are compared with."""
    dataset = simulated_dataset(app.data_dir, "field")
    with app.client() as client:
        stored = client.post("/extrinsics/versions", json={"T_camera_lidar": RIG_GUESS, "activate": True})
    assert stored.status_code == 201 and stored.json()["status"] == "active"
    return app, dataset, stored.json()


def test_without_auto_activate_a_result_stays_a_candidate(field):
    app, dataset, _ = field
    with app.client() as client:
        start = perturbed_truth(dataset, (-1.0, -1.0, -1.0), (0.02, 0.02, 0.02))
        second = calibrate(client, {"dataset": "field", "init": start, "sigmas_deg": [4.0, 2.0]})
        v2 = client.get(second["result_link"]).json()
        assert v2["status"] == "candidate"
        assert [level["sigma_in_deg"] for level in v2["quality"]["levels"]] == [4.0, 2.0]  # the schedule asked for
        assert v2["dataset_hash"] == content_hash(open_dataset(dataset))  # the files' hash, whichever job hashed them


def test_recalibration_from_the_active_version_reports_its_change(field):
    app, dataset, v1 = field
    with app.client() as client:
        # Field recalibration from the active version: the change against it is reported.
        second = calibrate(client, {"dataset": "field", "init": "active", "auto_activate": True})
        v2 = client.get(second["result_link"]).json()
        request = v2["parameters"]["request"]
        assert request["start"] == "active" and request["start_version"] == 1
        assert v2["supersedes"] == 1 and v2["change"]["against"] == 1
        delta = matrix(v1["T_camera_lidar"]) @ np.linalg.inv(matrix(v2["T_camera_lidar"]))
        assert v2["change"]["rotation_deg"] == pytest.approx(
            np.degrees(Rotation.from_matrix(delta[:3, :3]).magnitude()), abs=1e-6)
        t1, t2 = matrix(v1["T_camera_lidar"])[:3, 3], matrix(v2["T_camera_lidar"])[:3, 3]
        assert v2["change"]["translation_cm"] == pytest.approx(np.linalg.norm(t2 - t1) * 100, abs=1e-6)
        assert v2["dataset_hash"] == content_hash(open_dataset(dataset))  # same files, same hash
        # auto_activate: the service's bounds (verdict trusted, converged, >= 2 pairs here, <= 5 deg and <= 10 cm
        # of change). The verdict and uncertainty are stored with the version and shown at its top level.
        assert v2["verdict"] == v2["quality"]["verdict"] and v2["verdict"]["status"] in ("trusted", "weak", "failed")
        assert len(v2["uncertainty"]["rpy_deg"]) == 3 and len(v2["uncertainty"]["covariance"]) == 6
        expected_failures = [v2["verdict"]["status"] != "trusted", not v2["quality"]["converged"],
                             v2["quality"]["pairs_used"] < 2,
                             v2["change"]["rotation_deg"] > 5.0, v2["change"]["translation_cm"] > 10.0]
        checks = second["result"]["auto_activate"]
        assert checks["requested"] is True and len(checks["failed_checks"]) == sum(expected_failures)
        assert v2["status"] == ("candidate" if any(expected_failures) else "active")


def test_activation_exports_and_a_restart_that_keeps_versions_and_jobs(tmp_path):
    simulated_dataset(tmp_path / "data", "field")
    server = Server(tmp_path / "data").start()
    try:
        with server.client() as client:
            for number, activate in ((1, True), (2, True), (3, False)):  # 2 supersedes 1; 3 is a candidate
                transform = {"rpy_deg": [0.0, 15.0, -55.0 + number], "xyz_m": [0.09, 0.06, -0.17]}
                stored = client.post("/extrinsics/versions", json={"T_camera_lidar": transform, "activate": activate})
                assert stored.status_code == 201 and stored.json()["number"] == number
            v1 = client.get("/extrinsics/versions/1").json()
            # A job to outlive the restart: a capture into a complete dataset, which has nothing left to take.
            job = client.post("/capture", json={"dataset": "field", "n": 2}).json()
            assert wait_job(client, job["id"])["result"]["pairs_written"] == 0

            # Activate version 1 again: it becomes the active one, the others are not.
            response = client.post("/extrinsics/versions/1/activate")
            assert response.status_code == 200 and response.json()["status"] == "active"
            statuses = {v["number"]: v["status"] for v in client.get("/extrinsics/versions").json()}
            assert statuses[1] == "active" and list(statuses.values()).count("active") == 1
            assert statuses[3] == "candidate"
            assert client.get("/extrinsics").json()["number"] == 1

            check_exports(client, matrix(v1["T_camera_lidar"]))
            versions_before = client.get("/extrinsics/versions").json()
            jobs_before = client.get("/jobs").json()

        assert server.stop() in (0, -signal.SIGTERM)  # uvicorn re-raises the signal after a clean shutdown
        server.start()
        with server.client() as client:
            assert client.get("/extrinsics/versions").json() == versions_before
            jobs_after = client.get("/jobs").json()
            assert [(j["id"], j["status"], j["result"]) for j in jobs_after] == [
                (j["id"], j["status"], j["result"]) for j in jobs_before]
            assert client.get("/status").json()["active_extrinsics"]["version"] == 1
    finally:
        if server.proc is not None and server.proc.poll() is None:
            server.stop()


def check_exports(client, T):
    """Every export read back with its own reader (YAML, JSON, OpenCV, scipy for quaternions) gives T."""
    def export(fmt):
        response = client.get("/extrinsics", params={"format": fmt})
        assert response.status_code == 200, response.text
        return response.text

    assert np.allclose(matrix(yaml.safe_load(export("yaml"))["T_camera_lidar"]), T, atol=1e-12)
    document = json.loads(export("json"))
    assert np.allclose(matrix(document["T_camera_lidar"]), T, atol=1e-12)
    assert document["extrinsics_version"] == 1
    assert np.allclose(yaml.safe_load(export("kalibr"))["cam0"]["T_cam_lidar"], T, atol=1e-12)

    tf = yaml.safe_load(export("ros-tf"))
    assert (tf["header"]["frame_id"], tf["child_frame_id"]) == ("camera", "velodyne")
    q = tf["transform"]["rotation"]
    assert np.allclose(Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]]).as_matrix(), T[:3, :3], atol=1e-9)
    t = tf["transform"]["translation"]
    assert np.allclose([t["x"], t["y"], t["z"]], T[:3, 3], atol=1e-12)

    fs = cv2.FileStorage(export("opencv"), cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    assert np.allclose(fs.getNode("T").mat(), T, atol=1e-12)
    assert np.allclose(fs.getNode("R").mat() @ np.ones(3) + fs.getNode("t").mat().ravel(), T[:3] @ [1, 1, 1, 1])
    assert client.get("/extrinsics", params={"format": "xml"}).status_code == 422


def check_overlays(client, version):
    assert version["overlays"] == [f"/extrinsics/versions/{version['number']}/overlays/{p}.png" for p in (0, 1)]
    images = {}
    for stage in ("before", "after"):
        response = client.get(version["overlays"][1], params={"stage": stage})
        assert response.status_code == 200 and response.headers["content-type"] == "image/png"
        images[stage] = cv2.imdecode(np.frombuffer(response.content, np.uint8), cv2.IMREAD_COLOR)
        assert images[stage].shape == (128, 256, 3)  # the dataset's panorama size
    assert np.any(images["before"] != images["after"])  # the points moved with the calibration
    closeup = client.get(version["overlays"][1], params={"stage": "closeup"})
    assert closeup.status_code == 200 and closeup.headers["content-type"] == "image/png"
    cloud = client.get(version["overlays"][1], params={"stage": "cloud"})
    assert cloud.status_code == 200 and cloud.headers["content-type"] == "image/png"
    cloud_image = cv2.imdecode(np.frombuffer(cloud.content, np.uint8), cv2.IMREAD_COLOR)
    assert cloud_image.shape[0] == cloud_image.shape[1] >= 400  # square, from above
    assert client.get(version["overlays"][1], params={"stage": "sideways"}).status_code == 422
    small = client.get(version["overlays"][1], params={"stage": "before", "width": 64})
    assert small.status_code == 200 and small.headers["content-type"] == "image/png"
    small_image = cv2.imdecode(np.frombuffer(small.content, np.uint8), cv2.IMREAD_COLOR)
    assert small_image.shape == (32, 64, 3)
    assert client.get(version["overlays"][1], params={"width": 10}).status_code == 422
    assert client.get(f"/extrinsics/versions/{version['number']}/overlays/7.png").status_code == 404
