"""calib.elevation: the LiDAR's common elevation offset, fitted beside the pose on a head."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from calib.assess import TrustOptions
from calib.elevation import fit_elevation_offset, offset_features, raise_elevation
from calib.errors import CalibError
from calib.geometry import rotation_angle_deg
from calib.gmm import PairFeatures
from calib.optimize import OptimResult, optimise
from calib.pipeline import CalibParams, calibrate, schedule
from tests.calib.synthetic import TRUTH, head_sensors, make_head_place

GRID_DEG = (0.0, 0.25, 0.5, 0.75)  # around the offset: the default grid's other points take time, show nothing more
PARAMS = replace(CalibParams(), elevation_grid_deg=GRID_DEG)
LOW_DEG = 0.4  # the simulated LiDAR's beams all read this much lower than they fire


def _head(places: tuple[int, ...]) -> list[PairFeatures]:
    sensors = head_sensors(3)  # 3 x 80 deg: round enough to tell the offset from a tilt
    by_place = [make_head_place(seed, sensors) for seed in places]
    return [place[k] for k in range(len(sensors)) for place in by_place]


def _reading_low(feats: list[PairFeatures]) -> list[PairFeatures]:
    return offset_features(feats, -LOW_DEG)


def test_raising_keeps_range_and_azimuth_and_adds_the_offset_to_the_elevation():
    points = np.array([[10.0, 0.0, 0.0], [0.0, -3.0, 4.0], [-2.0, 2.0, -1.0], [0.0, 0.0, 5.0]])
    raised = raise_elevation(points, 0.5)
    assert np.linalg.norm(raised, axis=1) == pytest.approx(np.linalg.norm(points, axis=1))
    side = slice(0, 3)
    azimuth = np.arctan2(points[side, 1], points[side, 0])
    assert np.arctan2(raised[side, 1], raised[side, 0]) == pytest.approx(azimuth)
    elevation = np.degrees(np.arctan2(points[side, 2], np.hypot(points[side, 0], points[side, 1])))
    new = np.degrees(np.arctan2(raised[side, 2], np.hypot(raised[side, 0], raised[side, 1])))
    assert new - elevation == pytest.approx([0.5] * 3)
    assert raised[3] == pytest.approx(points[3])  # straight up: no azimuth to turn about


def test_calibrating_with_the_fit_recovers_the_pose_the_offset_bent_and_a_declared_sigma_opens_it():
    feats = _reading_low(_head((0, 1, 2)))
    trust = TrustOptions(restarts=0)
    # without the fit, the offset declared as known to 0.05 deg: its sigma moves the pose as the fit's slope says
    declared = calibrate(feats, TRUTH, PARAMS, trust=replace(trust, elevation_sigma_deg=0.05))
    fitted = calibrate(feats, TRUTH, PARAMS, trust=trust, fit_elevation=True)
    assert fitted.elevation is not None and fitted.elevation.offset_deg == pytest.approx(LOW_DEG, abs=0.05)
    assert 0.0 < fitted.elevation.sigma_deg < 0.1 and not fitted.elevation.at_bound
    error = [np.linalg.norm(r.T_camera_lidar.translation_m - TRUTH.translation_m) for r in (declared, fitted)]
    assert error[1] < 0.5 * error[0]
    assert rotation_angle_deg(fitted.T_camera_lidar.rotation, TRUTH.rotation) < 0.05
    assert fitted.assessment is not None and fitted.assessment.uncertainty.elevation is not None
    assert declared.assessment is not None and declared.assessment.uncertainty.elevation is not None
    z_cm_per_deg = abs(fitted.elevation.slope[5]) * 100
    assert declared.assessment.uncertainty.elevation[5] == pytest.approx(0.05 * z_cm_per_deg, rel=0.3)


def test_fitting_the_offset_needs_three_places():
    feats = _head((0, 1))
    opts = schedule(feats, PARAMS, TRUTH.tau)
    with pytest.raises(CalibError, match="3 or more places"):
        fit_elevation_offset(feats, OptimResult(TRUTH.tau, (), True, 0.0), opts, PARAMS.gmm)


def _rings(points_lidar: np.ndarray) -> np.ndarray:
    """(N,) int64: 2 deg elevation bins as rings."""
    elevation = np.degrees(np.arctan2(points_lidar[:, 2], np.hypot(points_lidar[:, 0], points_lidar[:, 1])))
    return np.floor(elevation / 2.0).astype(np.int64)


def _with_rings(feats: list[PairFeatures], biased_ring: int, extra_deg: float) -> list[PairFeatures]:
    """``feats`` with rings (:func:`_rings`) and the points of one ring read ``extra_deg`` low besides."""
    out = []
    for f in feats:
        points = f.points.points_lidar
        ring = _rings(points)
        on = ring == biased_ring
        points = points.copy()
        points[on] = raise_elevation(points[on], -extra_deg)
        out.append(replace(f, points=replace(f.points, points_lidar=points, ring=ring)))
    return out


def test_one_ring_that_reads_low_in_every_place_is_seen_by_the_jackknife_over_rings():
    feats = _head((0, 1, 2))
    rings = np.concatenate([_rings(f.points.points_lidar) for f in feats])
    busiest = int(np.bincount(rings - rings.min()).argmax() + rings.min())
    biased = _with_rings(feats, busiest, 0.3)
    opts = schedule(biased, PARAMS, TRUTH.tau)
    fit = fit_elevation_offset(biased, optimise(biased, TRUTH.tau, opts, PARAMS.gmm), opts, PARAMS.gmm,
                               grid_deg=(-0.5, -0.25, 0.0, 0.25, 0.5))
    assert fit.sigma_rings_deg > 2 * fit.sigma_places_deg  # every place shares the ring: only rings see it
    assert fit.sigma_deg == fit.sigma_rings_deg
    assert abs(fit.offset_deg) < 2 * fit.sigma_deg  # the true offset is 0: the ring's pull is within the sigma
