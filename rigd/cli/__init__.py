"""The ``rigd`` command line: one module per subcommand, each with ``register(subparsers)``."""

from __future__ import annotations

import importlib
import sys
import traceback
from collections.abc import Sequence

from calib.errors import CalibError
from drivers.errors import DriverError
from rigd.cli.exit_codes import CANT_CREATE, ERROR, INTERRUPTED, IO_ERROR, OS_ERROR, SOFTWARE
from rigd.cli.parser import RigdArgumentParser
from rigd.errors import DiskError, OutputError, RigdError, WorkerLostError
from rigd.space import is_storage_error, os_error_text
from rigd.version import software_version

# Each module defines register(subparsers) and sets a handler with parser.set_defaults(func=...).
COMMAND_MODULES = ("simulate", "demo", "camera", "lidar", "calibrate", "check", "evaluate", "serve", "capture",
                   "doctor", "import", "export", "dataset")
MODULE_OF = {"import": "import_"}  # a command whose module name differs ('import' is a keyword)


def build_parser(command: str | None = None) -> RigdArgumentParser:
    """The parser with every subcommand, or only ``command``'s when it names one: importing the others
    (plots, simulator, web service) would cost a calibration ~55 MB of memory and most of a second."""
    parser = RigdArgumentParser(
        prog="rigd",
        description="Targetless camera-LiDAR calibration for a Ladybug5 + VLP-16 rig (Kang & Doh 2020).",
    )
    parser.add_argument("--version", action="version", version=f"rigd {software_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in (command,) if command in COMMAND_MODULES else COMMAND_MODULES:
        importlib.import_module(f"rigd.cli.{MODULE_OF.get(name, name)}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    words = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(words[0] if words else None)
    args = parser.parse_args(words)  # a wrong command line exits USAGE here
    try:
        return int(args.func(args) or 0)
    except (RigdError, DriverError, CalibError) as exc:
        print(f"rigd: error: {exc}", file=sys.stderr)
        return exit_code(exc)
    except OSError as exc:  # a file no layer named: its path, the system's reason (and the free space)
        print(f"rigd: error: {os_error_text(exc)}", file=sys.stderr)
        return IO_ERROR
    except KeyboardInterrupt:
        print("rigd: interrupted", file=sys.stderr)
        return INTERRUPTED
    except Exception as exc:  # a bug: its traceback, then a code no verdict has (rigd check's 1 is "drifted")
        traceback.print_exc()
        print(f"rigd: internal error (a bug, its traceback above): {exc!r}", file=sys.stderr)
        return SOFTWARE


def exit_code(exc: Exception) -> int:
    """The exit code of a named error (rigd.cli.exit_codes)."""
    if isinstance(exc, DiskError) or is_storage_error(exc):
        return IO_ERROR
    if isinstance(exc, WorkerLostError):
        return OS_ERROR
    return CANT_CREATE if isinstance(exc, OutputError) else ERROR


if __name__ == "__main__":
    sys.exit(main())
