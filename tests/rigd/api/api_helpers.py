"""A real ``rigd serve`` process on a loopback port, driven over HTTP with httpx."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from rigd.dataset import open_dataset
from rigd.simulate import write_simulated_dataset

REPO = Path(__file__).resolve().parents[3]
FINISHED = {"succeeded", "failed", "cancelled"}


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


class Server:
    """``python -m rigd serve`` as a child process with its own data directory and RIGD_* environment."""

    def __init__(self, data_dir: Path, env: dict[str, str] | None = None, args: tuple[str, ...] = ()) -> None:
        self.data_dir = Path(data_dir)
        self.env = {k: v for k, v in os.environ.items() if not k.startswith("RIGD_")}
        self.env.update({"RIGD_DATA_DIR": str(self.data_dir), **(env or {})})
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

    def start(self, timeout_s: float = 60.0) -> Server:
        for _ in range(3):  # the free port may be taken between choosing and binding it
            self.port = free_port()
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


def wait_job(client: httpx.Client, job_id: int, timeout_s: float = 180.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job = client.get(f"/jobs/{job_id}").json()
        if job["status"] in FINISHED:
            return job
        time.sleep(0.2)
    raise AssertionError(f"job {job_id} did not finish in {timeout_s} s: {job}")


def matrix(transform: dict[str, Any]) -> np.ndarray:
    return np.asarray(transform["matrix"], dtype=np.float64)
