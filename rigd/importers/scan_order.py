"""Laser rings of a cloud stored without them, from the order its points were recorded in.

Many recordings keep a multi-laser LiDAR's points laser by laser, each laser one turn in firing order (the
Ford Campus PCDs; KITTI's velodyne .bin files are stored in firing order too), but drop the ring number the
scan-line edges need (docs/method.md, item 1). Rounding the elevation to bins does not recover it for a dense
LiDAR: an HDL-64E's upper lasers are 0.3-0.4 deg apart, and its lasers sit centimetres off the sensor's
origin, so a near return's elevation from the origin is off by up to a degree. The order does recover it: one
laser's returns turn clockwise by 0.09-0.54 deg from one to the next, and a laser's turn ends after about
360 deg, where the next laser starts (its elevation different, its azimuth a few degrees back or ahead).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

NEAR_TURN_DEG = 330.0  # past this much of a turn, a laser may end (its first and last returns are not aligned)
MAX_TURN_DEG = 372.0  # no laser turns further: a laser's turn overlaps its start by a few degrees at most
ELEVATION_STEP_DEG = 0.12  # neighbouring lasers of an HDL-64E are at least 0.3 deg apart
BACK_STEP_DEG = 0.5  # a laser's next return never lies this far back (laser offsets shift near ones ~0.1 deg)
OFFSET_SHIFT_DEG = 2.0  # no range jump moves a return's elevation further (a laser ~0.2 m off the origin, >= 6 m)


def _turns(points_lidar: F64) -> tuple[F64, F64, F64]:
    """Per point: azimuth and elevation (deg), and (N-1,) the clockwise turn from each point to the next."""
    p = np.asarray(points_lidar, dtype=np.float64)
    azimuth = np.degrees(np.arctan2(p[:, 1], p[:, 0]))
    elevation = np.degrees(np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1])))
    turn = np.mod(azimuth[:-1] - azimuth[1:] + 180.0, 360.0) - 180.0
    return azimuth, elevation, turn


def rings_from_scan_order(points_lidar: F64) -> NDArray[np.int16]:
    """Ring (N,) int16 of each point of a cloud stored laser by laser in firing order, numbered by the lasers'
    median elevation (0 = lowest, as rigd's clouds number them)."""
    n = len(points_lidar)
    if n < 2:
        return np.zeros(n, np.int16)
    _, elevation, turn = _turns(points_lidar)
    rng = np.linalg.norm(points_lidar, axis=1)
    segment = np.zeros(n, np.int64)
    turned, current, i = 0.0, 0, 0
    while i < n - 1:
        step = max(float(turn[i]), 0.0)
        cut = i + 1 if turned + step > MAX_TURN_DEG else \
            _laser_start(i, turn, elevation, rng) if turned >= NEAR_TURN_DEG else None
        if cut is None:
            turned += step
            i += 1
            continue
        current, turned = current + 1, 0.0
        segment[cut:] = current
        i = cut
    medians = np.array([np.median(elevation[segment == k]) for k in range(current + 1)])
    rank = np.empty(current + 1, np.int64)
    rank[np.argsort(medians, kind="stable")] = np.arange(current + 1)
    return rank[segment].astype(np.int16)


def _laser_start(i: int, turn: F64, elevation: F64, rng: F64) -> int | None:
    """The first point of another laser at or just after point ``i + 1``, or None: the azimuth steps back, or
    the elevation of the next five returns differs from the last five's while the range does not jump (a jump
    alone moves a near return's elevation through the laser's offset, by up to ``OFFSET_SHIFT_DEG``). The cut
    goes where the elevation steps most within that window, so one odd return does not move it."""
    if turn[i] < -BACK_STEP_DEG:
        return i + 1
    before = float(np.median(elevation[max(0, i - 4):i + 1]))
    after = float(np.median(elevation[i + 1:i + 6]))
    same_range = abs(float(np.median(rng[i + 1:i + 6])) - float(np.median(rng[max(0, i - 4):i + 1]))) \
        < 0.5 + 0.05 * float(rng[i])
    change = abs(after - before)
    if change <= ELEVATION_STEP_DEG or (change <= OFFSET_SHIFT_DEG and not same_range):
        return None
    window = np.abs(np.diff(elevation[i:i + 6]))
    return i + 1 + int(np.argmax(window))
