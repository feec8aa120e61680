"""calib.drift: the three answers and the promises behind them, and a search from a drifted and from the true pose."""

import dataclasses

import numpy as np
import pytest

from calib.drift import (
    DriftOptions,
    DriftStatus,
    Group,
    check_drift,
    farthest_change,
    hotelling_t2,
    judge,
    quantiles,
)
from calib.geometry import Transform
from calib.gmm import Evaluator, GmmOptions
from calib.pipeline import CalibParams
from tests.calib.synthetic import TRUTH, make_pair

PARAMS = dataclasses.replace(CalibParams(), gmm=dataclasses.replace(GmmOptions(), evaluator=Evaluator.FIELD),
                             min_boundary_points=0)
OPTS = DriftOptions()
# sigmas of a good 12-pair set (deg x3, cm x3; docs/check.md)
GOOD = np.array([0.04, 0.05, 0.015, 0.3, 0.3, 0.45])


def _status(change, sigma, n_places=12, opts=OPTS):
    return judge(np.asarray(change, float), np.diag(np.asarray(sigma, float) ** 2), n_places, opts)


def test_the_three_answers():
    assert _status(np.zeros(6), GOOD).status is DriftStatus.OK
    moved = _status([0, 0.5, 0, 0, 0, 0], GOOD)
    assert moved.status is DriftStatus.DRIFTED and moved.axes == ("pitch",) and "rotation moved 0.5" in moved.reasons[0]
    # beyond the threshold but within the noise: neither evidence of drift nor known to be fine
    noisy = _status([0, 0, 0, 0, 0, 2.5], [0.01] * 3 + [1.5] * 3)
    assert noisy.status is DriftStatus.UNKNOWN and "z" in noisy.axes
    assert noisy.reasons[0].startswith("translation changed 2.5 cm")
    # a weak axis that could hide a change of the threshold's size: unknown, naming it
    weak = _status(np.zeros(6), [0.04, 0.2, 0.015, 0.3, 0.3, 0.45])
    assert weak.status is DriftStatus.UNKNOWN and weak.axes == ("pitch",)
    assert _status(np.zeros(6), [0.04, 0.2, 0.015, 0.3, 0.3, 0.45],
                   opts=DriftOptions(threshold_rot_deg=0.6)).status is DriftStatus.OK


def test_a_diagonal_drift_counts_by_its_length():
    diagonal = np.array([0, 0, 0, 1.73, -1.73, 1.73])  # 3 cm, no axis over the 2 cm threshold
    result = _status(diagonal, GOOD)
    assert result.status is DriftStatus.DRIFTED and result.axes == ("x", "y", "z")
    assert "translation moved 3" in result.reasons[0]
    assert _status(diagonal * 0.5, GOOD).status is not DriftStatus.DRIFTED  # 1.5 cm: under it


def test_an_axis_the_pairs_do_not_pin_is_unknown_never_drifted():
    """A sparse street whose z sigma is 12 cm, checked at its truth, found z 28 cm away: along z the search's
    minimum says nothing of a drift, so the answer is unknown (z), with what would pin it; a drift along the axes
    the pairs do pin is still found."""
    sigma = np.array([0.04, 0.05, 0.015, 0.6, 0.3, 12.0])
    correlation = np.eye(6)
    correlation[3, 5] = correlation[5, 3] = 0.95  # x and z trade off, as on such a street
    covariance = correlation * np.outer(sigma, sigma)
    change = np.array([0.0, 0.0, 0.0, 0.3, 0.1, 28.0])
    q = quantiles(12, OPTS)
    assert hotelling_t2(change[3:], covariance[3:, 3:]) > q.t2_limit  # judged on all three axes: "drifted"
    result = judge(change, covariance, 12, OPTS)
    assert result.status is DriftStatus.UNKNOWN and result.axes == ("z",)
    assert any(r.startswith("z: the pairs do not pin it (z sigma 12 cm") and "2-10 m" in r for r in result.reasons)
    moved = judge(change + np.array([0, 0, 0, 0, 4.0, 0]), covariance, 12, OPTS)
    assert moved.status is DriftStatus.DRIFTED and moved.axes == ("y",)
    assert "(x +0.3, y +4.1; threshold 2)" in moved.reasons[0]


def test_too_few_places_is_unknown_whatever_the_change():
    for change in (np.zeros(6), np.array([0, 0, 2.0, 0, 0, 10.0])):
        result = _status(change, GOOD / 10, n_places=3)
        assert result.status is DriftStatus.UNKNOWN and result.axes == ("roll", "pitch", "yaw", "x", "y", "z")
        assert "3 places" in result.reasons[0] and result.groups == ()
    assert _status(np.zeros(6), GOOD / 10, n_places=4).status is DriftStatus.OK


