"""The FastAPI application: routers, error mapping, the request-size and body-time limits, start-up and
shutdown."""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from http import HTTPStatus
from typing import Any

import numpy as np
from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from calib.errors import CalibError
from drivers.errors import DriverError
from rigd.api.errors import QueueFullError
from rigd.api.routes import calibrate, capture, check, datasets, extrinsics, jobs
from rigd.api.routes import status as status_routes
from rigd.api.service import Service
from rigd.api.wording import public_text
from rigd.calibration.request import MAX_NESTING
from rigd.errors import DatasetError, RigdError
from rigd.store import ConflictError, NotFoundError, StorageError, StoreError, StoreUnavailableError
from rigd.store.jsonsafe import json_safe
from rigd.web import install as install_page

# Most specific first: the first class an error is an instance of decides its status.
ERROR_STATUS: tuple[tuple[type[Exception], HTTPStatus], ...] = (
    (NotFoundError, HTTPStatus.NOT_FOUND),
    (ConflictError, HTTPStatus.CONFLICT),
    (StoreUnavailableError, HTTPStatus.SERVICE_UNAVAILABLE),
    (StorageError, HTTPStatus.INSUFFICIENT_STORAGE),
    (StoreError, HTTPStatus.INTERNAL_SERVER_ERROR),
    (DatasetError, HTTPStatus.UNPROCESSABLE_ENTITY),
    (DriverError, HTTPStatus.SERVICE_UNAVAILABLE),
    (CalibError, HTTPStatus.UNPROCESSABLE_ENTITY),
    (RigdError, HTTPStatus.UNPROCESSABLE_ENTITY),
)


async def _error_response(request: Request, exc: Exception) -> JSONResponse:
    code = next(code for kind, code in ERROR_STATUS if isinstance(exc, kind))
    service: Service = request.app.state.service
    return JSONResponse({"detail": public_text(str(exc), service.datasets.root)}, status_code=int(code))


async def _queue_full(request: Request, exc: QueueFullError) -> JSONResponse:
    return JSONResponse({"detail": str(exc)}, status_code=int(HTTPStatus.TOO_MANY_REQUESTS),
                        headers={"Retry-After": str(exc.retry_after_s)})


ECHO_DEPTH = 4  # levels of a refused input echoed back in a 422's errors


