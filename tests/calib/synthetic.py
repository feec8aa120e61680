"""A small synthetic scene for calib tests: 3-D line segments seen by a panorama and a LiDAR.

Edge pixels are the rasterised projections of the segments under a known T_camera_lidar; edge points
are samples along the same segments in the LiDAR frame. Expected values are therefore known by
construction, independently of the cost code.
"""

from __future__ import annotations

import numpy as np

from calib.camera import Equirectangular, Mounted, Pinhole
from calib.edges_image import EdgePixels
from calib.edges_points import EdgePoints
from calib.fields import EdgeFields
from calib.geometry import Transform
from calib.gmm import PairFeatures, in_image
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
    fields = (EdgeFields.build(pixels.uv, pixels.score, width, height, wrap_u=True, sigma_min=0.7, sigma_max=48.0)
              if evaluator_fields else None)
    grid = PixelGrid.build(pixels.uv, pixels.score, width, height, True)  # as calib.pipeline's features carry
    return PairFeatures(cam, pixels, points, fields, grid)


def head_sensors(n: int = 5, width: int = 400, height: int = 300) -> list[Mounted]:
    """A Ladybug-like head: ``n`` pinhole sensors looking out round the head's up axis, 4 cm off its centre
    (optical frame: z out, x clockwise, y down), 80 deg of horizontal field each."""
    f = (width / 2) / np.tan(np.radians(40.0))
    pinhole = Pinhole(np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]]),
                      np.zeros(5), width, height)
    out = []
    for k in range(n):
        yaw = 360.0 * k / n
        T_head_sensor = Transform.from_rpy_xyz(np.array([-90.0, 0.0, yaw - 90.0]),
                                               0.04 * np.array([np.cos(np.radians(yaw)), np.sin(np.radians(yaw)), 0]))
        inverse = T_head_sensor.inverse()
        out.append(Mounted(f"cam{k}", pinhole, inverse.rotation, inverse.translation_m))
    return out


def make_head_place(seed: int, sensors: list[Mounted]) -> list[PairFeatures]:
    """One place of a head: the scene of :func:`segments` rasterised into every sensor under ``TRUTH`` (as
    T_head_lidar), one :class:`PairFeatures` per sensor sharing the cloud's edge points, place ``seed``."""
    segs = segments(seed)
    pts_lidar = np.concatenate([a + np.linspace(0, 1, 60)[:, None] * (b - a) for a, b in segs])
    dense = np.concatenate([a + np.linspace(0, 1, 2000)[:, None] * (b - a) for a, b in segs])
    points = EdgePoints(pts_lidar, np.ones(len(pts_lidar)), np.zeros(len(pts_lidar), np.int8))
    feats = []
    for cam in sensors:
        uv, valid = cam.project(TRUTH.apply(dense))
        inside = in_image(cam, uv, valid)
        pix = np.unique(np.rint(uv[inside]), axis=0)
        pixels = EdgePixels(pix.astype(np.float64), np.ones(len(pix)))
        fields = EdgeFields.build(pixels.uv, pixels.score, cam.width, cam.height, wrap_u=False, sigma_min=0.7,
                                  sigma_max=48.0)
        grid = PixelGrid.build(pixels.uv, pixels.score, cam.width, cam.height, False)
        feats.append(PairFeatures(cam, pixels, points, fields, grid, place=seed))
    return feats
