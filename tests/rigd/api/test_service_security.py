"""Listen address and token, request validation and bounds, datasets only by id."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from api_helpers import REPO, Server, free_port, simulated_dataset

from rigd.cli import main
from rigd.cli.exit_codes import ERROR

TOKEN = "correct-horse-battery-staple"


def serve(*args: str, env: dict[str, str] | None = None, timeout_s: float = 60) -> tuple[int, str]:
    """``rigd serve`` as a process, expected to refuse its settings: its exit code and stderr. It must exit
    well within ``timeout_s`` (a serving process raises TimeoutExpired)."""
    environment = {"PATH": "/usr/bin:/bin", **(env or {})}
    if "PYTHONPATH" in os.environ:  # the code under test, when it is not the installed tree
        environment["PYTHONPATH"] = os.environ["PYTHONPATH"]
    proc = subprocess.run([sys.executable, "-m", "rigd", "serve", "--port", str(free_port()), *args],
                          capture_output=True, text=True, timeout=timeout_s, cwd=REPO, env=environment)
    return proc.returncode, proc.stderr


def _would_serve(*args: object) -> None:
    raise AssertionError("rigd serve accepted the settings and went on to open its data directory")


@pytest.fixture
def serve_here(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]):
    """``rigd serve`` expected to refuse its settings, run in this process through ``rigd.cli.main`` (what
    ``python -m rigd`` calls, without the ~1.3 s CPU of a new interpreter's imports): its exit code and stderr.
    Settings it accepted fail the test where it would build the service, instead of serving forever."""
    def run(*args: str, env: dict[str, str] | None = None) -> tuple[int, str]:
        for name in [name for name in os.environ if name.startswith("RIGD_")]:
            monkeypatch.delenv(name)
        for name, value in (env or {}).items():
            monkeypatch.setenv(name, value)
        monkeypatch.setattr("rigd.api.service.build_service", _would_serve)
        capsys.readouterr()
        code = main(["serve", "--port", str(free_port()), *args])
        return code, capsys.readouterr().err
    return run


# A refusal as a process (the exit status python -m rigd gives): the public address and the empty token. The other
# cases run the same code (rigd.cli.main -> rigd.cli.serve.run) in this process.
def test_refuses_a_public_address_without_a_token(tmp_path):
    code, stderr = serve("--host", "0.0.0.0", "--data-dir", str(tmp_path))
    assert code == ERROR
    assert "rigd: error: refusing to listen on 0.0.0.0 without an API token" in stderr
    assert "Traceback" not in stderr


def test_refuses_a_short_token_and_bad_settings(tmp_path, serve_here):
    code, stderr = serve_here("--data-dir", str(tmp_path), env={"RIGD_TOKEN": "short"})
    assert code == ERROR and "at least 16 characters" in stderr
    code, stderr = serve_here("--data-dir", str(tmp_path), env={"RIGD_AUTO_ACTIVATE_MIN_PAIRS": "zero"})
    assert code == ERROR and "auto_activate_min_pairs" in stderr


@pytest.mark.parametrize("token", ["", " ", " " * 20, "\t\n"])
def test_refuses_an_empty_token(tmp_path, token, serve_here):
    # An empty RIGD_TOKEN= (a placeholder left in rigd.env) must not mean "no token": refuse to start.
    run = serve if token == "" else serve_here
    code, stderr = run("--data-dir", str(tmp_path), env={"RIGD_TOKEN": token})
    assert code == ERROR, stderr
    assert "rigd: error: the API token (RIGD_TOKEN) is empty" in stderr
    assert "Traceback" not in stderr


def test_refuses_an_empty_token_in_the_rig_file(tmp_path, serve_here):
    rig = tmp_path / "rig.yaml"
    rig.write_text("service:\n  token:\n")
    code, stderr = serve_here("--data-dir", str(tmp_path / "data"), "--config", str(rig))
    assert code == ERROR, stderr
    assert "the API token (RIGD_TOKEN) is empty" in stderr


@pytest.mark.parametrize("token, problem", [
    ("correct-horse-b\u00e4ttery-staple", "printable ASCII"),  # UTF-8 on the wire, latin-1 in the server
    ("correct-horse-battery-staple\u20ac", "printable ASCII"),
    ("correct horse\tbattery staple", "printable ASCII"),  # a control character
    (" correct-horse-battery-staple", "leading or trailing white space"),  # HTTP strips it from the header
])
def test_refuses_a_token_a_client_cannot_send(tmp_path, token, problem, serve_here):
    code, stderr = serve_here("--data-dir", str(tmp_path), env={"RIGD_TOKEN": token})
    assert code == ERROR, stderr
    assert "the API token (RIGD_TOKEN)" in stderr and problem in stderr


@pytest.fixture(scope="module")
def guarded(tmp_path_factory):
    data = tmp_path_factory.mktemp("secure") / "data"
    simulated_dataset(data, "ds", pairs=1)
    server = Server(data, env={"RIGD_TOKEN": TOKEN}).start()
    yield server
    server.stop()


@pytest.mark.parametrize("method, path, body", [
    ("POST", "/calibrate", {"dataset": "ds", "init": {"rpy_deg": [0, 0, 0], "xyz_m": [0, 0, 0]}}),
    ("POST", "/extrinsics/versions", {"T_camera_lidar": {"rpy_deg": [0, 0, 0], "xyz_m": [0, 0, 0]}}),
    ("POST", "/extrinsics/versions/1/activate", None),
    ("DELETE", "/jobs/1", None),
])
def test_mutating_endpoints_need_the_token(guarded, method, path, body):
    with guarded.client() as anonymous, guarded.client("wrong-token-of-enough-length") as wrong:
        for client in (anonymous, wrong):
            response = client.request(method, path, json=body)
            assert response.status_code == 401 and response.headers["WWW-Authenticate"] == "Bearer"


def test_reading_is_open_and_the_token_admits_writes(guarded):
    with guarded.client() as anonymous, guarded.client(TOKEN) as client:
        assert anonymous.get("/status").status_code == 200
        assert anonymous.get("/datasets").status_code == 200
        created = client.post("/extrinsics/versions", json={
            "T_camera_lidar": {"rpy_deg": [0, 15, -55], "xyz_m": [0.09, 0.06, -0.17]}, "note": "tape measure"})
        assert created.status_code == 201 and created.headers["Location"].startswith("/extrinsics/versions/")
        assert anonymous.get(created.headers["Location"]).json()["parameters"]["note"] == "tape measure"


@pytest.mark.parametrize("body, field", [
    ({"dataset": "../etc", "init": "rig"}, "dataset"),  # an id, never a path
    ({"dataset": "/var/lib/rigd", "init": "rig"}, "dataset"),
    ({"dataset": "ds", "init": "rig", "out_dir": "/tmp"}, "out_dir"),  # unknown keys are refused
    ({"dataset": "ds", "init": {"rpy_deg": [0, 0], "xyz_m": [0, 0, 0]}}, "rpy_deg"),
    ({"dataset": "ds", "init": {"matrix": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}}, "init"),
    ({"dataset": "ds", "sigmas_deg": [1.0] * 7}, "sigmas_deg"),
    ({"dataset": "ds", "sigmas_deg": [-1.0]}, "sigmas_deg"),
])
def test_calibrate_bodies_are_validated(guarded, body, field):
    with guarded.client(TOKEN) as client:
        response = client.post("/calibrate", json=body)
    assert response.status_code == 422, response.text
    assert field in response.text


def test_non_finite_numbers_and_oversized_bodies_are_refused(guarded):
    with guarded.client(TOKEN) as client:
        nan = client.post("/calibrate", content=b'{"dataset": "ds", "sigmas_deg": [NaN]}',
                          headers={"Content-Type": "application/json"})
        assert nan.status_code == 422
        huge = client.post("/extrinsics/versions", content=b'{"note": "' + b"x" * 100_000 + b'"}',
                           headers={"Content-Type": "application/json"})
        assert huge.status_code == 413


def test_dataset_paths_stay_inside_the_data_dir(guarded):
    with guarded.client() as client:
        assert client.get("/datasets/ds").status_code == 200
        for path in ("/datasets/..%2F..%2Fetc", "/datasets/.hidden", "/datasets/" + "a" * 65):
            assert client.get(path).status_code in (404, 422), path
        assert client.get("/datasets/missing").status_code == 404