def _echo(value: Any, depth: int = 0) -> Any:
    """``value`` with objects and arrays below ``ECHO_DEPTH`` levels elided: a refused body may nest hundreds
    of levels deep, which encoding it whole would not survive (RecursionError, a 500)."""
    if isinstance(value, dict):
        return "{...}" if depth >= ECHO_DEPTH else {k: _echo(v, depth + 1) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return "[...]" if depth >= ECHO_DEPTH else [_echo(v, depth + 1) for v in value]
    return value


async def _validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
    # FastAPI's own handler echoes the input, and an input NaN would make that reply invalid JSON (a 500).
    errors = [{**error, "input": _echo(error["input"])} if "input" in error else error for error in exc.errors()]
    return JSONResponse({"detail": json_safe(jsonable_encoder(errors))},
                        status_code=int(HTTPStatus.UNPROCESSABLE_ENTITY))


class BodyLimit:
    """Refuse request bodies over ``max_bytes`` (413) and bodies of unknown length (411) before reading them."""

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http":
            headers = dict(scope["headers"])
            length = headers.get(b"content-length")
            refusal = None
            if length is None and b"transfer-encoding" in headers:
                refusal = (HTTPStatus.LENGTH_REQUIRED, "send the body with a Content-Length")
            elif length is not None and (not length.isdigit() or int(length) > self.max_bytes):
                refusal = (HTTPStatus.REQUEST_ENTITY_TOO_LARGE, f"request bodies are limited to {self.max_bytes} bytes")
            if refusal is not None:
                await JSONResponse({"detail": refusal[1]}, status_code=int(refusal[0]))(scope, receive, send)
                return
        await self.app(scope, receive, send)


class BodyTimeout:
    """Answer 408 and close the connection when a request's body has not arrived in full ``timeout_s`` after
    its headers.

    uvicorn bounds idle keep-alive connections but not a body that trickles or stops: a client announcing
    100 bytes and sending 10 would hold its connection open for as long as it likes.
    The body is read here in full (BodyLimit, outside this, has bounded its size) and handed on as received.
    """

    def __init__(self, app: ASGIApp, timeout_s: float) -> None:
        self.app = app
        self.timeout_s = timeout_s

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        try:
            received = await asyncio.wait_for(_receive_body(receive), self.timeout_s)
        except TimeoutError:
            response = JSONResponse({"detail": f"the request body did not arrive within {self.timeout_s:g} s"},
                                    status_code=int(HTTPStatus.REQUEST_TIMEOUT), headers={"Connection": "close"})
            await response(scope, receive, send)
            return
        await self.app(scope, _replay(received, receive), send)


async def _receive_body(receive: Receive) -> list[Message]:
    """The messages up to the body's last part (or the client's disconnect)."""
    messages = []
    while True:
        message = await receive()
        messages.append(message)
        if message["type"] != "http.request" or not message.get("more_body", False):
            return messages


def _replay(messages: list[Message], receive: Receive) -> Receive:
    pending = deque(messages)

    async def replayed() -> Message:
        return pending.popleft() if pending else await receive()  # then: the disconnect, when it comes

    return replayed


def json_nesting(body: bytes) -> int:
    """How deep the objects and arrays of JSON text ``body`` nest; brackets inside strings do not count.

    Vectorised and linear: a regular expression for strings backtracks quadratically on an unterminated one
    full of escaped quotes (10 s for 40 KB)."""
    c = np.frombuffer(body, np.uint8)
    if c.size == 0:
        return 0
    index = np.arange(c.size)
    backslash = c == ord("\\")
    # Backslashes in the run ending at each byte; a byte is escaped when an odd run precedes it.
    run = index - np.maximum.accumulate(np.where(backslash, -1, index))
    escaped = np.concatenate(([False], run[:-1] % 2 == 1))
    in_string = np.cumsum((c == ord('"')) & ~escaped) % 2 == 1  # a quote itself counts as inside: not a bracket
    opens = np.isin(c, np.frombuffer(b"[{", np.uint8)) & ~in_string
    closes = np.isin(c, np.frombuffer(b"]}", np.uint8)) & ~in_string
    return int(np.cumsum(opens.astype(np.int64) - closes).max(initial=0))


def _is_json(headers: dict[bytes, bytes]) -> bool:
    kind = headers.get(b"content-type", b"").split(b";")[0].strip().lower()
    return kind in (b"", b"application/json") or kind.endswith(b"+json")


class NestingLimit:
    """Refuse (422) a JSON body nested deeper than ``max_depth`` before anything parses it.

    Python's json parser, pydantic's errors and FastAPI's encoder all recurse: a 64 KB body can nest 30,000
    levels, a RecursionError (a 500 with a long traceback) or, from the parser, a 400 that does not say why.
    Runs inside :class:`BodyTimeout`, which has read the body already."""

    def __init__(self, app: ASGIApp, max_depth: int) -> None:
        self.app = app
        self.max_depth = max_depth

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or not _is_json(dict(scope["headers"])):
            await self.app(scope, receive, send)
            return
        received = await _receive_body(receive)
        depth = json_nesting(b"".join(m.get("body", b"") for m in received if m["type"] == "http.request"))
        if depth > self.max_depth:
            await JSONResponse({"detail": f"the body nests objects and arrays {depth} levels deep, at most "
                                f"{self.max_depth} are accepted (no request of this API needs more than 4)"},
                               status_code=int(HTTPStatus.UNPROCESSABLE_ENTITY))(scope, receive, send)
            return
        await self.app(scope, _replay(received, receive), send)


def create_app(service: Service) -> FastAPI:
    """The application around a built (not yet started) service; starting and stopping follow the lifespan."""

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        service.start()
        try:
            yield
        finally:
            service.stop()

    app = FastAPI(
        title="rigd",
        version=service.software_version,
        description="Targetless camera-LiDAR calibration service for a Ladybug5 + VLP-16 rig: capture datasets, "
        "calibrate them in a worker process, keep immutable extrinsics versions and export them.",
        lifespan=lifespan,
    )
    app.state.service = service
    for kind, _ in ERROR_STATUS:
        app.add_exception_handler(kind, _error_response)
    app.add_exception_handler(RequestValidationError, _validation_error)  # type: ignore[arg-type]
    app.add_exception_handler(QueueFullError, _queue_full)  # type: ignore[arg-type]
    app.add_middleware(NestingLimit, max_depth=MAX_NESTING)  # inside BodyTimeout: the body has arrived
    app.add_middleware(BodyTimeout, timeout_s=service.settings.body_timeout_s)
    app.add_middleware(BodyLimit, max_bytes=service.settings.max_body_bytes)  # added last: runs first
    for module in (status_routes, jobs, capture, calibrate, check, datasets, extrinsics):
        app.include_router(module.router)
    install_page(app)  # the operator page: rigd/web
    return app
