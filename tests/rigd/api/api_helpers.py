"""A real ``rigd serve`` process on a loopback port, driven over HTTP with httpx (:class:`Server`: crashes,
cancels, signals, restarts, security), or rigd's application in this process (:class:`App`: route behaviour)."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path
from typing import Any
from unittest import mock

import httpx
import numpy as np
import yaml

with warnings.catch_warnings():  # Starlette 1.x would rather its TestClient ran on httpx2; httpx serves it here
    warnings.filterwarnings("ignore", "Using `httpx` with `starlette.testclient`")
    from fastapi.testclient import TestClient

from rigd.api.main import create_app
from rigd.api.service import Service, build_service
from rigd.api.settings import load_settings
from rigd.dataset import open_dataset
from rigd.simulate import write_simulated_dataset

REPO = Path(__file__).resolve().parents[3]
FINISHED = {"succeeded", "failed", "cancelled"}
# A calibration job in one process: no pool start-ups (~2.5 s CPU a job). Tests of the pool itself (cancel, crash,
# a killed worker) ask for POOL.
ONE_WORKER = {"RIGD_WORKERS": "1"}
POOL = {"RIGD_WORKERS": "2"}


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def simulated_dataset(data_dir: Path, name: str, pairs: int = 2, seed: int = 5) -> Path:
    """A small simulated dataset inside ``data_dir/datasets`` (256 x 128 panoramas: fast to calibrate)."""
    return write_simulated_dataset(data_dir / "datasets" / name, "indoor", pairs, seed, width=256, height=128,
                                   progress=False)


def perturbed_truth(dataset: Path, rpy_deg: tuple[float, float, float] = (1.0, -1.0, 1.0),
                    xyz_m: tuple[float, float, float] = (0.02, -0.02, 0.02)) -> dict[str, list[float]]:
    truth = open_dataset(dataset).ground_truth
    assert truth is not None
    return {"rpy_deg": (truth.rpy_deg + rpy_deg).tolist(), "xyz_m": (truth.translation_m + xyz_m).tolist()}


# The sim rig's T_camera_lidar (drivers.sim.rig.PAPER_T_CAMERA_LIDAR) off by 1.7 deg and 3.5 cm.
RIG_GUESS = {"rpy_deg": [0.82, 14.47, -54.14], "xyz_m": [0.1134, 0.0397, -0.1459]}


def rig_file(path: Path, lidar: str | None = None) -> Path:
    """A rig file for the simulated rig (small panoramas, short stops; its file beside ``path``) with a
    perturbed initial guess and quick captures; ``lidar`` replaces the LiDAR source."""
    sim = path.with_name(f"{path.stem}-sim.yaml")
    sim.write_text(yaml.safe_dump({"scene": "indoor", "seed": 5, "stops": 6, "still_s": 2.5, "move_s": 1.0,
                                   "width": 256, "height": 128}))
    camera = "sim" if lidar else f"sim:{sim}"
    path.write_text(yaml.safe_dump({
        "camera": {"model": "equirectangular", "width": 256, "height": 128, "source": camera},
        "lidar": {"model": "VLP-16", "source": lidar or f"sim:{sim}"},
        "initial_guess": RIG_GUESS,
        "capture": {"n": 2, "still_seconds": 0.5, "sweeps": 2},
    }))
    return path


class Server:
    """``python -m rigd serve`` as a child process with its own data directory and RIGD_* environment; its rig
    file is :func:`rig_file`'s unless ``env`` names another (RIGD_CONFIG)."""

    def __init__(self, data_dir: Path, env: dict[str, str] | None = None, args: tuple[str, ...] = ()) -> None:
        self.data_dir = Path(data_dir)
        self.env = {k: v for k, v in os.environ.items() if not k.startswith("RIGD_")}
        config = rig_file(self.data_dir.parent / f"{self.data_dir.name}-rig.yaml")
        self.env.update({"RIGD_DATA_DIR": str(self.data_dir), "RIGD_CONFIG": str(config), **ONE_WORKER, **(env or {})})
        self.args = args
        self.proc: subprocess.Popen[bytes] | None = None
        self.port = 0
        self.log_path = self.data_dir.parent / f"{self.data_dir.name}-serve.log"

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def client(self, token: str | None = None) -> httpx.Client:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        return httpx.Client(base_url=self.url, timeout=30.0, headers=headers)

    def start(self, timeout_s: float = 60.0, same_port: bool = False) -> Server:
        """Start it on a free port, or with ``same_port`` on the one it had (a restart, as a page sees it)."""
        for _ in range(1 if same_port else 3):  # the free port may be taken between choosing and binding it
            self.port = self.port if same_port else free_port()
            with self.log_path.open("ab") as log:
                self.proc = subprocess.Popen(
                    [sys.executable, "-m", "rigd", "serve", "--port", str(self.port), "--log-level", "warning",
                     *self.args], env=self.env, stdout=log, stderr=subprocess.STDOUT, cwd=REPO)
            if self._wait_ready(timeout_s):
                return self
        raise AssertionError(f"rigd serve did not start:\n{self.log_path.read_text()}")

    def _wait_ready(self, timeout_s: float) -> bool:
        assert self.proc is not None
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                return False
            try:
                if httpx.get(f"{self.url}/status", timeout=2.0).status_code == 200:
                    return True
            except httpx.TransportError:
                time.sleep(0.1)
        self.kill()
        return False

    def stop(self) -> int:
        """SIGTERM (as systemd stops it) and wait; returns the exit code."""
        assert self.proc is not None
        self.proc.send_signal(signal.SIGTERM)
        return self.proc.wait(timeout=60)

    def kill(self) -> None:
        assert self.proc is not None
        self.proc.kill()
        self.proc.wait(timeout=30)


