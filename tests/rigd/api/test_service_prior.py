"""POST /calibrate with a prior from the rig's drawing: validated, carried to the worker, and its effect and
the verdict stored with the version."""

from __future__ import annotations

import numpy as np
from api_helpers import App, matrix, perturbed_truth, simulated_dataset, wait_job

from rigd.dataset import open_dataset


def test_prior_and_fixed_translation_reach_the_calibration(tmp_path):
    data = tmp_path / "data"
    dataset = simulated_dataset(data, "ds", pairs=2)
    lever = (open_dataset(dataset).ground_truth.translation_m + [0.01, 0.0, 0.0]).tolist()
    server = App(data).start()  # route behaviour and the worker: rigd's app in this process
    try:
        with server.client() as client:
            start = perturbed_truth(dataset)
            for bad in ({"xyz_m": lever}, {"sigma_deg": 2.0}, {"xyz_m": lever, "sigma_cm": -1}):
                response = client.post("/calibrate", json={"dataset": "ds", "init": start, "prior": bad})
                assert response.status_code == 422, (bad, response.text)
            # The versions table's centimetres typed as metres: 19 m, no rig's lever arm; refused, unit named.
            in_cm = {"xyz_m": [9.34, 6.24, -15.68], "sigma_cm": 1.0}
            response = client.post("/calibrate", json={"dataset": "ds", "init": start, "prior": in_cm})
            assert response.status_code == 422, response.text
            assert "19.29 m from the camera, more than the 5 m any rig has: it is in metres" in response.text
            assert client.get("/jobs").json() == []  # nothing queued
            body = {"dataset": "ds", "init": start, "prior": {"xyz_m": lever, "sigma_cm": 1.0},
                    "fix_translation": True, "tolerance": {"rotation_deg": 0.5, "translation_cm": 5.0}}
            job = wait_job(client, client.post("/calibrate", json=body).json()["id"])
            assert job["status"] == "succeeded", job
            version = client.get(job["result_link"]).json()
            assert np.allclose(matrix(version["T_camera_lidar"])[:3, 3], lever, atol=1e-9)  # held at the prior
            prior = version["parameters"]["request"]["options"]["prior"]
            assert prior == {"xyz_m": lever, "sigma_cm": 1.0, "rpy_deg": None, "sigma_deg": None}
            assert version["uncertainty"]["xyz_cm"] == [0.0, 0.0, 0.0]
            assert version["verdict"]["status"] in ("trusted", "weak", "failed")
            assert version["status"] == ("active" if version["verdict"]["status"] == "trusted" else "candidate")
    finally:
        server.stop()


def test_an_elevation_fit_reaches_the_worker_and_two_places_are_refused_by_name(tmp_path):
    data = tmp_path / "data"
    dataset = simulated_dataset(data, "ds", pairs=2)
    server = App(data).start()
    try:
        with server.client() as client:
            body = {"dataset": "ds", "init": perturbed_truth(dataset), "fit_elevation_offset": True}
            job = wait_job(client, client.post("/calibrate", json=body).json()["id"])
            assert job["status"] == "failed", job
            assert "elevation offset needs 3 or more places, got 2" in job["error"]
            assert job["params"]["request"]["options"]["fit_elevation_offset"] is True
    finally:
        server.stop()