def test_farthest_change_is_the_bound_over_all_directions():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(200_000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    for _ in range(5):
        a = rng.normal(size=(3, 3))
        cov = a @ a.T + 0.01 * np.eye(3)
        change = rng.normal(size=3) * rng.uniform(0, 3)
        k = rng.uniform(0.5, 3)
        brute = np.max(u @ change + k * np.sqrt(np.einsum("ij,jk,ik->i", u, cov, u)))
        far = farthest_change(change, cov, k)
        assert np.linalg.norm(far) == pytest.approx(brute, rel=1e-3)
        assert (far - change) @ np.linalg.solve(cov, far - change) == pytest.approx(k**2, rel=1e-6)
    assert np.linalg.norm(farthest_change(np.zeros(3), np.diag([1.0, 4.0, 0.25]), 2.0)) == pytest.approx(4.0)


def _at_most(share, n):
    """``share`` plus three standard deviations of a rate measured over ``n`` Monte Carlo draws."""
    return share + 3 * np.sqrt(share * (1 - share) / n)


def _draws(rng, covariance, n_places, n):
    """Checks as the pairs make them: a Gaussian change and a covariance estimated with n_places - 1 degrees of
    freedom (a Wishart draw around the true one)."""
    dof = n_places - 1
    root = np.linalg.cholesky(covariance)
    for _ in range(n):
        noise = rng.normal(size=(dof, 6)) @ root.T
        yield rng.normal(size=6) @ root.T, noise.T @ noise / dof


@pytest.mark.parametrize("group", list(Group))
def test_a_drift_of_the_threshold_reads_ok_at_most_one_time_in_twenty(group):
    """The ok promise, at its worst case (a change of exactly the threshold), along a weak and a strong axis."""
    rng = np.random.default_rng(7)
    sigma = np.array([0.04, 0.09, 0.015, 0.3, 0.3, 0.6])
    cov = np.diag(sigma**2)
    n, oks = 2000, 0
    for i, (noise, estimate) in enumerate(_draws(rng, cov, 12, n)):
        true = np.zeros(6)
        axis = group.axes.start + (1 if i % 2 else 2)  # pitch / yaw, y / z
        true[axis] = OPTS.threshold(group) * (1 if i % 4 < 2 else -1)
        oks += judge(true + noise, estimate, 12, OPTS).status is DriftStatus.OK
    assert oks / n <= _at_most(1 - OPTS.ok_confidence, n)


def test_no_drift_reads_drifted_at_most_one_time_in_twenty():
    """The false-alarm promise with thresholds the pairs just resolve (3 sigma; a change along an axis they do not
    pin is not judged), and the T² quantile itself: with no change, each group's T² passes its limit in its
    share of the 5 % (Bonferroni: half each), not far below it either."""
    rng = np.random.default_rng(11)
    sigma = np.array([0.1, 0.1, 0.1, 1.0, 1.0, 1.0])
    opts = DriftOptions(threshold_rot_deg=0.3, threshold_trans_cm=3.0)
    n = 2000
    draws = list(_draws(rng, np.diag(sigma**2), 8, n))
    alarms = sum(judge(c, est, 8, opts).status is DriftStatus.DRIFTED for c, est in draws)
    assert alarms / n <= _at_most(1 - opts.drift_confidence, n)
    limit = quantiles(8, opts).t2_limit
    share = (1 - opts.drift_confidence) / 2
    beyond = sum(hotelling_t2(c[:3], est[:3, :3]) > limit for c, est in draws) / n
    assert 0.5 * share <= beyond <= _at_most(share, n)


def test_quantiles_widen_with_fewer_places():
    few, many = quantiles(5, OPTS), quantiles(40, OPTS)
    assert few is not None and many is not None and quantiles(3, OPTS) is None
    assert few.t > many.t > 1.645 and few.t2_limit > many.t2_limit > 9.35  # chi2(3) at 97.5 %


@pytest.fixture(scope="module")
def pairs():
    return [make_pair(seed) for seed in range(1, 6)]


def test_check_finds_injected_drift_and_passes_the_truth(pairs):
    opts = DriftOptions(threshold_rot_deg=0.3, threshold_trans_cm=3.0)
    at_truth = check_drift(pairs, TRUTH, PARAMS, opts)
    assert at_truth.status is DriftStatus.OK, at_truth.reasons
    assert at_truth.places == 5
    assert np.all(np.abs(at_truth.change) < [0.05] * 3 + [0.5] * 3)
    moved = Transform.from_rpy_xyz(TRUTH.rpy_deg + [0.0, 1.0, 0.0], TRUTH.translation_m + [0.0, 0.0, 0.05])
    drifted = check_drift(pairs, moved, PARAMS, opts)
    assert drifted.status is DriftStatus.DRIFTED and "z" in drifted.axes
    # the search lands back near the truth: the change is the injected error, reversed
    assert np.linalg.norm(drifted.found.translation_m - TRUTH.translation_m) < 0.01
    few = check_drift(pairs[:3], moved, PARAMS, opts)
    assert few.status is DriftStatus.UNKNOWN and "3 places" in few.reasons[0]
