"""calib.search: the global search for an initial guess, and its runners-up in the assessment."""

import dataclasses
import weakref

import numpy as np
import pytest

import calib.search as initial_module
from calib.assess import TrustOptions, assess
from calib.camera import Pinhole
from calib.geometry import Transform, rotation_angle_deg, so3_exp
from calib.gmm import Evaluator, GmmOptions
from calib.optimize import OptimOptions, optimise
from calib.pipeline import CalibParams, calibrate
from calib.search import SearchOptions, base_rotation, default_search, grid_mounts, search_initial
from tests.calib.synthetic import TRUTH, make_pair

FIELD = dataclasses.replace(GmmOptions(), evaluator=Evaluator.FIELD)


@pytest.fixture(scope="module")
def pairs():
    return [make_pair(1), make_pair(2)]


def test_grid_covers_every_yaw_and_the_tilt_range():
    mounts = grid_mounts(SearchOptions(yaw_step_deg=15.0, tilt_deg=30.0, tilt_step_deg=15.0))
    assert len(mounts) == 24 * 5 * 5
    assert mounts[:, 2].min() == -180.0 and mounts[:, 2].max() == 165.0
    assert np.abs(mounts[:, :2]).max() == 30.0
    assert len(np.unique(mounts, axis=0)) == len(mounts)


def test_pinhole_search_looks_along_the_lidar_forward_axis_within_the_field_of_view(pairs):
    pinhole = Pinhole(np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]]), np.zeros(5), 640, 480)
    base = base_rotation(pinhole)
    # LiDAR forward, left, up -> optical z, -x, -y
    np.testing.assert_array_equal(base @ [1, 0, 0], [0, 0, 1])
    np.testing.assert_array_equal(base @ [0, 1, 0], [-1, 0, 0])
    np.testing.assert_array_equal(base @ [0, 0, 1], [0, -1, 0])
    np.testing.assert_array_equal(base_rotation(pairs[0].camera), np.eye(3))
    opts = default_search(pinhole)  # 65.2 x 51.3 deg field of view
    assert opts.yaw_range_deg == pytest.approx(np.degrees(np.arctan(0.64)))
    assert opts.tilt_deg == pytest.approx(np.degrees(np.arctan(0.48)))
    mounts = grid_mounts(opts)
    assert mounts[:, 2].min() == pytest.approx(-opts.yaw_range_deg) and mounts[:, 2].max() <= opts.yaw_range_deg
    assert default_search(pairs[0].camera) == SearchOptions()


def test_search_finds_a_mount_far_outside_the_local_basin(pairs):
    # TRUTH is yaw -55 deg, pitch 15 deg from the identity; the lever arm (20 cm) is not given.
    coarse = SearchOptions(yaw_step_deg=30.0, tilt_step_deg=30.0)  # the nearest mount is 15 deg off in pitch
    found = search_initial(pairs, np.zeros(3), coarse)
    best = so3_exp(found.best.tau[:3])
    assert rotation_angle_deg(best, TRUTH.rotation) < 3.0
    costs = [c.cost for c in found.candidates]
    assert costs == sorted(costs)
    for c in found.candidates[1:]:  # runners-up are distinct poses
        assert rotation_angle_deg(so3_exp(c.tau[:3]), best) > SearchOptions().distinct_deg
    final = optimise(pairs, found.best.tau, OptimOptions(), FIELD)
    assert rotation_angle_deg(so3_exp(final.tau[:3]), TRUTH.rotation) < 0.05


def test_calibrate_without_a_guess_reports_the_search_and_weighs_the_runner_up(pairs):
    params = dataclasses.replace(CalibParams(), gmm=FIELD)
    result = calibrate(pairs, None, params, trust=TrustOptions(restarts=1),
                       search=SearchOptions(yaw_step_deg=30.0, tilt_step_deg=30.0))
    assert result.search is not None and result.assessment is not None
    assert rotation_angle_deg(result.T_camera_lidar.rotation, TRUTH.rotation) < 0.05
    origins = [r.origin for r in result.assessment.restarts]
    assert origins.count("search runner-up") == min(1, len(result.search.candidates) - 1)


def test_an_alternative_that_ends_lower_replaces_a_stuck_solution(pairs):
    stuck_start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [0.0, 0.0, 60.0], TRUTH.translation_m)
    opts = dataclasses.replace(OptimOptions(), alternative_schedules=0)
    stuck = optimise(pairs, stuck_start.tau, opts, FIELD)
    assert rotation_angle_deg(so3_exp(stuck.tau[:3]), TRUTH.rotation) > 10.0  # a far local minimum
    good = optimise(pairs, TRUTH.tau, opts, FIELD)
    a = assess(pairs, stuck, opts, FIELD, prior=None, trust=TrustOptions(restarts=1), alternatives=(good,))
    assert rotation_angle_deg(so3_exp(a.tau[:3]), TRUTH.rotation) < 0.05
    assert [r.origin for r in a.restarts if r.origin.startswith("search")] == ["search start"]
    # The restarts probe the new solution's basin, not the stuck start's 60 deg away: they come back to it (a
    # restart that ends lower is the solution, and the first solution is listed in its place).
    restarts = [r for r in a.restarts if r.origin in ("restart", "solution")]
    assert restarts and all(np.all(np.abs(r.offset) < [0.2, 0.2, 0.2, 1.0, 1.0, 1.0]) for r in restarts)


class _Blurred(list):  # a stand-in for one width's blurred pairs, weakly referenceable
    pass


def test_the_mi_polish_prepares_each_blur_once_and_holds_only_the_current_one(monkeypatch):
    """The candidates are polished width by width and the score keeps one width's blurred images (300 MB per
    width on a Ladybug5-size head): each width is prepared once, and an earlier width's copies are let go."""
    made: list[tuple[float, weakref.ref]] = []

    def prepare(photo, blur_deg, seed=0):
        blurred = _Blurred([blur_deg])
        made.append((blur_deg, weakref.ref(blurred)))
        return blurred

    monkeypatch.setattr(initial_module, "prepare", prepare)
    monkeypatch.setattr(initial_module, "mi_costs", lambda prepared, rotations, t: np.zeros(len(rotations)))
    score = initial_module._mi_score([])
    steps = ((8.0, 2.0), (4.0, 1.0), (2.0, 1.0), (1.0, 0.5))
    polished = initial_module._polish_all(score, [np.eye(3)] * 3, np.zeros(3), steps, 2)
    assert len(polished) == 3
    assert [width for width, _ in made] == [2.0, 1.0, 0.5]
    assert [ref() is not None for _, ref in made] == [False, False, True]


def test_progress_counts_the_mi_batches_then_the_pairs_edge_grids(pairs, monkeypatch):
    """With images the MI grid runs first in this process: the bar moves with its batches, not after them."""
    monkeypatch.setattr(initial_module, "prepare", lambda photo, blur_deg, seed=0: [])
    monkeypatch.setattr(initial_module, "mi_costs", lambda prepared, rotations, t: -np.ones(len(rotations)))
    seen: list[tuple[int, int]] = []
    coarse = SearchOptions(yaw_step_deg=30.0, tilt_step_deg=30.0)  # 108 mounts: 2 MI batches of 64
    found = search_initial(pairs, np.zeros(3), coarse, on_progress=lambda done, total: seen.append((done, total)),
                           photo=[object()])
    assert found.scores == ("edges", "mutual information")
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)]
