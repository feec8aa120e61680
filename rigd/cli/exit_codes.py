"""Every exit code of ``rigd``, in this one table (docs/reliability.md#exit-codes gives the same numbers; the
README's command table, docs/trust.md and docs/check.md link to it).

``rigd calibrate`` and ``rigd check`` exit with their verdict, a member of calib.assess.Status or
calib.drift.DriftStatus, looked up here by its name (``Calibrate[status.name]``): rigd.cli imports this module for
every command, and importing those two calib modules costs about a third of a second (OpenCV, SciPy) that
``rigd lidar`` has no use for. tests/rigd/test_exit_codes.py holds the names against the enums.

Errors exit with codes of their own, BSD's sysexits.h (64 and up), which no verdict uses: a script reading
``rigd check``'s 1 (drifted) or 2 (unknown) can never be reading a crash or a refused file.
"""

from __future__ import annotations

import signal
from enum import IntEnum

OK = 0
UNHEALTHY = 1  # rigd doctor: a check failed; rigd camera info: no Ladybug found, or a health warning;
#               rigd camera export-head: written, but a sensor's lens fit is poor
NOT_STARTED = 3  # rigd serve could not start, as uvicorn.run exits (e.g. the port is taken)
USAGE = 64  # EX_USAGE: the command line is wrong (an unknown option, a value its type refuses), argparse's error
ERROR = 65  # EX_DATAERR: a RigdError, DriverError or CalibError, "rigd: error: ..." naming the thing refused
SOFTWARE = 70  # EX_SOFTWARE: an error rigd did not foresee (a bug): "rigd: internal error: ..." and its traceback
OS_ERROR = 71  # EX_OSERR: a worker process of the calibration ended abruptly (killed, out of memory)
CANT_CREATE = 73  # EX_CANTCREAT: an output refused: it is an input, or holds what another run wrote (--overwrite)
IO_ERROR = 74  # EX_IOERR: a write failed: the file system is full or read-only (the path and its free space named)
SIGNALLED = 128  # plus the signal's number: rigd capture stopped by SIGTERM exits 143
INTERRUPTED = SIGNALLED + signal.SIGINT  # Ctrl-C: 130


class Calibrate(IntEnum):
    """``rigd calibrate`` by its verdict, calib.assess.Status (docs/trust.md)."""

    TRUSTED = 0
    WEAK = 3
    FAILED = 4
    NOT_ASSESSED = 5  # a photometric baseline (--method mi|nid|gom): no uncertainty, no verdict


class Check(IntEnum):
    """``rigd check`` by its answer, calib.drift.DriftStatus (docs/check.md); an error exits with its own code."""

    OK = 0
    DRIFTED = 1
    UNKNOWN = 2
