"""What `rigd calibrate` loads before it calibrates: no library that only other commands or other methods use.
Each is memory in every calibration and in each worker process it starts (matplotlib and scipy's linear algebra
stack were 44 MiB of a 12-pair calibration's 336 MiB peak, docs/performance.md), and time in every start."""

from __future__ import annotations

import subprocess
import sys

# matplotlib: plots (evaluation, the elevation profile); scipy.optimize, scipy.spatial and the scipy.linalg and
# scipy.sparse they bring: NID and the paper's edge scores; fastapi: the service.
NOT_AT_START = ("matplotlib", "scipy.optimize", "scipy.spatial", "scipy.linalg", "scipy.sparse", "fastapi")

LOADED = """
import sys
from rigd.cli import build_parser
build_parser("calibrate")
import rigd.calibration.job, calib.assess  # the command's job and what its pool's workers preload
print(" ".join(m for m in {names} if m in sys.modules))
"""


def test_the_calibrate_command_starts_without_the_libraries_it_does_not_use() -> None:
    code = LOADED.format(names=repr(NOT_AT_START))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert done.stdout.split() == []
