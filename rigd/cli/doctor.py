"""``rigd doctor``: versions, rig file, data directory, VLP-16 packets, Ladybug5, service (docs/doctor.md)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rigd.cli.exit_codes import OK, UNHEALTHY
from rigd.doctor import Check, DoctorOptions, Status, run_checks

_WIDTH = max(len(s.value) for s in Status)


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "doctor",
        help="check this computer for a field run: versions, rig file, disk, VLP-16 packets, Ladybug5, service",
        description="One line per check, ok / warn / fail, with the fix. Exit code 1 if any check fails, else 0 "
        "(warnings do not fail). Listens on the VLP-16 data port for --listen seconds; the only thing it "
        "contacts is rigd serve's GET /status, and only on loopback. See docs/doctor.md.",
    )
    parser.add_argument("--config", type=Path, default=None,
                        help="rig file (default: $RIGD_CONFIG, ./rig.yaml, /etc/rigd/rig.yaml)")
    parser.add_argument("--listen", type=float, default=DoctorOptions.listen_s, metavar="SECONDS",
                        help=f"how long to wait for VLP-16 packets (default {DoctorOptions.listen_s:g})")
    parser.set_defaults(func=run)


def format_check(check: Check) -> str:
    """``status  name: detail`` and, unless ok, an indented ``fix:`` line."""
    line = f"{check.status.value:<{_WIDTH}}  {check.name}: {check.detail}"
    return line if check.status is Status.OK or not check.fix else f"{line}\n{'':<{_WIDTH}}  fix: {check.fix}"


def run(args: argparse.Namespace) -> int:
    checks = run_checks(DoctorOptions(config=args.config, listen_s=args.listen))
    for check in checks:
        print(format_check(check), flush=True)
    counts = {s: sum(c.status is s for c in checks) for s in Status}
    print(f"doctor: {counts[Status.OK]} ok, {counts[Status.WARN]} warn, {counts[Status.FAIL]} fail")
    return UNHEALTHY if counts[Status.FAIL] else OK
