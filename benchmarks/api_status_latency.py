"""``GET /status`` latency of ``rigd serve`` while a calibration runs (target: p99 <= 20 ms).

Run: .venv/bin/python benchmarks/api_status_latency.py [--pairs 6] [--width 1024] [--idle-requests 300]
Starts ``rigd serve`` on a loopback port with a fresh data directory holding a simulated dataset, measures
/status with one keep-alive httpx client while idle, then again while a calibration of that dataset runs
in the worker process (requests back to back until the job ends). Prints count, p50, p99 and max.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import httpx
import numpy as np

from rigd.dataset import open_dataset
from rigd.simulate import write_simulated_dataset


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def start(data: Path, port: int, *, env: dict[str, str] | None = None, log: Path | None = None,
          preexec: Callable[[], None] | None = None) -> subprocess.Popen[bytes]:
    """``rigd serve`` on ``port`` with the data directory ``data`` and ``env`` (the caller's RIGD_ variables
    dropped), its output into ``log`` if given; returns once ``GET /status`` answers."""
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("RIGD_")}, "RIGD_DATA_DIR": str(data),
           **(env or {})}
    with log.open("wb") if log is not None else contextlib.nullcontext() as out:
        proc = subprocess.Popen([sys.executable, "-m", "rigd", "serve", "--port", str(port), "--log-level",
                                 "warning"], env=env, stdout=out, stderr=subprocess.STDOUT if out else None,
                                preexec_fn=preexec)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"http://127.0.0.1:{port}/status", timeout=2.0).status_code == 200:
                return proc
        except httpx.TransportError:
            time.sleep(0.1)
    proc.kill()
    raise SystemExit("rigd serve did not start" + (f":\n{log.read_text()}" if log is not None else ""))


def bench_data_dir(tmp: Path, pairs: int, width: int) -> tuple[Path, dict[str, list[float]]]:
    """A data directory holding dataset ``bench`` (simulated, indoor, seed 3) and an initial guess for it
    2 deg / 3 cm off its ground truth."""
    data = tmp / "data"
    dataset = write_simulated_dataset(data / "datasets" / "bench", "indoor", pairs, 3, width, width // 2,
                                      progress=False)
    truth = open_dataset(dataset).ground_truth
    assert truth is not None
    return data, {"rpy_deg": (truth.rpy_deg + 2.0).tolist(), "xyz_m": (truth.translation_m + 0.03).tolist()}


def timed_status(client: httpx.Client) -> float:
    started = time.perf_counter()
    response = client.get("/status")
    elapsed = time.perf_counter() - started
    response.raise_for_status()
    return elapsed * 1e3


def report(label: str, ms: list[float]) -> None:
    a = np.asarray(ms)
    print(f"{label:28s} n={len(a):5d}  p50 {np.percentile(a, 50):6.2f} ms  p99 {np.percentile(a, 99):6.2f} ms  "
          f"max {a.max():6.2f} ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=6)
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--idle-requests", type=int, default=300)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data, init = bench_data_dir(Path(tmp), args.pairs, args.width)
        port = free_port()
        proc = start(data, port)
        try:
            with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10) as client:
                for _ in range(20):  # warm up the connection and the server's code paths
                    timed_status(client)
                report("idle", [timed_status(client) for _ in range(args.idle_requests)])
                job = client.post("/calibrate", json={"dataset": "bench", "init": init}).json()
                busy, started = [], time.monotonic()
                while True:
                    busy.append(timed_status(client))
                    if len(busy) % 20 == 0 and client.get(f"/jobs/{job['id']}").json()["status"] not in (
                            "queued", "running"):
                        break
                final = client.get(f"/jobs/{job['id']}").json()
                report("during calibration", busy)
                print(f"calibration: {args.pairs} pairs {args.width}x{args.width // 2}, {final['status']}, "
                      f"{time.monotonic() - started:.1f} s wall; /status requests back to back meanwhile")
        finally:
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=60)


if __name__ == "__main__":
    main()