class _Client(TestClient):
    """A client of a started :class:`App`: on its event loop, and entering it does not run the lifespan again
    (a TestClient's ``with`` would start the service a second time)."""

    def __enter__(self) -> _Client:
        return self

    def __exit__(self, *args: object) -> None:
        self.close()


class App:
    """rigd's application (``create_app(build_service(settings))``, as ``rigd serve`` builds it) run in this
    process by Starlette's TestClient: the same routes, service and worker processes without the ~2.5 s CPU of
    starting a ``rigd serve`` (imports). Settings as :class:`Server`'s: :func:`rig_file`'s rig, ``env``'s
    ``RIGD_*`` values, nothing from this process's environment. A route that raises fails the test."""

    def __init__(self, data_dir: Path, env: dict[str, str] | None = None) -> None:
        self.data_dir = Path(data_dir)
        config = rig_file(self.data_dir.parent / f"{self.data_dir.name}-rig.yaml")
        self.env = {"RIGD_DATA_DIR": str(self.data_dir), "RIGD_CONFIG": str(config), **ONE_WORKER, **(env or {})}
        self._main: TestClient | None = None
        self.service: Service | None = None

    def start(self) -> App:
        outside = {k: v for k, v in os.environ.items() if not k.startswith("RIGD_")}
        with mock.patch.dict(os.environ, {**outside, **self.env}, clear=True):
            settings = load_settings()
        self.service = build_service(settings)
        self.app = create_app(self.service)
        self._main = TestClient(self.app)
        self._main.__enter__()  # the lifespan: the service starts (its job runner and sensor monitor)
        return self

    def client(self, token: str | None = None) -> _Client:
        assert self._main is not None and self._main.portal is not None, "start() the app first"
        client = _Client(self.app, headers={"Authorization": f"Bearer {token}"} if token else None)
        client.portal = self._main.portal  # the app's event loop, as one server's requests share one
        return client

    def stop(self) -> None:
        """The lifespan's end, as a SIGTERM'd ``rigd serve``: jobs stopped, the database closed, the lock released."""
        if self._main is not None:
            main, self._main = self._main, None
            main.__exit__(None, None, None)

    def kill(self) -> None:
        """The end of a service whose data directory is gone (where a test kills ``rigd serve``): the lifespan's
        end, which records what it can."""
        self.stop()


def wait_job(client: httpx.Client, job_id: int, timeout_s: float = 180.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job = client.get(f"/jobs/{job_id}").json()
        if job["status"] in FINISHED:
            return job
        time.sleep(0.2)
    raise AssertionError(f"job {job_id} did not finish in {timeout_s} s: {job}")


def wait_running(client: httpx.Client, job_id: int, log_text: str = "worker process") -> dict[str, Any]:
    """The job once it runs and its log tail holds ``log_text`` (by default: its worker process started)."""
    deadline = time.monotonic() + 60
    while (job := client.get(f"/jobs/{job_id}").json())["status"] != "running" or not any(
            log_text in line for line in job["log_tail"]):
        assert time.monotonic() < deadline and job["status"] in {"queued", "running"}, job
        time.sleep(0.05)
    return job


def matrix(transform: dict[str, Any]) -> np.ndarray:
    return np.asarray(transform["matrix"], dtype=np.float64)


def worker_pid(log_tail: list[str]) -> int:
    pids = [int(m.group(1)) for line in log_tail if (m := re.search(r"worker process (\d+) started", line))]
    assert pids, log_tail
    return pids[-1]


def _stat(pid: str) -> list[str] | None:
    """/proc/PID/stat's fields after the command name (state, ppid, pgrp, ...), None if it has exited."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (FileNotFoundError, ProcessLookupError):
        return None


def _live() -> dict[int, list[str]]:
    stats = {int(p.name): _stat(p.name) for p in Path("/proc").iterdir() if p.name.isdigit()}
    return {pid: fields for pid, fields in stats.items() if fields is not None and fields[0] != "Z"}


def process_group(pgid: int) -> list[int]:
    """The running (not zombie) processes of process group ``pgid``."""
    return sorted(pid for pid, fields in _live().items() if int(fields[2]) == pgid)


def descendants(pid: int) -> list[int]:
    """The running processes started by ``pid``, its children's children and so on."""
    children: dict[int, list[int]] = {}
    for child, fields in _live().items():
        children.setdefault(int(fields[1]), []).append(child)
    found, todo = [], [pid]
    while todo:
        found += (kids := children.get(todo.pop(), []))
        todo += kids
    return sorted(found)


def gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return True
    return state == "Z"  # exited, waiting to be reaped by whoever adopted it
