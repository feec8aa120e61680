"""A small synthetic scene for calib tests: 3-D line segments seen by a panorama and a LiDAR.

Edge pixels are the rasterised projections of the segments under a known T_camera_lidar; edge points
are samples along the same segments in the LiDAR frame. Expected values are therefore known by
construction, independently of the cost code.
"""

from __future__ import annotations

import numpy as np

from calib.camera import Equirectangular
from calib.edges_image import EdgePixels
from calib.edges_points import EdgePoints
from calib.fields import EdgeFields
from calib.geometry import Transform
from calib.gmm import PairFeatures
from calib.pixel_grid import PixelGrid

TRUTH = Transform.from_rpy_xyz(np.array([-0.18, 15.47, -55.14]), np.array([0.0934, 0.0597, -0.1659]))


def segments(seed: int, n: int = 40, scale: float = 1.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """Random vertical and horizontal segments 2-8 m from the origin, in the LiDAR frame (all of it times
    ``scale``: a scene so far that the lever arm moves no edge by a measurable amount)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        az = rng.uniform(-np.pi, np.pi)
        r = rng.uniform(2.0, 8.0)
        base = np.array([r * np.cos(az), r * np.sin(az), rng.uniform(-1.0, 0.5)])
        if rng.random() < 0.5:
            d = np.array([0.0, 0.0, rng.uniform(0.8, 1.5)])
        else:
            d = np.array([-np.sin(az), np.cos(az), 0.0]) * rng.uniform(0.8, 1.5)
        out.append((base * scale, (base + d) * scale))
    return out


def make_pair(seed: int, width: int = 512, height: int = 256, evaluator_fields: bool = True,
              scale: float = 1.0) -> PairFeatures:
    cam = Equirectangular(width, height)
    segs = segments(seed, scale=scale)
    pts_lidar = np.concatenate([a + np.linspace(0, 1, 60)[:, None] * (b - a) for a, b in segs])
    dense = np.concatenate([a + np.linspace(0, 1, 2000)[:, None] * (b - a) for a, b in segs])
    uv, _ = cam.project(TRUTH.apply(dense))
    pix = np.unique(np.stack([np.mod(np.rint(uv[:, 0]), width), np.clip(np.rint(uv[:, 1]), 0, height - 1)], 1),
                    axis=0)
    pixels = EdgePixels(pix.astype(np.float64), np.ones(len(pix)))
    points = EdgePoints(pts_lidar, np.ones(len(pts_lidar)), np.zeros(len(pts_lidar), np.int8))
    fields = EdgeFields.build(pixels.uv, pixels.score, width, height, True, 0.7, 48.0) if evaluator_fields else None
    grid = PixelGrid.build(pixels.uv, pixels.score, width, height, True)  # as calib.pipeline's features carry
    return PairFeatures(cam, pixels, points, fields, grid)
