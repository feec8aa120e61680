"""A careless or hostile client (issue 15): text that is not Unicode, symlinks out of the data directory,
bodies that never arrive, a full queue, a second service on the same data directory, a deleted data
directory, a camera without its SDK layout."""

from __future__ import annotations

import pytest
from api_helpers import Server, simulated_dataset

JSON = {"Content-Type": "application/json"}
IDENTITY = {"rpy_deg": [0, 0, 0], "xyz_m": [0, 0, 0]}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    data = tmp_path_factory.mktemp("hardening") / "data"
    simulated_dataset(data, "ds", pairs=1)
    server = Server(data).start()
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
