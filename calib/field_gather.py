"""The field evaluator's gather, compiled (numba): bilinear samples of one image's built bands.

:func:`calib.fields.sample_fields` reads, for every centre, the four bilinear corners on the two rungs nearest
its sigma from the bands of :class:`calib.fields.EdgeFields`, and interpolates in space and in log sigma. In
numpy that is a dozen (4, N, 2)-shaped temporaries per call, for a few thousand centres; here it is one loop,
with the same arithmetic in the same order (the values are bit-identical: tests/calib/test_fields.py). A
corner on a row its block has not built yet stops the loop and returns False: the caller grows the bands
(numpy, rare) and samples again.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from calib.compiled import Kernel

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
I64 = NDArray[np.int64]

_DX = (0, 1, 0, 1)  # corners (0, 0), (1, 0), (0, 1), (1, 1), in calib.fields' order
_DY = (0, 0, 1, 1)


def _gather_py(uv: F64, pos: F64, factor: I64, hf: I64, wf: I64, cb: I64, bw: I64, row0: I64, rows: I64,
               offset: I64, flat: F32, wrap_u: bool, out: F64) -> bool:
    """Samples of centres ``uv`` (N,2) px at rung positions ``pos`` (N,) (log-sigma ladder index) into
    ``out`` (N, 9); False (``out`` incomplete) when a corner inside the image lies on an unbuilt row."""
    n_rungs = factor.shape[0]
    last = flat.shape[0] - 1
    both = np.zeros((2, 9))
    for i in range(uv.shape[0]):
        k0 = int(math.floor(pos[i]))
        t = pos[i] - k0
        both[:] = 0.0
        for side in range(2):
            k = k0 if side == 0 else min(k0 + 1, n_rungs - 1)
            f = factor[k]
            x = (uv[i, 0] - (f - 1) / 2.0) / f
            y = (uv[i, 1] - (f - 1) / 2.0) / f
            x0, y0 = math.floor(x), math.floor(y)
            ax, ay = x - x0, y - y0
            for c in range(4):
                xi, yi = int(x0) + _DX[c], int(y0) + _DY[c]
                if wrap_u:
                    xi = xi % wf[k]
                ok = 0 <= xi < wf[k] and 0 <= yi < hf[k]
                wx = 1 - ax if _DX[c] == 0 else ax
                wy = 1 - ay if _DY[c] == 0 else ay
                weight = wx * wy if ok else 0.0
                xi = min(max(xi, 0), wf[k] - 1)
                block = xi // cb[k]
                r0, nr = row0[k, block], rows[k, block]
                if ok and (nr == 0 or yi < r0 or yi >= r0 + nr):
                    return False
                row_in_block = min(max(yi - r0, 0), max(nr - 1, 0))
                cell = offset[k, block] + row_in_block * bw[k, block] + xi - block * cb[k]
                if last < 0:  # nothing built yet and this corner outside the image: it adds zero
                    continue
                cell = min(max(cell, 0), last)
                for ch in range(9):
                    both[side, ch] += weight * np.float64(flat[cell, ch])
        for ch in range(9):
            out[i, ch] = (1.0 - t) * both[0, ch] + t * both[1, ch]
    return True


gather = Kernel(_gather_py, nogil=True)
