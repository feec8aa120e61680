"""A VLP-16's per-laser vertical offsets, for clouds decoded without them.

Each VLP-16 laser leaves the sensor from its own height: the manual's geometry (drivers.vlp16.calibration) puts
the -15 deg laser's origin 11.2 mm above the sensor's origin and the +15 deg laser's 11.2 mm below, and a point is
``z = r sin(elevation) + offset``. rigd's decoder applies it; the ROS velodyne driver's VLP16db.yaml carried zero
offsets until 2023, so clouds recorded through it (and exported as PCD) have every ring's points on a cone through
the origin, the lower rings up to 11 mm low and the upper ones up to 11 mm high. rig.yaml ``lidar.vertical_offsets:
manual`` adds them as each cloud is loaded; `rigd import pairs` sets it when the clouds lack them
(:func:`lacks_vertical_offsets`).
"""

from __future__ import annotations

import dataclasses
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.calibration import manual_vertical_offset_m
from drivers.vlp16.layout import NOMINAL_ELEVATION_DEG
from rigd.dataset.pcd import Cloud
from rigd.errors import DatasetError

VLP16 = "VLP-16"
# rad: a ring whose points all lie this close to the nominal cone through the origin (median |elevation error|)
# was decoded without offsets: the smallest offset (0.7 mm of the +-1 deg lasers) is 0.04 deg at 1 m.
_CONE_TOLERANCE_RAD = np.radians(0.002)
_CLOSE_M = 5.0  # the test uses points nearer than this, where the largest offsets show most


class VerticalOffsets(Enum):
    """rig.yaml ``lidar.vertical_offsets``: the clouds as recorded, or with the VLP-16 manual's offsets added."""

    AS_RECORDED = "as-recorded"
    MANUAL = "manual"


def ring_elevations_deg() -> NDArray[np.float64]:
    """(16,) float64 deg: the VLP-16's nominal elevation of each ring (0 = lowest beam, as rigd numbers rings)."""
    return np.sort(NOMINAL_ELEVATION_DEG)


def ring_offsets_m() -> NDArray[np.float64]:
    """(16,) float64 m: the manual's vertical offset of each ring's laser (ring 0 the lowest beam, +11.2 mm)."""
    return manual_vertical_offset_m(ring_elevations_deg())


def _has_vlp16_rings(ring: NDArray[np.int16] | None) -> bool:
    return ring is not None and len(ring) > 0 and 0 <= int(ring.min()) and int(ring.max()) < len(NOMINAL_ELEVATION_DEG)


def _ring(cloud: Cloud, where: str) -> NDArray[np.int16]:
    ring = cloud.ring
    if ring is None or not _has_vlp16_rings(ring):
        held = "none" if ring is None or len(ring) == 0 else f"rings {int(ring.min())}..{int(ring.max())}"
        raise DatasetError(f"{where}: the VLP-16's vertical offsets need each point's ring (0..15); the cloud has "
                           f"{held}")
    return ring


def with_vertical_offsets(cloud: Cloud, where: str) -> Cloud:
    """``cloud`` with each point raised by its ring's manual offset (m, along the LiDAR's z); DatasetError naming
    ``where`` when the cloud has no VLP-16 rings."""
    ring = _ring(cloud, where)
    points = cloud.points_lidar.copy()
    points[:, 2] += ring_offsets_m()[ring]
    return dataclasses.replace(cloud, points_lidar=points)


def lacks_vertical_offsets(cloud: Cloud) -> bool:
    """Whether ``cloud`` (a VLP-16's, rings 0..15) was decoded without per-laser offsets: the points of every ring
    seen within 5 m lie on that ring's nominal cone through the origin. False for a cloud without such rings."""
    ring = cloud.ring
    if ring is None or not _has_vlp16_rings(ring):
        return False
    p = cloud.points_lidar
    horizontal = np.hypot(p[:, 0], p[:, 1])
    close = (np.linalg.norm(p, axis=1) < _CLOSE_M) & (horizontal > 0)
    elevation = np.arctan2(p[close, 2], horizontal[close])
    error = np.abs(elevation - np.radians(ring_elevations_deg())[ring[close]])
    rings = np.unique(ring[close])
    if len(rings) < 2:
        return False
    return all(float(np.median(error[ring[close] == r])) < _CONE_TOLERANCE_RAD for r in rings)
