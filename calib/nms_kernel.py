"""Non-maximum suppression of an edge-magnitude image, compiled (numba).

:func:`calib.edges_image.non_max_suppression` in numpy makes a dozen full-image temporaries (the gradient
angle, its sector, four pairs of shifted neighbour images, the masks); on the Ford head's 1616x616 images that
was about a fifth of the features' time outside L0 smoothing. Here it is one pass, with the same arithmetic
(the angle in degrees folded into [0, 180), rounded half to even into four 45-degree sectors) and the same
borders: rows repeat their edge, columns wrap round a panorama and repeat their edge otherwise.
``tests/calib/test_nms_kernel.py`` compares it with the numpy steps on real and random images.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from calib.compiled import Kernel

F64 = NDArray[np.float64]

_TO_DEGREES = 180.0 / math.pi  # numpy's rad2deg multiplies by this constant


def _non_max_py(magnitude: F64, gx: F64, gy: F64, wrap_u: bool, out: F64) -> None:
    """``out`` (H,W) = ``magnitude`` (H,W) where it is a maximum across the edge (>= the next pixel along
    the gradient, > the previous one), else 0."""
    h, w = magnitude.shape
    for i in range(h):
        for j in range(w):
            angle = math.atan2(gy[i, j], gx[i, j]) * _TO_DEGREES
            if angle >= 180.0 or angle <= -180.0:  # np.mod(+-180, 180) is +0
                angle = 0.0
            elif angle < 0.0:
                angle += 180.0
            sector = int(np.rint(angle / 45.0)) % 4
            du = 1 if sector < 2 else (0 if sector == 2 else -1)
            dv = 0 if sector == 0 else 1
            fi, bi = min(max(i + dv, 0), h - 1), min(max(i - dv, 0), h - 1)
            fj, bj = j + du, j - du
            if wrap_u:
                fj, bj = fj % w, bj % w
            else:
                fj, bj = min(max(fj, 0), w - 1), min(max(bj, 0), w - 1)
            m = magnitude[i, j]
            out[i, j] = m if (m >= magnitude[fi, fj] and m > magnitude[bi, bj]) else 0.0


non_max = Kernel(_non_max_py, nogil=True)
