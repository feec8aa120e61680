"""The service end to end over HTTP: dataset -> calibrate -> job polling -> versions -> activate -> export,
field recalibration from the active version, and a restart that keeps versions and jobs."""

from __future__ import annotations

import json
import signal

import cv2
import numpy as np
import pytest
import yaml
from api_helpers import Server, matrix, perturbed_truth, simulated_dataset, wait_job
from scipy.spatial.transform import Rotation

from rigd.dataset import open_dataset


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    data = tmp_path_factory.mktemp("flow") / "data"
    dataset = simulated_dataset(data, "indoor-a")
    server = Server(data, env={"RIGD_AUTO_ACTIVATE_MIN_PAIRS": "2"}).start()
    yield server, dataset
    if server.proc is not None and server.proc.poll() is None:
        server.stop()


def calibrate(client, body):
    response = client.post("/calibrate", json=body)
    assert response.status_code == 202, response.text
    job = response.json()
    assert response.headers["Location"] == f"/jobs/{job['id']}"
    assert job["status"] in {"queued", "running"} and job["kind"] == "calibrate"
    return wait_job(client, job["id"])


def test_calibrate_then_version_activate_export_and_restart(served):
    server, dataset = served
    truth = open_dataset(dataset).ground_truth
    with server.client() as client:
        listed = client.get("/datasets").json()
        assert [d["id"] for d in listed] == ["indoor-a"] and listed[0]["pair_count"] == 2
        assert [p["number"] for p in client.get("/datasets/indoor-a").json()["pairs"]] == [0, 1]

        # No version yet: "active" cannot be the start.
        assert client.post("/calibrate", json={"dataset": "indoor-a", "init": "active"}).status_code == 409
        first = calibrate(client, {"dataset": "indoor-a", "init": perturbed_truth(dataset)})
        assert first["status"] == "succeeded", first
        assert first["fraction"] == 1.0 and first["started_at"] and first["finished_at"]
        assert any("stored extrinsics version 1" in line for line in first["log_tail"])
        assert first["result_link"] == "/extrinsics/versions/1"
        v1 = client.get(first["result_link"]).json()
        # The first version is the active one (there was none); it moved towards the truth (1.7 deg, 3.5 cm off).
        assert v1["status"] == "active" and v1["supersedes"] is None and v1["change"] is None
        R = matrix(v1["T_camera_lidar"])[:3, :3]
        assert np.degrees(Rotation.from_matrix(R.T @ truth.rotation).magnitude()) < 1.0
        assert v1["dataset_id"] == "indoor-a" and v1["dataset_hash"].startswith("sha256:")
        assert v1["job_id"] == first["id"] and v1["code_version"]

        # Field recalibration from the active version: the change against it is reported.
        second = calibrate(client, {"dataset": "indoor-a", "init": "active", "auto_activate": True})
        v2 = client.get(second["result_link"]).json()
        assert v2["parameters"]["init"] == "active" and v2["parameters"]["init_version"] == 1
        assert v2["supersedes"] == 1 and v2["change"]["against"] == 1
        delta = matrix(v1["T_camera_lidar"]) @ np.linalg.inv(matrix(v2["T_camera_lidar"]))
        assert v2["change"]["rotation_deg"] == pytest.approx(
            np.degrees(Rotation.from_matrix(delta[:3, :3]).magnitude()), abs=1e-6)
        t1, t2 = matrix(v1["T_camera_lidar"])[:3, 3], matrix(v2["T_camera_lidar"])[:3, 3]
        assert v2["change"]["translation_cm"] == pytest.approx(np.linalg.norm(t2 - t1) * 100, abs=1e-6)
        assert v2["dataset_hash"] == v1["dataset_hash"]  # same files, same hash
        checks = second["result"]["auto_activate"]
        assert checks["requested"] is True
        assert v2["status"] == ("active" if not checks["failed_checks"] else "candidate")
        # Restarting from the optimum it found moves it little: within the default bounds (5 deg, 10 cm).
        assert v2["change"]["rotation_deg"] < 5.0 and v2["change"]["translation_cm"] < 10.0

        # A simulated dataset's rig.yaml has no initial guess, nor has this service a rig file.
        response = client.post("/calibrate", json={"dataset": "indoor-a", "init": "rig"})
        assert response.status_code == 422 and "initial_guess" in response.json()["detail"]
        # Without auto_activate a result stays a candidate.
        third = calibrate(client, {"dataset": "indoor-a", "init": perturbed_truth(dataset)})
        assert client.get(third["result_link"]).json()["status"] == "candidate"

        # Activate version 1 again: it becomes the active one, the others are not.
        response = client.post("/extrinsics/versions/1/activate")
        assert response.status_code == 200 and response.json()["status"] == "active"
        statuses = {v["number"]: v["status"] for v in client.get("/extrinsics/versions").json()}
        assert statuses[1] == "active" and list(statuses.values()).count("active") == 1
        assert client.get("/extrinsics").json()["number"] == 1

        check_exports(client, matrix(v1["T_camera_lidar"]))
        check_overlays(client, v1)
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
    assert client.get(f"/extrinsics/versions/{version['number']}/overlays/7.png").status_code == 404
