"""Slow-header clients (issue 33): connections that send part of a request line and nothing more must not
lock a normal client out, and the server closes them after RIGD_HEADER_TIMEOUT_S."""

from __future__ import annotations

import socket
import time

import httpx
import pytest
from api_helpers import Server

HEADER_TIMEOUT_S = 2.0
MAX_CONNECTIONS = 200
SLOW = 300


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    data = tmp_path_factory.mktemp("slow-headers") / "data"
    server = Server(data, env={"RIGD_HEADER_TIMEOUT_S": str(HEADER_TIMEOUT_S),
                               "RIGD_MAX_CONNECTIONS": str(MAX_CONNECTIONS)}).start()
    yield server
    server.stop()


def slow_client(port: int) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    sock.sendall(b"GET /sta")  # a partial request line, and nothing more
    return sock


def read_until_closed(sock: socket.socket, deadline: float) -> bytes | None:
    """What the server sent before closing, or None if it is still open at ``deadline``."""
    received = b""
    while (left := deadline - time.monotonic()) > 0:
        sock.settimeout(left)
        try:
            chunk = sock.recv(4096)
        except TimeoutError:
            return None
        except ConnectionResetError:
            return received
        if not chunk:
            return received
        received += chunk
    return None


def test_slow_header_connections_do_not_lock_out_a_normal_client(server):
    opened = time.monotonic()
    slow = [slow_client(server.port) for _ in range(SLOW)]
    try:
        assert time.monotonic() - opened < HEADER_TIMEOUT_S, "opening took too long for the test to mean much"
        with httpx.Client(base_url=server.url, timeout=5.0) as client:
            for _ in range(5):
                start = time.monotonic()
                response = client.get("/status", headers={"Connection": "close"})
                assert response.status_code == 200, response.text
                assert time.monotonic() - start < 1.0

        # Beyond the cap, each new connection closed the oldest one waiting for its headers ...
        deadline = time.monotonic() + HEADER_TIMEOUT_S + 5
        outcomes = [read_until_closed(sock, deadline) for sock in slow]
        assert all(outcome is not None for outcome in outcomes), "a slow connection stayed open"
        evicted = [o for o in outcomes if o == b""]
        timed_out = [o for o in outcomes if o]
        assert len(evicted) >= SLOW - MAX_CONNECTIONS
        # ... and the rest got 408 after the header timeout.
        assert timed_out and all(o.startswith(b"HTTP/1.1 408 ") for o in timed_out), timed_out[:1]
        assert time.monotonic() - opened >= HEADER_TIMEOUT_S
    finally:
        for sock in slow:
            sock.close()


def test_a_normal_keep_alive_client_is_not_cut_off(server):
    """The header timeout starts again after each response: a client that takes its time between requests
    (under uvicorn's keep-alive timeout of 5 s) but sends each request whole is served."""
    with httpx.Client(base_url=server.url, timeout=5.0) as client:
        for _ in range(3):
            assert client.get("/status").status_code == 200
            time.sleep(HEADER_TIMEOUT_S / 2)


def test_accept_errors_at_the_open_file_limit_are_logged_once_a_minute():
    import errno
    import logging

    from rigd.api.connections import AcceptErrorFilter

    def record() -> logging.LogRecord:
        error = OSError(errno.EMFILE, "Too many open files")
        return logging.LogRecord("asyncio", logging.ERROR, __file__, 1, "socket.accept() out of system resource\n"
                                 "socket: <...>", (), (OSError, error, None))

    accept_errors = AcceptErrorFilter(interval_s=60)
    first = record()
    assert accept_errors.filter(first) and first.exc_info is None and "Too many open files" in first.getMessage()
    assert not any(accept_errors.filter(record()) for _ in range(1000))
    other = logging.LogRecord("asyncio", logging.ERROR, __file__, 1, "Task exception was never retrieved", (), None)
    assert accept_errors.filter(other)
    accept_errors.last -= 61
    later = record()
    assert accept_errors.filter(later) and "1000 not logged" in later.getMessage()
