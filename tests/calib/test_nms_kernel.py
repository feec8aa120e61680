"""The compiled non-maximum suppression equals the numpy formulation it replaced, pixel for pixel."""

from __future__ import annotations

import numpy as np
import pytest

from calib.edges_image import _SECTOR_STEPS, _gradient_sector, _sobel, non_max_suppression


def _numpy_nms(magnitude: np.ndarray, gx: np.ndarray, gy: np.ndarray, wrap_u: bool) -> np.ndarray:
    sector = _gradient_sector(gx, gy)
    padded = np.pad(magnitude, ((1, 1), (0, 0)), mode="edge")
    padded = np.pad(padded, ((0, 0), (1, 1)), mode="wrap" if wrap_u else "edge")
    h, w = magnitude.shape
    keep = np.zeros_like(magnitude, dtype=bool)
    for s, (du, dv) in enumerate(_SECTOR_STEPS):
        fwd = padded[1 + dv: 1 + dv + h, 1 + du: 1 + du + w]
        bwd = padded[1 - dv: 1 - dv + h, 1 - du: 1 - du + w]
        keep |= (sector == s) & (magnitude >= fwd) & (magnitude > bwd)
    return np.where(keep, magnitude, 0.0)


@pytest.mark.parametrize("wrap_u", [False, True])
def test_nms_equals_numpy_on_a_textured_image_with_plateaus(wrap_u: bool) -> None:
    rng = np.random.default_rng(5)
    grey = np.round(rng.random((41, 67)) * 4) / 4  # few grey levels: ties, plateaus, exact 45-degree angles
    grey[10:20, 5:30] = 1.0
    gx, gy = _sobel(grey, wrap_u)
    magnitude = np.hypot(gx, gy)
    expected = _numpy_nms(magnitude, gx, gy, wrap_u)
    assert np.array_equal(non_max_suppression(magnitude, gx, gy, wrap_u), expected)
    assert 0 < np.count_nonzero(expected) < magnitude.size


def test_sector_boundaries_at_exact_angles() -> None:
    """Gradients at 0, +-22.5, 45, 90, 180 degrees and zero: the kernel's sector equals numpy's."""
    angles = np.radians([0.0, 22.5, -22.5, 45.0, 67.5, 90.0, 112.5, 135.0, 157.5, 180.0, -180.0, -90.0])
    gx, gy = np.cos(angles)[None, :].repeat(3, 0), np.sin(angles)[None, :].repeat(3, 0)
    gx[:, -1], gy[:, -1] = 0.0, 0.0
    magnitude = np.tile([[1.0], [3.0], [2.0]], (1, len(angles)))  # the middle row is the maximum across rows
    for wrap_u in (False, True):
        assert np.array_equal(non_max_suppression(magnitude, gx, gy, wrap_u), _numpy_nms(magnitude, gx, gy, wrap_u))
