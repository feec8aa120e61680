"""The exact evaluator's compiled sums equal a brute force over every edge pixel (module calib.pixel_grid)."""

import numpy as np
import pytest

from calib.camera import Equirectangular, Pinhole
from calib.fields import SOFT_REACH, gaussian_kernel, soft_disk
from calib.pixel_grid import PixelGrid


def brute_force(camera, q, score, uv, sigma):
    """(N, 9) over every pixel: those within 4.5 sigma directly or across the u seam (a panorama), each at
    the camera's shortest displacement."""
    out = np.zeros((len(uv), 9))
    for i, (c, s) in enumerate(zip(uv, sigma, strict=True)):
        du = q[:, 0] - c[0]
        if isinstance(camera, Equirectangular):
            du = du - camera.width * np.round(du / camera.width)
        near = du**2 + (q[:, 1] - c[1]) ** 2 <= (SOFT_REACH * s) ** 2
        delta = camera.displacement(q[near], np.broadcast_to(c, (int(near.sum()), 2)))
        d2 = (delta**2).sum(axis=1)
        g = gaussian_kernel(d2, s)
        dg = np.where(d2 <= 9 * s * s, np.exp(-0.5 * d2 / s**2), 0.0)[:, None] * delta / s**2
        soft, dsoft = soft_disk(np.sqrt(d2), s)
        dsoft_c = -(dsoft / np.maximum(np.sqrt(d2), 1e-12))[:, None] * delta
        e = score[near]
        out[i] = [(e * g).sum(), *(e[:, None] * dg).sum(axis=0), g.sum(), *dg.sum(axis=0), soft.sum(),
                  *dsoft_c.sum(axis=0)]
    return out


@pytest.mark.parametrize("camera", [Equirectangular(256, 128),
                                    Pinhole(np.array([[200.0, 0, 150], [0, 200.0, 90], [0, 0, 1]]), np.zeros(5),
                                            300, 180)], ids=["panorama", "pinhole"])
def test_sums_equal_brute_force(camera):
    rng = np.random.default_rng(0)
    w, h = camera.width, camera.height
    q = np.c_[rng.uniform(-0.5, w - 0.5, 3000), rng.uniform(-0.5, h - 0.5, 3000)]
    score = rng.uniform(0.1, 1.0, 3000)
    uv = np.c_[rng.uniform(-10, w + 10, 400), rng.uniform(-10, h + 10, 400)]
    uv[:40, 0] = rng.uniform(-2, 2, 40)  # at the seam
    uv[40:60, 1] = rng.uniform(0, 3, 20)  # near the north pole
    sigma = np.exp(rng.uniform(np.log(0.7), np.log(40.0), 400))  # up to disks wider than the image
    grid = PixelGrid.build(q, score, w, h, isinstance(camera, Equirectangular))
    expected = brute_force(camera, q, score, uv, sigma)
    np.testing.assert_allclose(grid.sums(uv, sigma), expected, rtol=1e-10, atol=1e-10 * np.abs(expected).max())


def test_no_pixels_and_no_centres():
    grid = PixelGrid.build(np.zeros((0, 2)), np.zeros(0), 64, 32, True)
    assert np.array_equal(grid.sums(np.ones((3, 2)), np.ones(3)), np.zeros((3, 9)))
    full = PixelGrid.build(np.ones((5, 2)), np.ones(5), 64, 32, False)
    assert full.sums(np.zeros((0, 2)), np.zeros(0)).shape == (0, 9)
