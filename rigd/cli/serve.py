"""``rigd serve``: the HTTP service (FastAPI under uvicorn); settings from options, RIGD_* and the rig file."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rigd.api.settings import Settings, check_exposure, load_settings
from rigd.cli.exit_codes import NOT_STARTED, OK


def _settings_help() -> str:
    lines = ["settings (option > environment > 'service:' section of the rig file > default):"]
    for name, field in Settings.model_fields.items():
        default = "none" if field.default is None else field.default
        lines.append(f"  RIGD_{name.upper():34} {field.description} (default {default})")
    return "\n".join(lines)


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "serve",
        help="run the HTTP service (capture, calibrate, extrinsics versions, status)",
        description="Serves the rigd HTTP API with uvicorn (OpenAPI documentation at /docs). Listens on "
        "127.0.0.1 unless given another address, which needs an API token (RIGD_TOKEN): mutating requests "
        "must then carry 'Authorization: Bearer TOKEN'.",
        epilog=_settings_help(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--host", default=None, help="listen address (RIGD_HOST, default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=None, help="listen port (RIGD_PORT, default 8000)")
    parser.add_argument("--data-dir", type=Path, default=None, help="data directory (RIGD_DATA_DIR)")
    parser.add_argument("--config", type=Path, default=None, help="rig file, e.g. /etc/rigd/rig.yaml (RIGD_CONFIG)")
    parser.add_argument("--log-level", default=None, choices=["critical", "error", "warning", "info", "debug"],
                        help="uvicorn log level (RIGD_LOG_LEVEL, default info)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import uvicorn

    from rigd.api.connections import (
        accept_backlog,
        connection_cap,
        guarded_protocol,
        quiet_accept_errors,
        raise_fd_limit,
    )
    from rigd.api.main import create_app
    from rigd.api.service import build_service

    settings = load_settings(host=args.host, port=args.port, data_dir=args.data_dir, config=args.config,
                             log_level=args.log_level)
    check_exposure(settings)
    app = create_app(build_service(settings))
    protocol = guarded_protocol(settings.header_timeout_s, settings.max_connections)
    config = uvicorn.Config(app, host=settings.host, port=settings.port, log_level=settings.log_level,
                            timeout_graceful_shutdown=5, http=protocol)
    # After uvicorn.Config, which sets up the logging these go to (once, at startup); before it listens.
    fd_limit = raise_fd_limit()
    config.backlog = accept_backlog(fd_limit)
    protocol.max_connections = connection_cap(settings.max_connections, fd_limit)
    quiet_accept_errors()
    server = uvicorn.Server(config)
    try:
        server.run()
    except KeyboardInterrupt:  # uvicorn re-raises the Ctrl-C it handled, as uvicorn.run ignores it
        pass
    return OK if server.started else NOT_STARTED  # as uvicorn.run: e.g. the port is taken
