"""Connection-level guards of ``rigd serve`` against slow-header clients (issue 33).

uvicorn bounds idle keep-alive connections (``timeout_keep_alive``) but not a client that opens a connection
and sends its request line or headers slowly, or never finishes them: about 1,000 such connections used up
systemd's default 1024 open files, every further accept() failed (asyncio logged each failure) and no
client was served. Here:

- :func:`raise_fd_limit` raises the soft limit of open files to the hard one (LimitNOFILE in the unit);
- :func:`guarded_protocol` is uvicorn's h11 protocol with a header timeout (a connection whose request line
  and headers have not arrived ``header_timeout_s`` after it opened, or after its previous response, gets
  408 and is closed) and a connection cap (beyond it, a new connection closes the oldest one still waiting
  for its headers, so a flood of slow clients cannot shut out a normal one; with none waiting, the new
  connection gets 503 and is closed). The cap stays below the open-file limit, so accept() does not fail;
  should it fail anyway, :class:`AcceptErrorFilter` logs that at most once a minute.

uvicorn's own ``limit_concurrency`` does not serve here: it counts every open connection, the slow ones
included, and answers 503 to the *normal* client's request once they exceed it.
"""

from __future__ import annotations

import asyncio
import logging
import resource
import time
from typing import Any, ClassVar

from uvicorn.protocols.http.h11_impl import H11Protocol

# uvicorn's logger: its handlers are set up once uvicorn.Config exists, and journald shows it with the rest.
LOG = logging.getLogger("uvicorn.error")
# Open files kept for everything but client connections: the database, job logs, worker pipes, sensors.
RESERVED_FILES = 256


def _plain_response(status: str, text: str) -> bytes:
    body = text.encode()
    return (f"HTTP/1.1 {status}\r\ncontent-type: text/plain; charset=utf-8\r\nconnection: close\r\n"
            f"content-length: {len(body)}\r\n\r\n").encode() + body


_TIMEOUT = _plain_response("408 Request Timeout", "the request headers did not arrive in time")
_BUSY = _plain_response("503 Service Unavailable", "too many connections, try again later")


def raise_fd_limit() -> int:
    """Raise the soft limit of open files to the hard one; returns the soft limit now in force."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard != soft:
        try:
            resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
        except (ValueError, OSError) as exc:  # e.g. an infinite hard limit the kernel caps lower
            LOG.warning("could not raise the open-file limit from %d to %s: %s", soft, hard, exc)
        else:
            LOG.info("raised the open-file limit from %d to %d", soft, hard)
            soft = hard
    return soft


def accept_backlog(fd_limit: int) -> int:
    """The listen backlog: uvicorn's 2048, smaller under a low open-file limit. asyncio accepts up to this many
    connections in a row before the protocol sees any of them, so the cap must leave room for them."""
    return max(64, min(2048, fd_limit // 4))


def connection_cap(max_connections: int, fd_limit: int) -> int:
    """``max_connections``, lowered to leave :data:`RESERVED_FILES` and one accept burst
    (:func:`accept_backlog`) of ``fd_limit`` for everything else."""
    cap = max(16, min(max_connections, fd_limit - RESERVED_FILES - accept_backlog(fd_limit)))
    if cap < max_connections:
        LOG.warning("serving at most %d connections (RIGD_MAX_CONNECTIONS is %d, the open-file limit %d; raise "
                    "LimitNOFILE)", cap, max_connections, fd_limit)
    return cap


class AcceptErrorFilter(logging.Filter):
    """Let asyncio's "socket.accept() out of system resource" through once a minute, without its traceback
    and with the count of those held back: at the open-file limit it comes at every retry (megabytes a minute)."""

    def __init__(self, interval_s: float = 60.0) -> None:
        super().__init__()
        self.interval_s = interval_s
        self.last = -interval_s
        self.held_back = 0

    def filter(self, record: logging.LogRecord) -> bool:
        if not str(record.msg).startswith("socket.accept() out of system resource"):
            return True
        now = time.monotonic()
        if now - self.last < self.interval_s:
            self.held_back += 1
            return False
        error = record.exc_info[1] if record.exc_info else None
        record.msg = (f"socket.accept() out of system resource ({error}); the open-file limit (LimitNOFILE) is "
                      f"too low; logged at most every {self.interval_s:g} s, {self.held_back} not logged since "
                      "the last time")
        record.args, record.exc_info, record.exc_text = (), None, None
        self.last, self.held_back = now, 0
        return True


def quiet_accept_errors() -> None:
    logging.getLogger("asyncio").addFilter(AcceptErrorFilter())


def guarded_protocol(header_timeout_s: float, max_connections: int) -> type[HeaderGuard]:
    """uvicorn's h11 protocol with a header timeout and a connection cap (uvicorn's ``http=`` setting); its
    ``max_connections`` may be changed before the server starts."""
    return type("HeaderGuard", (HeaderGuard,), {"header_timeout_s": header_timeout_s,
                                                "max_connections": max_connections, "waiting": {}})


class HeaderGuard(H11Protocol):
    """See the module's documentation; :func:`guarded_protocol` makes one with its settings."""

    header_timeout_s: ClassVar[float] = 10.0
    max_connections: ClassVar[int] = 1024
    # The connections waiting for a request's headers, oldest first (dict: insertion order, O(1) removal).
    waiting: ClassVar[dict[HeaderGuard, None]] = {}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._header_timer: asyncio.TimerHandle | None = None
        self._armed_cycle: object = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        if len(self.connections) > self.max_connections:
            if not self.waiting:
                transport.write(_BUSY)
                transport.close()
                return
            oldest = next(iter(self.waiting))
            oldest._disarm()
            oldest.transport.close()
        self._arm()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def handle_events(self) -> None:
        super().handle_events()
        if self._header_timer is not None and self.cycle is not self._armed_cycle:
            self._disarm()  # a request's headers have arrived

    def on_response_complete(self) -> None:
        if not self.transport.is_closing():
            self._arm()  # before uvicorn reads a pipelined request (handle_events then disarms)
        super().on_response_complete()

    def _arm(self) -> None:
        self._disarm()
        self._armed_cycle = self.cycle
        self._header_timer = self.loop.call_later(self.header_timeout_s, self._headers_late)
        self.waiting[self] = None

    def _disarm(self) -> None:
        if self._header_timer is not None:
            self._header_timer.cancel()
            self._header_timer = None
        self.waiting.pop(self, None)

    def _headers_late(self) -> None:
        self._header_timer = None
        self.waiting.pop(self, None)
        if self.cycle is self._armed_cycle and not self.transport.is_closing():
            self.transport.write(_TIMEOUT)
            self.transport.close()

