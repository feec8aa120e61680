"""calib.assess_photo: the NID solution's restarts, per-axis sigma and verdict (docs/trust.md)."""

from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np
import pytest

from calib.assess import Status, TrustOptions
from calib.assess_photo import _cluster_hists, _gradient, _hessian, _offsets, assess_photometric
from calib.errors import CalibError
from calib.geometry import Transform
from calib.methods import Method, calibrate_method
from calib.photometric import (
    PhotoCost,
    PhotoParams,
    level_pairs,
    optimise_photometric,
    project_level,
    sample,
    soft_joint_histogram,
)
from calib.uncertainty import TO_DISPLAY, tau_at, xi_of
from tests.calib.test_photometric import TRUTH, ideal_pair

SMALL = PhotoParams(cost=PhotoCost.NID, blur_deg=(0.5, 0.0), step_rot_deg=(0.6, 0.2), step_trans_m=(0.03, 0.01),
                    max_evals=300, restarts=1, rotation_only_levels=0)


def test_stencil_derivatives_are_exact_on_a_quadratic():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 6))
    hess, grad = a @ a.T + np.eye(6), rng.normal(size=6)
    h = np.array([1e-3] * 3 + [1e-2] * 3)
    values = np.array([grad @ x + 0.5 * x @ hess @ x for x in _offsets(h)])
    assert _gradient(values[:13], h) == pytest.approx(grad, rel=1e-9, abs=1e-9)
    assert _hessian(values, h) == pytest.approx(hess, rel=1e-6, abs=1e-6)


def test_cluster_histograms_add_up_to_the_pair_histogram():
    """The soft histogram is additive over samples: 'without a cluster' is a subtraction."""
    pair = ideal_pair(5)
    lp = level_pairs([pair], TRUTH.tau, SMALL, 1, [(pair.points_lidar, pair.reflectivity)])[0]
    labels = np.arange(len(lp.points_lidar)) % 7
    per = _cluster_hists(lp, TRUTH.tau, labels, 7, SMALL.n_bins)
    uv, inside = project_level(lp, TRUTH.tau)
    whole = soft_joint_histogram(lp.reflectivity[inside], sample(lp.grey, lp.camera, uv[inside]), SMALL.n_bins)
    assert per.sum(axis=0) == pytest.approx(whole, abs=1e-9)


def test_an_ideal_pair_is_assessed():
    pair = ideal_pair(2)
    start = tau_at(TRUTH.tau, np.array([np.radians(0.4), np.radians(-0.3), np.radians(0.2), 0.02, -0.01, 0.01]))
    solved = optimise_photometric([pair], start, SMALL)
    trust = replace(TrustOptions(), restarts=2)
    a = assess_photometric([pair], solved, SMALL, trust, starts=(start,))
    u = a.uncertainty
    assert u.is_minimum and u.kappa > 0 and u.jackknife is not None and u.restart_spread is not None
    assert len(a.restarts) == 2 and a.verdict.status is not Status.FAILED
    error = np.abs(xi_of(TRUTH.tau, a.tau) * TO_DISPLAY)
    assert np.all(error <= [0.05] * 3 + [0.5] * 3)  # deg, cm
    assert np.all(np.isfinite(u.sigma)) and np.all(u.sigma > 0)
    assert np.all(u.sigma >= u.restart_spread)  # the restarts' landing spread is part of the sigma


def test_only_nid_is_assessed():
    pair = ideal_pair(3)
    with pytest.raises(CalibError, match="defined for NID"):
        assess_photometric([pair], optimise_photometric([pair], TRUTH.tau, replace(SMALL, cost=PhotoCost.MI)),
                           replace(SMALL, cost=PhotoCost.MI), TrustOptions(restarts=0))


def test_nid_assessed_method_has_a_verdict_and_the_baseline_none():
    pair = ideal_pair(4)
    start = Transform.from_tau(tau_at(TRUTH.tau, np.array([np.radians(0.2), 0, 0, 0.01, 0, 0])))
    trust = TrustOptions(restarts=1)
    assert calibrate_method(Method.NID, None, [pair], start, trust=trust).assessment is None
    result = calibrate_method(Method.NID_ASSESSED, None, [pair], start, trust=trust)
    assert result.assessment is not None and result.assessment.verdict.status is not Status.NOT_ASSESSED


def test_restarts_in_a_pool_give_the_same_assessment():
    pair = ideal_pair(2)
    start = tau_at(TRUTH.tau, np.array([np.radians(0.3), 0.0, np.radians(-0.2), 0.01, 0.0, -0.01]))
    solved = optimise_photometric([pair], start, SMALL)
    trust = replace(TrustOptions(), restarts=3)
    alone = assess_photometric([pair], solved, SMALL, trust, starts=(start,))
    with ThreadPoolExecutor(1) as pool:
        pooled = assess_photometric([pair], solved, SMALL, trust, starts=(start,), executor=pool)
    assert np.array_equal(alone.tau, pooled.tau)
    assert [r.offset.tolist() for r in alone.restarts] == [r.offset.tolist() for r in pooled.restarts]
    assert alone.verdict == pooled.verdict
