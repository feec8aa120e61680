"""``GET /status`` latency of ``rigd serve`` while slow-header clients hold connections (issue 33; target:
p99 <= 200 ms with 2,000 of them).

Run: .venv/bin/python benchmarks/slow_headers.py [--slow 2000] [--requests 300] [--nofile 1024]
Starts ``rigd serve`` on a loopback port (fresh data directory, RIGD_HEADER_TIMEOUT_S=60 so that the slow
connections stay open while it measures), opens ``--slow`` connections that each send ``GET /sta`` and nothing
more, then requests /status ``--requests`` times, each on a new connection (as a client locked out by a full
file table would be), and prints count, failures, p50, p99, max, how many slow connections are still open,
and how many accept() errors the service logged. ``--nofile N`` starts the service with a hard limit of N open
files (1024: systemd's default without LimitNOFILE).
"""

from __future__ import annotations

import argparse
import resource
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
from api_status_latency import free_port, start


def start_limited(data: Path, port: int, log: Path, nofile: int | None) -> subprocess.Popen[bytes]:
    """``rigd serve`` with slow connections kept open (RIGD_HEADER_TIMEOUT_S=60), at most ``nofile`` open files."""

    def limit() -> None:
        if nofile is not None:
            resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, nofile))

    return start(data, port, env={"RIGD_HEADER_TIMEOUT_S": "60"}, log=log, preexec=limit)


def still_open(sock: socket.socket) -> bool:
    sock.setblocking(False)
    try:
        return sock.recv(1) != b""
    except BlockingIOError:
        return True
    except OSError:
        return False


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--slow", type=int, default=2000)
    parser.add_argument("--requests", type=int, default=300)
    parser.add_argument("--nofile", type=int, default=None)
    args = parser.parse_args()
    _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))  # this client holds --slow sockets itself

    tmp = Path(tempfile.mkdtemp(prefix="rigd-slow-headers-"))
    port, log = free_port(), tmp / "serve.log"
    proc = start_limited(tmp / "data", port, log, args.nofile)
    slow = []
    try:
        for _ in range(args.slow):
            sock = socket.create_connection(("127.0.0.1", port), timeout=10)
            sock.sendall(b"GET /sta")
            slow.append(sock)
        time.sleep(0.5)
        latencies, failed = [], 0
        # One client (building one costs ~40 ms: its TLS context), a new TCP connection per request.
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=5.0, headers={"Connection": "close"}) as client:
            for _ in range(args.requests):
                start_s = time.perf_counter()
                try:
                    failed += client.get("/status").status_code != 200
                except httpx.HTTPError:
                    failed += 1
                latencies.append((time.perf_counter() - start_s) * 1000)
        open_count = sum(still_open(sock) for sock in slow)
    finally:
        for sock in slow:
            sock.close()
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=60)
    ms = np.asarray(latencies)
    text = log.read_text(errors="replace")
    print(f"slow-header connections {args.slow} (still open at the end: {open_count}), service open-file limit "
          f"{args.nofile or hard}")
    print(f"GET /status, new connection each: {len(ms)} requests, {failed} failed, p50 {np.percentile(ms, 50):.1f} "
          f"ms, p99 {np.percentile(ms, 99):.1f} ms, max {ms.max():.1f} ms")
    print(f"service log: {len(text)} bytes, {text.count('out of system resource')} accept() errors")


if __name__ == "__main__":
    main()
