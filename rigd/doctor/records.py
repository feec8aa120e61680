"""What a check reports: one line with a status and, unless it is ok, the fix."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

from rigd.doctor.errors import DoctorError


class Status(Enum):
    """OK: nothing to do. WARN: works, but look at it (or it cannot be told from here). FAIL: rigd cannot do
    its job on this machine until it is fixed; ``rigd doctor`` then exits with code 1."""

    OK = "ok"
    WARN = "warn"
    FAIL = "fail"


@dataclass(frozen=True)
class Check:
    """One line of the report: ``name`` of what was checked, its ``status``, what was found (``detail``) and
    what to do about it (``fix``, empty when ok)."""

    name: str
    status: Status
    detail: str
    fix: str = ""


@dataclass(frozen=True)
class DoctorOptions:
    """``config``: the rig file given on the command line (None: $RIGD_CONFIG, ./rig.yaml, /etc/rigd/rig.yaml);
    ``listen_s``: how long to listen for VLP-16 packets (s); ``http_timeout_s``: for the service's reply (s);
    ``sdk_library``: overrides the rig file's Ladybug SDK library (None: the rig file's)."""

    config: Path | None = None
    listen_s: float = 1.5
    http_timeout_s: float = 2.0
    sdk_library: str | None = None

    def __post_init__(self) -> None:
        for name in ("listen_s", "http_timeout_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise DoctorError(f"doctor: {name} must be a positive number of seconds, got {value!r}")
