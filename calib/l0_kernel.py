"""The element-wise steps of one L0 smoothing iteration, compiled (numba).

:func:`calib.edges_image.l0_smooth` spends most of an iteration outside its two FFTs: the forward
differences, the flattening test and the adjoint in space are eight numpy passes over the image with their
temporaries, and the spectral update three more over the half spectrum (about 60 % of the time on a
1620x616 image, measured with ``benchmarks/calibrate_profile.py --serial``). Here each is one loop, in the
same float32 arithmetic and the same order as the numpy steps they replace, so the result is bit-identical
(``tests/calib/test_l0_kernel.py`` compares them).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from calib.compiled import Kernel

F32 = NDArray[np.float32]
C64 = NDArray[np.complex64]


def _flattened_adjoint_py(smooth: F32, threshold: np.float32, gx: F32, gy: F32, adjoint: F32) -> None:
    """``adjoint`` (H,W) = D^T of the periodic forward differences of ``smooth`` (H,W), each pixel's pair
    (gx, gy) set to zero where gx^2 + gy^2 < ``threshold`` (the L0 step's hard threshold, lam / beta).
    ``gx``, ``gy`` (H,W) are scratch."""
    h, w = smooth.shape
    for i in range(h):
        down = i + 1 if i + 1 < h else 0
        for j in range(w):
            right = j + 1 if j + 1 < w else 0
            dx = smooth[i, right] - smooth[i, j]
            dy = smooth[down, j] - smooth[i, j]
            energy = dx * dx
            energy += dy * dy
            if energy < threshold:
                dx = np.float32(0.0)
                dy = np.float32(0.0)
            gx[i, j] = dx
            gy[i, j] = dy
    for i in range(h):
        up = i - 1 if i > 0 else h - 1
        for j in range(w):
            left = j - 1 if j > 0 else w - 1
            value = gx[i, left] - gx[i, j]
            value += gy[up, j]
            value -= gy[i, j]
            adjoint[i, j] = value


def _spectral_update_py(f_image: C64, f_adjoint: C64, beta: np.float32, denom_grad: F32) -> None:
    """``f_adjoint`` (H, W//2+1) becomes (f_image + beta f_adjoint) / (1 + beta denom_grad), in place: the
    L0 step's solve for S in the Fourier domain."""
    h, w = f_adjoint.shape
    one = np.float32(1.0)
    for i in range(h):
        for j in range(w):
            a = f_image[i, j]
            b = f_adjoint[i, j]
            re = a.real + beta * b.real
            im = a.imag + beta * b.imag
            scale = one / (one + beta * denom_grad[i, j])  # numpy's complex division by a real: times 1/d
            f_adjoint[i, j] = complex(re * scale, im * scale)


flattened_adjoint = Kernel(_flattened_adjoint_py, nogil=True)
spectral_update = Kernel(_spectral_update_py, nogil=True)
