"""Every exit code of ``rigd``, in this one table (the README's command table, docs/trust.md, docs/check.md and
docs/doctor.md give the same numbers).

``rigd calibrate`` and ``rigd check`` exit with their verdict, a member of calib.assess.Status or
calib.check.DriftStatus, looked up here by its name (``Calibrate[status.name]``): rigd.cli imports this module for
every command, and importing those two calib modules costs about a second (numba, OpenCV, SciPy) that
``rigd lidar`` has no use for. tests/rigd/test_exit_codes.py holds the names against the enums.
"""

from __future__ import annotations

import signal
from enum import IntEnum

OK = 0
ERROR = 2  # a RigdError, DriverError or CalibError ("rigd: error: ..."), and argparse's usage errors
UNHEALTHY = 1  # rigd doctor: a check failed; rigd camera info: no Ladybug found, or a health warning;
#               rigd camera export-head: written, but a sensor's lens fit is poor
NOT_STARTED = 3  # rigd serve could not start, as uvicorn.run exits (e.g. the port is taken)
SIGNALLED = 128  # plus the signal's number: rigd capture stopped by SIGTERM exits 143
INTERRUPTED = SIGNALLED + signal.SIGINT  # Ctrl-C: 130


class Calibrate(IntEnum):
    """``rigd calibrate`` by its verdict, calib.assess.Status (docs/trust.md)."""

    TRUSTED = 0
    WEAK = 3
    FAILED = 4
    NOT_ASSESSED = 5  # a photometric baseline (--method mi|nid|gom): no uncertainty, no verdict


class Check(IntEnum):
    """``rigd check`` by its answer, calib.check.DriftStatus (docs/check.md); an error also exits 2."""

    OK = 0
    DRIFTED = 1
    UNKNOWN = 2
