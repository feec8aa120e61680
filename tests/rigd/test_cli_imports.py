"""What a command loads before it works: no library that only other commands or other methods use. Each is
memory in every process that loads it (numba 55 MiB; matplotlib and scipy's linear algebra stack were 44 MiB of a
12-pair calibration's 336 MiB peak, docs/performance.md) and time at every start."""

from __future__ import annotations

import subprocess
import sys

import pytest

# numba: calib's kernels, compiled at their first call (calib.compiled); matplotlib: plots (the evaluation, the
# elevation profile); scipy.optimize, scipy.spatial and the scipy.linalg and scipy.sparse they bring: NID and the
# paper's edge scores.
NOT_AT_START = ("numba", "matplotlib", "scipy.optimize", "scipy.spatial", "scipy.linalg", "scipy.sparse")

LOADED = """
import sys
from rigd.cli import build_parser
build_parser({command!r})
{imports}
print(" ".join(m for m in {names!r} if m in sys.modules))
"""

# Each command's parser and the modules its work starts from: the calibration job; the capture daemon and the
# service, which run for hours beside the drivers on the rig's computer.
STARTS = {
    "calibrate": "import rigd.calibration.job",
    "capture": "import rigd.capture.engine",
    "serve": "import rigd.api.main",
}


@pytest.mark.parametrize("command", sorted(STARTS))
def test_a_command_starts_without_the_libraries_it_does_not_use(command: str) -> None:
    code = LOADED.format(command=command, imports=STARTS[command], names=NOT_AT_START)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert done.stdout.split() == []
