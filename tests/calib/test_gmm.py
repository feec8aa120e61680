import dataclasses

import numpy as np
import pytest

from calib.geometry import Transform, rotation_angle_deg
from calib.gmm import Evaluator, GmmOptions, KernelNorm, cost_and_gradient, freeze
from calib.optimize import OptimOptions, optimise
from tests.calib.synthetic import TRUTH, make_pair

EXACT = dataclasses.replace(GmmOptions(), evaluator=Evaluator.EXACT)
FIELD = dataclasses.replace(GmmOptions(), evaluator=Evaluator.FIELD)


@pytest.fixture(scope="module")
def pairs():
    return [make_pair(1), make_pair(2)]


def _sigma_px(feats, deg):
    return [np.radians(deg) * f.camera.pixels_per_radian for f in feats]


def _frozen_cost(feats, tau, s, opts):
    frozen = [freeze(f, tau, si, opts) for f, si in zip(feats, s, strict=True)]
    return frozen, cost_and_gradient(feats, frozen, tau, s, opts)


@pytest.mark.parametrize("opts", [EXACT, dataclasses.replace(EXACT, kernel_norm=KernelNorm.PAPER),
                                  dataclasses.replace(EXACT, weighted=False)])
def test_analytic_gradient_matches_finite_differences_of_the_frozen_model(pairs, opts):
    tau = TRUTH.tau + np.array([0.02, -0.01, 0.015, 0.03, -0.02, 0.01])
    s = _sigma_px(pairs, 3.0)
    frozen, cg = _frozen_cost(pairs, tau, s, opts)
    numeric = np.zeros(6)
    for k in range(6):
        e = np.zeros(6)
        e[k] = 1e-6
        plus = cost_and_gradient(pairs, frozen, tau + e, s, opts).cost
        minus = cost_and_gradient(pairs, frozen, tau - e, s, opts).cost
        numeric[k] = (plus - minus) / 2e-6
    assert np.linalg.norm(cg.gradient - numeric) < 0.02 * np.linalg.norm(numeric)


def test_field_evaluator_agrees_with_exact_enumeration(pairs):
    tau = TRUTH.tau + np.array([0.01, 0.0, -0.01, 0.02, 0.0, 0.0])
    for deg in (10.0, 20.0, 40.0):  # wide enough for the pooled rungs (narrower centres are summed exactly)
        s = _sigma_px(pairs, deg)
        exact = _frozen_cost(pairs, tau, s, EXACT)[1]
        field = _frozen_cost(pairs, tau, s, FIELD)[1]
        assert abs(field.cost - exact.cost) < 0.05 * abs(exact.cost)
        cos = field.gradient @ exact.gradient / np.linalg.norm(field.gradient) / np.linalg.norm(exact.gradient)
        assert cos > 0.9


def test_truth_is_cheaper_than_perturbed_poses(pairs):
    s = _sigma_px(pairs, 2.0)
    at_truth = _frozen_cost(pairs, TRUTH.tau, s, FIELD)[1].cost
    rng = np.random.default_rng(0)
    for _ in range(5):
        d = np.r_[rng.uniform(-0.03, 0.03, 3), rng.uniform(-0.05, 0.05, 3)]
        assert _frozen_cost(pairs, TRUTH.tau + d, s, FIELD)[1].cost > at_truth


def test_optimiser_recovers_truth_from_a_perturbed_start(pairs):
    start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [2.0, -2.0, 2.5], TRUTH.translation_m + [0.05, -0.04, 0.05])
    result = optimise(pairs, start.tau, OptimOptions(), FIELD)
    found = Transform.from_tau(result.tau)
    assert rotation_angle_deg(found.rotation, TRUTH.rotation) < 0.2
    assert np.linalg.norm(found.translation_m - TRUTH.translation_m) < 0.02
    for level in result.levels:  # the cost never rises across accepted iterations by more than refreezing noise
        assert level.costs[-1] <= level.costs[0] + 1e-9


def test_field_evaluator_sums_narrow_centres_exactly_and_builds_no_full_resolution_rung():
    feats = [make_pair(1)]  # its own fields: nothing built yet
    ladder = feats[0].fields
    narrow_share = {}
    for deg in (3.0, 10.0, 20.0):
        s = _sigma_px(feats, deg)
        frozen, field = _frozen_cost(feats, TRUTH.tau, s, FIELD)
        narrow_share[deg] = float(np.mean(~ladder.reads_pooled(frozen[0].sigma_px)))
        if narrow_share[deg] == 1.0:
            assert field.cost == _frozen_cost(feats, TRUTH.tau, s, EXACT)[1].cost
    assert narrow_share[3.0] == 1.0 and 0.0 < narrow_share[10.0] < 1.0 and narrow_share[20.0] == 0.0
    assert ladder.rows[ladder.factor == 1].sum() == 0  # the memory a full-resolution band would take
    assert ladder.rows[ladder.factor > 1].sum() > 0
