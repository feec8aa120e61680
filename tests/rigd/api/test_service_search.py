"""POST /calibrate without an initial guess: the global search runs in the worker and its report is stored."""

from __future__ import annotations

from api_helpers import App, simulated_dataset, wait_job


def test_calibrate_with_init_search_finds_the_mount(tmp_path):
    data = tmp_path / "data"
    simulated_dataset(data, "ds", pairs=2)  # simulated rig.yaml files carry no initial_guess
    server = App(data).start()  # route behaviour and the worker: rigd's app in this process
    try:
        with server.client() as client:
            # the service's rig file has a guess; "search" ignores it (the camera was remounted)
            response = client.post("/calibrate", json={"dataset": "ds", "init": "search"})
            assert response.status_code == 202, response.text
            job = wait_job(client, response.json()["id"])
            assert job["status"] == "succeeded", job
            version = client.get(job["result_link"]).json()
            request = version["parameters"]["request"]
            assert request["start"] == "search" and request["initial"] is None
            search = version["quality"]["initial_search"]
            assert search["grid"]["mounts"] > 0 and search["candidates"]
            assert version["quality"]["error_vs_ground_truth"]["rotation_deg"] < 1.0
            assert client.post("/calibrate", json={"dataset": "ds", "init": "upside-down"}).status_code == 422
    finally:
        server.stop()
