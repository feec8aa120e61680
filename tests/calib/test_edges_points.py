"""LiDAR edge points along the rings: boundaries against the ring's own azimuth step, and gaps of missing
returns that a surface bridges."""

from __future__ import annotations

import numpy as np

from calib.edges_points import BOUNDARY, ScanlineEdgeParams, azimuth_step, scanline_edge_points


def _ring(azimuth_deg: np.ndarray, range_m: np.ndarray, elevation_deg: float = -10.0) -> np.ndarray:
    """Points (N,3) m of one ring at the given azimuths and ranges."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.stack([range_m * np.cos(el) * np.cos(az), range_m * np.cos(el) * np.sin(az),
                     range_m * np.full_like(az, np.sin(el))], axis=1)


def _boundaries(points: np.ndarray) -> np.ndarray:
    edges = scanline_edge_points(points, np.zeros(len(points), np.int16), ScanlineEdgeParams(use_folds=False))
    return edges.points_lidar[edges.kind == BOUNDARY]


def test_the_azimuth_step_is_the_rings_own() -> None:
    for step in (0.09, 0.2, 0.45):
        pts = _ring(np.arange(-180.0, 180.0, step), np.full(int(round(360 / step)), 12.0))
        assert abs(np.degrees(azimuth_step(pts)) - step) < 1e-6


def test_a_coarse_ring_on_flat_ground_has_no_boundaries() -> None:
    # An HDL-64E's lower block fires every 0.45 deg with an occasional 0.54 deg step: a fixed 0.5 deg gap
    # threshold read every such step as missing returns and put boundaries all over the ground.
    az = np.cumsum(np.where(np.arange(800) % 7 == 0, 0.54, 0.45)) - 180.0
    az = az[az < 180.0]
    assert len(_boundaries(_ring(az, np.full(len(az), 9.0)))) == 0


def test_a_dropout_bridged_by_one_surface_is_not_a_silhouette() -> None:
    az = np.arange(-180.0, 180.0, 0.2)
    keep = (az < 10.0) | (az > 14.0)  # 4 deg without returns (a dark window) in a wall at one range
    assert len(_boundaries(_ring(az[keep], np.full(int(keep.sum()), 15.0)))) == 0


def test_a_gap_to_the_sky_keeps_both_sides() -> None:
    az = np.arange(-180.0, 180.0, 0.2)
    keep = (az < 10.0) | (az > 40.0)  # 30 deg of sky between two buildings at one range
    found = _boundaries(_ring(az[keep], np.full(int(keep.sum()), 15.0), elevation_deg=5.0))
    found_az = np.degrees(np.arctan2(found[:, 1], found[:, 0]))
    assert np.any(np.abs(found_az - 9.9) < 0.15) and np.any(np.abs(found_az - 40.1) < 0.15)


def test_a_jump_across_missing_returns_marks_only_the_near_side() -> None:
    az = np.arange(-180.0, 180.0, 0.2)
    rng = np.where(az < 10.0, 5.0, 20.0)  # a near pole's edge at 10 deg, then returns only from 13 deg on
    keep = (az < 10.0) | (az > 13.0)
    found = _boundaries(_ring(az[keep], rng[keep]))
    found_range = np.linalg.norm(found, axis=1)
    near = np.abs(np.degrees(np.arctan2(found[:, 1], found[:, 0])) - 9.9) < 0.15
    assert near.any() and np.allclose(found_range[near], 5.0)
    assert not np.any(np.abs(found_range - 20.0) < 0.1)  # the far side is the occluded background
