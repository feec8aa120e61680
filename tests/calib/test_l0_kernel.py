"""The compiled L0 iteration steps equal the numpy steps they replace, bit for bit."""

from __future__ import annotations

import numpy as np
import scipy.fft

from calib.l0_kernel import flattened_adjoint, spectral_update


def _numpy_adjoint(smooth: np.ndarray, threshold: float) -> np.ndarray:
    gx = np.roll(smooth, -1, axis=1) - smooth
    gy = np.roll(smooth, -1, axis=0) - smooth
    energy = gx * gx
    energy += gy * gy
    flat = energy < np.float32(threshold)
    gx[flat], gy[flat] = 0.0, 0.0
    out = np.roll(gx, 1, axis=1) - gx
    out += np.roll(gy, 1, axis=0)
    out -= gy
    return out


def test_flattened_adjoint_equals_numpy_on_odd_sizes_with_wrap() -> None:
    rng = np.random.default_rng(3)
    smooth = rng.random((37, 53)).astype(np.float32)
    scratch = [np.empty_like(smooth) for _ in range(3)]
    for threshold in (1e-4, 0.05, 0.4):
        flattened_adjoint(smooth, np.float32(threshold), *scratch)
        expected = _numpy_adjoint(smooth, threshold)
        assert np.array_equal(scratch[2], expected)
        assert 0 < np.count_nonzero(expected)


def test_spectral_update_equals_numpy_complex_division() -> None:
    rng = np.random.default_rng(4)
    f_image = scipy.fft.rfft2(rng.random((24, 40)).astype(np.float32))
    f_adjoint = scipy.fft.rfft2(rng.standard_normal((24, 40)).astype(np.float32))
    denom = (rng.random(f_image.shape) * 8).astype(np.float32)
    beta = np.float32(37.5)
    expected = (f_image + beta * f_adjoint) / (np.float32(1.0) + beta * denom)
    spectral_update(f_image, f_adjoint, beta, denom)
    assert f_adjoint.dtype == np.complex64
    assert np.array_equal(f_adjoint, expected)
