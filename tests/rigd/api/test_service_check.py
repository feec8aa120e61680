"""POST /check: a check job in the worker process whose result is the drift report (no version is stored)."""

from __future__ import annotations

import json
import sqlite3
from contextlib import closing

from api_helpers import App, simulated_dataset, wait_job

from calib.drift import DriftOptions
from rigd.api.models import ThresholdIn
from rigd.dataset import open_dataset


def test_check_against_active_version_and_explicit_transform(tmp_path):
    data = tmp_path / "data"
    dataset = simulated_dataset(data, "ds", pairs=8)  # 256 x 128 images: 8 places pin the pose down
    truth = open_dataset(dataset).ground_truth
    assert truth is not None
    at_truth = {"rpy_deg": truth.rpy_deg.tolist(), "xyz_m": truth.translation_m.tolist()}
    server = App(data).start()  # route behaviour and the worker: rigd's app in this process
    try:
        with server.client() as client:
            response = client.post("/check", json={"dataset": "ds"})
            assert response.status_code == 409, response.text
            assert "no active" in response.json()["detail"]
            assert client.post("/check", json={"dataset": "ds", "against": 7}).status_code == 404
            assert client.post("/check", json={"dataset": "nope", "against": at_truth}).status_code == 404
            for bad in ({"threshold": {"rotation_deg": -1, "translation_cm": 3}}, {"against": 0},
                        {"against": "rig"}, {"against": True}, {"threshold": {"rotation_deg": 0}}):
                response = client.post("/check", json={"dataset": "ds", **bad})
                assert response.status_code == 422, (bad, response.text)

            stored = client.post("/extrinsics/versions", json={"T_camera_lidar": at_truth, "activate": True})
            assert stored.status_code == 201, stored.text
            assert stored.json()["status"] == "active"

            response = client.post("/check", json={"dataset": "ds", "against": "active"})
            assert response.status_code == 202, response.text
            assert response.headers["Location"] == f"/jobs/{response.json()['id']}"
            assert response.json()["kind"] == "check"
            again = client.post("/check", json={"dataset": "ds"})  # identical while queued or running
            assert again.status_code == 200 and again.json()["id"] == response.json()["id"], again.text
            job = wait_job(client, response.json()["id"])
            assert job["status"] == "succeeded", job
            assert job["params"]["against"] == "active" and job["params"]["against_version"] == 1
            result = job["result"]
            assert result["status"] in ("ok", "unknown"), result
            assert len(result["change"]["rpy_deg"]) == 3 and len(result["sigma"]["xyz_cm"]) == 3
            assert result["thresholds"] == job["params"]["threshold"]
            assert result["places"] == 8
            assert job["result_link"] is None
            raw = client.get(f"/jobs/{job['id']}").content  # answered through JobOut's typed CheckReport
            with closing(sqlite3.connect(data / "rigd.db")) as conn:
                stored = conn.execute("SELECT result FROM jobs WHERE id = ?", (job["id"],)).fetchone()[0]
            assert json.dumps(json.loads(raw)["result"]) == stored  # the same keys, order and values

            off = {"rpy_deg": (truth.rpy_deg + [0.0, 0.0, 1.5]).tolist(),
                   "xyz_m": (truth.translation_m + [0.0, 0.06, 0.0]).tolist()}
            body = {"dataset": "ds", "against": off, "threshold": {"rotation_deg": 0.5, "translation_cm": 3}}
            response = client.post("/check", json=body)
            assert response.status_code == 202, response.text
            job = wait_job(client, response.json()["id"])
            assert job["status"] == "succeeded", job
            assert job["result"]["status"] == "drifted", job["result"]
            assert job["result"]["thresholds"] == {"rotation_deg": 0.5, "translation_cm": 3.0}

            assert [v["number"] for v in client.get("/extrinsics/versions").json()] == [1]  # no version made
            assert client.get("/jobs", params={"kind": "check"}).json()[0]["kind"] == "check"
    finally:
        server.stop()


def test_the_service_checks_with_the_commands_default_thresholds():
    default = DriftOptions()
    assert ThresholdIn().model_dump() == {"rotation_deg": default.threshold_rot_deg,
                                          "translation_cm": default.threshold_trans_cm}
