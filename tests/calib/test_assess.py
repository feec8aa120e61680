"""calib.prior and calib.assess: the MAP term, the Newton-step jackknife, the verdict."""

import dataclasses

import numpy as np
import pytest

import calib.assess as assess_module
from calib.assess import (
    AXES,
    Evidence,
    Restart,
    Status,
    TrustOptions,
    Uncertainty,
    _jackknife,
    _run_restarts,
    assess,
    trust_region_step,
    verdict_of,
    with_cross_check,
    with_intrinsics,
)
from calib.errors import CalibError
from calib.geometry import Transform, rpy_deg_to_matrix
from calib.gmm import Evaluator, GmmOptions
from calib.optimize import OptimOptions, optimise
from calib.prior import Prior
from calib.uncertainty import TO_DISPLAY, xi_of
from tests.calib.synthetic import TRUTH, make_pair

FIELD = dataclasses.replace(GmmOptions(), evaluator=Evaluator.FIELD)


@pytest.fixture(scope="module")
def pairs():
    return [make_pair(1), make_pair(2)]


def test_prior_gradient_matches_finite_differences():
    prior = Prior(np.array([0.1, -0.2, 0.3]), np.array([0.01, 0.02, 0.03]), rpy_deg_to_matrix(np.array([3, -5, 40])),
                  np.radians([1.0, 2.0, 3.0]))
    tau = Transform.from_rpy_xyz(np.array([4, -3, 42]), np.array([0.12, -0.25, 0.2])).tau
    nll, grad = prior.nll_and_gradient(tau)
    assert nll > 0
    for k in range(6):
        e = np.zeros(6)
        e[k] = 1e-6
        numeric = (prior.nll_and_gradient(tau + e)[0] - prior.nll_and_gradient(tau - e)[0]) / 2e-6
        assert grad[k] == pytest.approx(numeric, rel=1e-4, abs=1e-6)
    assert prior.nll_and_gradient(Transform(prior.rotation, prior.xyz_m).tau)[0] == pytest.approx(0.0, abs=1e-20)


@pytest.mark.parametrize("bad", [dict(xyz_m=np.zeros(3)), dict(sigma_xyz_m=np.full(3, -1.0), xyz_m=np.zeros(3)),
                                 dict(rotation=np.eye(3))])
def test_incomplete_or_negative_prior_is_refused(bad):
    with pytest.raises(CalibError):
        Prior(**bad)


def test_a_tight_translation_prior_holds_the_lever_arm_and_fix_keeps_it_exactly(pairs):
    lever = TRUTH.translation_m + [0.03, -0.03, 0.02]  # a drawing 4.7 cm off
    start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [1.0, -1.0, 1.0], lever)
    free = optimise(pairs, start.tau, OptimOptions(), FIELD)
    tight = optimise(pairs, start.tau, OptimOptions(), FIELD, prior=Prior(lever, np.full(3, 1e-4)))
    fixed = optimise(pairs, start.tau, OptimOptions(), FIELD, prior=Prior(lever, fix_translation=True))
    assert np.linalg.norm(free.tau[3:] - TRUTH.translation_m) < 0.01  # the images alone find the truth
    assert np.linalg.norm(tight.tau[3:] - lever) < 0.002  # a 0.1 mm prior wins over them
    assert np.array_equal(fixed.tau[3:], start.translation_m)


def test_newton_jackknife_is_exact_for_quadratic_clusters():
    rng = np.random.default_rng(1)
    n, groups = 30, rng.integers(0, 6, 30)
    a = [(lambda m: m @ m.T + np.eye(6))(rng.normal(size=(6, 6))) for _ in range(n)]
    b = [rng.normal(size=6) for _ in range(n)]
    theta = np.linalg.solve(sum(a), sum(b))
    grads = np.array([ai @ theta - bi for ai, bi in zip(a, b, strict=True)])
    cov, unheld = _jackknife(grads, np.array(a), np.zeros((6, 6)), groups, 6, np.ones(6, bool), np.ones(6), 1e9)
    assert unheld == ()  # every left-out solve is a Newton step well inside the (huge) bound
    loo = np.array([np.linalg.solve(sum(a[i] for i in range(n) if groups[i] != g),
                                    sum(b[i] for i in range(n) if groups[i] != g)) for g in range(6)])
    centred = loo - loo.mean(axis=0)
    assert np.allclose(cov, 5 / 6 * centred.T @ centred, rtol=1e-8, atol=1e-14)


def _model(h, g, s):
    return g @ s + 0.5 * s @ h @ s


@pytest.mark.parametrize("kind", ["newton inside", "positive definite, long", "indefinite", "hard case"])
def test_trust_region_step_is_the_lowest_point_of_the_model_in_the_scaled_ball(kind):
    rng = np.random.default_rng(3)
    q, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    w = {"newton inside": [1, 2, 3, 4, 5, 6], "positive definite, long": [1e-4, 2, 3, 4, 5, 6],
         "indefinite": [-2, -0.1, 1, 2, 3, 4], "hard case": [-1, 0.5, 1, 2, 3, 4]}[kind]
    h = q @ np.diag(w) @ q.T
    g = q @ np.array([0.0 if kind == "hard case" else 0.3, 0.2, -0.1, 0.4, 0.1, -0.2])
    scale, radius = np.array([1.0, 1.0, 1.0, 0.1, 0.1, 0.1]), 0.5
    step = trust_region_step(h, g, scale, radius)
    newton = -np.linalg.solve(h, g)
    if kind == "newton inside":
        assert np.linalg.norm(scale * newton) < radius and np.allclose(step, newton)
        return
    assert np.linalg.norm(scale * step) == pytest.approx(radius, rel=1e-6)
    ball = rng.normal(size=(20000, 6))
    ball = ball / np.linalg.norm(ball, axis=1, keepdims=True) * radius * rng.uniform(0, 1, (20000, 1)) ** (1 / 6)
    others = [_model(h, g, y / scale) for y in ball]
    assert _model(h, g, step) <= min(others) + 1e-9


def test_a_group_that_alone_sees_a_direction_moves_the_jackknife_by_the_kernel_width_not_without_bound():
    """One frame in groups of image cells: if only one group pins an axis, leaving it out leaves that axis
    flat (here slightly curved down). The left-out solve is then bounded by the quadratic model's reach, so
    the jackknife sigma is a few radii, where an unbounded Newton step gave an arbitrarily large one."""
    rng = np.random.default_rng(4)
    n, n_groups, radius = 40, 8, np.radians(1.76)
    groups = np.arange(n) % n_groups
    hessians = np.array([np.diag([1.0, 1.0, 1.0, 1.0, 1.0, 0.0]) for _ in range(n)])
    hessians[groups == 0, 5, 5] = 8.0 / 5  # only group 0's 5 clusters see z, and a little negative elsewhere
    hessians[groups != 0, 5, 5] = -1e-3
    grads = rng.normal(scale=0.01, size=(n, 6))
    grads -= grads.mean(axis=0)  # at the solution: the gradient sums to zero
    cov, unheld = _jackknife(grads, hessians, np.zeros((6, 6)), groups, n_groups, np.ones(6, bool), np.ones(6),
                             radius)
    unbounded, _ = _jackknife(grads, hessians, np.zeros((6, 6)), groups, n_groups, np.ones(6, bool), np.ones(6), 1e9)
    assert cov is not None and unbounded is not None
    assert unheld == (0,)  # without group 0 nothing holds z: its left-out solve ran to the kernel's width
    sigma = np.sqrt(np.diag(cov))
    assert 0.5 * radius < sigma[5] <= np.sqrt(n_groups - 1) * radius  # z: as unknown as the kernel lets it be
    assert np.sqrt(unbounded[5, 5]) > 10 * radius
    assert np.all(sigma[:5] < 0.1 * radius)  # the other axes: their own small spread


def _unc(sigma, is_min=True):
    sigma = np.asarray(sigma, dtype=float)
    return Uncertainty(np.diag((sigma / TO_DISPLAY) ** 2), sigma, sigma, None, 0, "", is_min, 1.0, 0.5)


def test_verdict_trusted_weak_and_failed():
    trust = TrustOptions()
    assert verdict_of(_unc([0.05] * 3 + [0.5] * 3), [], trust).status is Status.TRUSTED
    weak = verdict_of(_unc([0.05, 0.05, 0.05, 0.5, 0.5, 3.0]), [], trust)
    assert weak.status is Status.WEAK and weak.weak_axes == ("z",) and "z" in weak.reasons[0]
    tie = Restart(np.array([0.0, 0.5, 0.0, 0.0, 0.0, 0.0]), delta_nll=1.0)  # another pose, equally good
    amb = verdict_of(_unc([0.05] * 3 + [0.5] * 3), [tie], trust)
    assert amb.status is Status.WEAK and amb.weak_axes == ("pitch",)
    far_but_worse = Restart(np.array([3.0, 0, 0, 0, 0, 0]), delta_nll=50.0)  # a worse minimum: no ambiguity
    back = Restart(np.array([0.01, 0, 0, 0.1, 0, 0]), delta_nll=0.1)
    one_stuck = [far_but_worse, back, back, back]
    assert verdict_of(_unc([0.05] * 3 + [0.5] * 3), one_stuck, trust).status is Status.TRUSTED
    # Most restarts at other, worse minima: the solution is one of several nearby, so nothing is claimed.
    rugged = verdict_of(_unc([0.05] * 3 + [0.5] * 3), [far_but_worse, far_but_worse, back, far_but_worse], trust)
    assert rugged.status is Status.FAILED and "1 of 4 restarts came back" in rugged.reasons[-1]
    runner_up = Restart(np.array([30.0, 0, 0, 0, 0, 0]), delta_nll=80.0, origin="search runner-up")
    assert verdict_of(_unc([0.05] * 3 + [0.5] * 3), [back, runner_up], trust).status is Status.TRUSTED
    far_tie = Restart(np.array([3.0, 0, 0, 0, 0, 0]), delta_nll=0.5)
    assert verdict_of(_unc([0.05] * 3 + [0.5] * 3), [far_tie], trust).status is Status.FAILED
    assert verdict_of(_unc([0.05] * 6, is_min=False), [], trust).status is Status.FAILED
    assert verdict_of(_unc([2.0] * 3 + [30.0] * 3), [], trust).status is Status.FAILED
    # Every axis over its tolerance, two of them far (measured: ours_1+2 with a 1 cm lever-arm prior, 8.3 deg
    # off, roll and pitch sigma 1.6 and 0.65 deg, yaw 0.16 deg, the prior's 1 cm): nothing is vouched for.
    none_known = verdict_of(_unc([1.56, 0.65, 0.16, 1.0, 1.0, 1.0]), [], trust)
    assert none_known.status is Status.FAILED and none_known.weak_axes == ("roll", "pitch", "yaw", "x", "y", "z")
    assert "no axis is known" in none_known.reasons[-1]
    five = verdict_of(_unc([1.56, 0.65, 0.05, 1.0, 1.0, 1.0]), [], trust)  # yaw known: the rest is named
    assert five.status is Status.WEAK and "yaw" not in five.weak_axes
    loose = TrustOptions(tolerance_trans_cm=10.0)  # the rig file's tolerance decides
    assert verdict_of(_unc([0.05, 0.05, 0.05, 0.5, 0.5, 3.0]), [], loose).status is Status.TRUSTED


def test_a_principal_point_known_to_a_pixel_is_a_tilt_one_camera_cannot_rule_out():
    """K's principal point shifts the image as a tilt of the LiDAR would: sigma / f rad about the camera's x (rows)
    and y (columns) axes, none about the optical axis (docs/trust.md)."""
    # A forward camera under a ROS LiDAR: camera x = -LiDAR y, camera y = -LiDAR z, optical axis = LiDAR x.
    forward = Transform(np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]), np.zeros(3)).tau
    fx, fy, sigma_px = 1000.0, 500.0, 1.0
    trust = TrustOptions(intrinsics_sigma_rad=(sigma_px / fy, sigma_px / fx))
    data = _unc([0.03] * 3 + [0.5] * 3)
    added = with_intrinsics(data, forward, trust)
    assert added.intrinsics is not None
    # about LiDAR x (the optical axis) nothing; about LiDAR y (camera x) the rows' 1/fy; about z the columns' 1/fx
    assert added.intrinsics[:3] == pytest.approx([0.0, np.degrees(1 / fy), np.degrees(1 / fx)], abs=1e-9)
    assert added.sigma[:3] == pytest.approx(np.hypot(0.03, added.intrinsics[:3]))
    assert verdict_of(data, [], trust).status is Status.TRUSTED
    tilted = verdict_of(added, [], trust)
    assert tilted.status is Status.WEAK and tilted.weak_axes == ("pitch",)  # 2.5 * 0.118 deg > 0.2; yaw 0.16 < 0.2
    assert with_intrinsics(data, forward, TrustOptions()) is data  # K taken as exact


def test_a_second_methods_disagreement_unvouches_its_axes_and_fails_nothing():
    """The GMM's edges landing d from NID's answer: an axis where 2.5 d / sqrt(2) passes the tolerance is not
    vouched for, and named; the sigma stays the method's own, and however far the edges land, the result is not
    failed for it (the edges may be the biased ones)."""
    data = _unc([0.03] * 3 + [0.5] * 3)
    near = np.array([0.0, np.radians(0.3), 0.0, 0.0, 0.0, 0.04])  # 0.3 deg about the LiDAR's y, 4 cm along z
    trust = TrustOptions(cross_check_pose=tuple(near))
    added = with_cross_check(data, trust)
    assert added.cross_check == pytest.approx([0.0, 0.3 / np.sqrt(2), 0.0, 0.0, 0.0, 4.0 / np.sqrt(2)])
    assert np.array_equal(added.sigma, data.sigma)
    assert verdict_of(data, [], trust).status is Status.TRUSTED
    disputed = verdict_of(added, [], trust)
    assert disputed.status is Status.WEAK and disputed.weak_axes == ("pitch", "z")
    assert any("the image's edges refined from this answer move pitch 0.3°, z 4 cm" in r for r in disputed.reasons)
    far = np.array([np.radians(1.5), np.radians(1.5), np.radians(1.5), 0.05, 0.05, 0.05])
    everywhere = verdict_of(with_cross_check(data, TrustOptions(cross_check_pose=tuple(far))), [], trust)
    assert everywhere.status is Status.WEAK and everywhere.weak_axes == AXES
    small = np.array([0.0, np.radians(0.05), 0.0, 0.0, 0.0, 0.005])  # within tolerance: nothing to say
    assert verdict_of(with_cross_check(data, TrustOptions(cross_check_pose=tuple(small))), [], trust).status \
        is Status.TRUSTED
    assert with_cross_check(data, TrustOptions()) is data  # no second method: nothing added


def test_a_solution_far_from_every_start_fails_however_well_determined_it_looks():
    """Sigmas and restarts are local: a solve that ran 45 deg to another alignment of the edges can have both
    looking fine (measured: ours_1+2 with a 1 cm lever-arm prior, yaw 45.5 deg off, yaw sigma 0.05 deg)."""
    trust = TrustOptions()
    sharp = _unc([0.05] * 3 + [0.5] * 3)
    assert verdict_of(sharp, [], trust, moved_deg=19.0).status is Status.TRUSTED
    far = verdict_of(sharp, [], trust, moved_deg=45.5)
    assert far.status is Status.FAILED and far.weak_axes == ("roll", "pitch", "yaw", "x", "y", "z")
    assert "45.5 deg from its start" in far.reasons[0]
    assert verdict_of(sharp, [], TrustOptions(max_move_deg=60.0), moved_deg=45.5).status is Status.TRUSTED


def test_a_translation_metres_from_its_start_fails_and_names_the_unit():
    """A lever arm typed in cm where metres are meant (9.34, 6.24, -15.68 as a prior) pulls the translation 19 m
    from its start, where sigmas and restarts can look fine: failed, saying how far and in which unit."""
    trust = TrustOptions()
    sharp = _unc([0.05] * 3 + [0.5] * 3)
    assert verdict_of(sharp, [], trust, moved_m=0.4).status is Status.TRUSTED
    far = verdict_of(sharp, [], trust, moved_deg=0.5, moved_m=19.07)
    assert far.status is Status.FAILED and far.weak_axes == ("roll", "pitch", "yaw", "x", "y", "z")
    assert "19.07 m from its start" in far.reasons[0] and "in metres" in far.reasons[0]


def test_assessment_measures_the_rotation_from_the_nearest_start(pairs):
    start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [1.5, -1.0, 1.0], TRUTH.translation_m + [0.04, -0.03, 0.03])
    opts = OptimOptions()
    result = optimise(pairs, start.tau, opts, FIELD)
    trust = TrustOptions(restarts=0)
    near = assess(pairs, result, opts, FIELD, prior=None, trust=trust, starts=(start.tau,))
    moved = np.degrees(np.linalg.norm(xi_of(start.tau, near.tau)[:3]))
    assert near.moved_deg == pytest.approx(moved, rel=1e-6) and 1.0 < near.moved_deg < 3.0
    assert near.verdict.status is Status.TRUSTED
    assert near.moved_m == pytest.approx(float(np.linalg.norm(start.tau[3:] - near.tau[3:])), rel=1e-9)
    elsewhere = Transform.from_rpy_xyz(TRUTH.rpy_deg + [0.0, 0.0, 40.0], TRUTH.translation_m)
    both = assess(pairs, result, opts, FIELD, prior=None, trust=trust, starts=(elsewhere.tau, start.tau))
    assert both.moved_deg == pytest.approx(near.moved_deg)  # the nearest start counts
    only_far = assess(pairs, result, opts, FIELD, prior=None, trust=trust, starts=(elsewhere.tau,))
    assert only_far.moved_deg == pytest.approx(40.0, abs=2.0) and only_far.verdict.status is Status.FAILED
    assert assess(pairs, result, opts, FIELD, prior=None, trust=trust).moved_deg is None


def test_restarts_weigh_the_prior_as_the_solution_did(pairs):
    """The prior's weight kappa is the level cost's scale where a level starts; restarts reuse the solution's
    per level instead of estimating their own, so they minimise the same objective (and skip 13 gradient
    evaluations a level)."""
    opts = dataclasses.replace(OptimOptions(), alternative_schedules=0)
    prior = Prior(TRUTH.translation_m + [0.02, -0.01, 0.0], np.full(3, 0.1))
    start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [1.5, -1.0, 1.0], TRUTH.translation_m + [0.04, -0.03, 0.03])
    result = optimise(pairs, start.tau, opts, FIELD, prior=prior)
    kappas = tuple(t.kappa for t in result.levels)
    assert len(set(kappas)) == len(kappas) and all(k > 0 for k in kappas)  # estimated per level
    again = optimise(pairs, start.tau, opts, FIELD, prior=prior, kappas=kappas)
    assert np.array_equal(again.tau, result.tau) and again.final_cost == result.final_cost
    _, runs = _run_restarts(pairs, result, opts, FIELD, prior, TrustOptions(restarts=2), None)
    for run in runs:
        assert tuple(t.kappa for t in run.levels) == kappas[-2:]
    # A solution from a shorter schedule (the alternative one) lacks a level of the tail: estimated there.
    short = optimise(pairs, result.tau, dataclasses.replace(opts, sigmas_deg=opts.sigmas_deg[-1:]), FIELD, prior=prior)
    _, runs = _run_restarts(pairs, short, opts, FIELD, prior, TrustOptions(restarts=1), None)
    assert runs[0].levels[1].kappa == short.levels[0].kappa and runs[0].levels[0].kappa > 0


def test_assessment_of_a_clean_synthetic_solve_is_trusted_and_covers_the_truth(pairs):
    start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [1.5, -1.0, 1.0], TRUTH.translation_m + [0.04, -0.03, 0.03])
    opts = OptimOptions()
    result = optimise(pairs, start.tau, opts, FIELD)
    a = assess(pairs, result, opts, FIELD, prior=None, trust=TrustOptions(restarts=2))
    err = np.abs(xi_of(TRUTH.tau, a.tau) * TO_DISPLAY)
    assert a.verdict.status is Status.TRUSTED, a.verdict.reasons
    assert np.all(err <= 3 * a.uncertainty.sigma + 1e-9) and np.all(a.uncertainty.sigma > 0)
    assert a.uncertainty.jackknife is not None and a.uncertainty.jackknife_groups == 8  # 2 pairs: cell groups
    assert len(a.restarts) == 2 and a.uncertainty.is_minimum


def test_fixed_translation_reports_no_translation_uncertainty(pairs):
    opts = OptimOptions()
    prior = Prior(TRUTH.translation_m, fix_translation=True)
    start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [1.0, 1.0, -1.0], TRUTH.translation_m)
    result = optimise(pairs, start.tau, opts, FIELD, prior=prior)
    a = assess(pairs, result, opts, FIELD, prior=prior, trust=TrustOptions(restarts=1))
    assert np.all(a.uncertainty.sigma[3:] == 0) and np.all(a.uncertainty.sigma[:3] > 0)
    assert np.array_equal(a.tau[3:], TRUTH.translation_m)
    assert a.verdict.fixed_axes == ("x", "y", "z") and not set(a.verdict.weak_axes) & {"x", "y", "z"}
    assert "held at the values given, not checked" in a.verdict.reasons[-1]


def test_a_held_lever_arm_the_data_disagree_with_vouches_for_nothing(pairs):
    """The lever arm typed in metres where cm were meant (1/100 of the true one), held: the same levels with the
    translation free fit far better, and the verdict says the values given disagree with the data."""
    opts = OptimOptions()
    prior = Prior(TRUTH.translation_m / 100.0, fix_translation=True)
    start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [1.0, 1.0, -1.0], TRUTH.translation_m / 100.0)
    result = optimise(pairs, start.tau, opts, FIELD, prior=prior)
    v = assess(pairs, result, opts, FIELD, prior=prior, trust=TrustOptions(restarts=1)).verdict
    assert v.status is not Status.TRUSTED and v.weak_axes == AXES
    assert any("the values given disagree with the data" in r for r in v.reasons) or v.status is Status.FAILED


def test_a_result_beyond_3_sigma_of_the_lever_arm_given_is_not_trusted():
    """A sharp result 18 sigma from a lever arm given (free translation): the translation is named, with the
    distance in the prior's sigmas."""
    sharp = np.full(6, 0.01)
    unc = Uncertainty(np.eye(6) * 1e-4, sharp, sharp, None, 0, "", True, 1.0, 0.9)
    far = verdict_of(unc, [], TrustOptions(), evidence=Evidence(prior_z=(0.5, 18.0)))
    assert far.status is Status.WEAK and far.weak_axes == ("x", "y", "z")
    assert "the result lies 18 sigma from the lever arm given" in far.reasons[-1]
    assert verdict_of(unc, [], TrustOptions(), evidence=Evidence(prior_z=(0.5, 2.0))).status is Status.TRUSTED


def test_independent_solves_in_a_process_pool_end_exactly_where_serial_ones_do(pairs):
    """calib.pipeline.calibrate with the application's pool: the alternative schedule, the search's
    runner-up and the second restart solved in workers (their fields rebuilt there: pickled without their
    bands) give the serial run's numbers, bit for bit."""
    import multiprocessing
    import pickle
    from concurrent.futures import ProcessPoolExecutor

    from calib.pipeline import CalibParams, calibrate, with_sigmas
    from calib.search import SearchOptions

    trust = TrustOptions(restarts=2)  # one here, one in a worker
    search = SearchOptions(yaw_range_deg=30.0, tilt_deg=0.0)  # a few mounts: a runner-up, quickly
    params = with_sigmas(CalibParams(), (4.0, 2.0))  # two levels: an alternative schedule still, in half the time
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        serial = calibrate(pairs, None, params, trust=trust, search=search)
        assert all(p.fields is None or len(p.fields.flat) > 0 for p in pairs)  # the run built bands ...
        shipped = pickle.loads(pickle.dumps(pairs))
        assert all(p.fields is None or len(p.fields.flat) == 0 for p in shipped)  # ... not shipped
        pooled = calibrate(pairs, None, params, trust=trust, search=search, executor=pool)
        assert serial.assessment is not None and pooled.assessment is not None
        assert np.array_equal(serial.T_camera_lidar.tau, pooled.T_camera_lidar.tau)
        assert serial.optim.final_cost == pooled.optim.final_cost
        for a, b in zip(serial.assessment.restarts, pooled.assessment.restarts, strict=True):
            assert np.array_equal(a.offset, b.offset) and a.delta_nll == b.delta_nll and a.origin == b.origin
        assert serial.assessment.verdict == pooled.assessment.verdict
        assert "search runner-up" in {r.origin for r in pooled.assessment.restarts}


def test_the_guess_lever_arm_is_a_weak_prior_of_the_solve_and_not_of_the_reported_sigma(pairs):
    from calib.pipeline import CalibParams, calibrate, solve_prior

    guess = Transform.from_rpy_xyz(TRUTH.rpy_deg + [1.0, -1.5, 1.0], TRUTH.translation_m + [0.04, -0.03, 0.03])
    weak = solve_prior(None, guess, CalibParams().guess_sigma_m)
    assert weak is not None and np.array_equal(weak.xyz_m, guess.translation_m)
    np.testing.assert_array_equal(weak.sigma_xyz_m, [0.1, 0.1, 0.1])
    declared = Prior(TRUTH.translation_m, np.full(3, 0.01))
    assert solve_prior(declared, guess, 0.1) is declared  # the drawing's lever arm wins
    rotation_only = Prior(rotation=TRUTH.rotation, sigma_rot_rad=np.full(3, 0.1))
    merged = solve_prior(rotation_only, guess, 0.1)
    assert merged is not None and merged.sigma_rot_rad is not None and merged.sigma_xyz_m is not None
    assert solve_prior(None, guess, 0.0) is None

    trust = TrustOptions(restarts=1)
    with_guess = calibrate(pairs, guess, CalibParams(), trust=trust)
    without = calibrate(pairs, guess, CalibParams(guess_sigma_m=0.0), trust=trust)
    assert with_guess.guess_sigma_m == 0.1 and without.guess_sigma_m is None
    # Where the images determine the translation (to a few mm here) a 10 cm prior 5.8 cm off moves it < 0.5 mm,
    assert np.linalg.norm(with_guess.T_camera_lidar.translation_m - TRUTH.translation_m) < 0.01
    assert np.linalg.norm(with_guess.T_camera_lidar.translation_m - without.T_camera_lidar.translation_m) < 5e-4
    # and the reported uncertainty is the data's: a prior used by the solve alone does not shrink it.
    result = without.optim
    tight = Prior(result.tau[3:], np.full(3, 1e-4))  # 0.1 mm, against the data's 0.6 mm
    alone = assess(pairs, result, OptimOptions(), GmmOptions(), prior=None, trust=TrustOptions(restarts=0))
    solved_with = assess(pairs, result, OptimOptions(), GmmOptions(), prior=None, trust=TrustOptions(restarts=0),
                         solving=tight)
    declared_tight = assess(pairs, result, OptimOptions(), GmmOptions(), prior=tight, trust=TrustOptions(restarts=0))
    np.testing.assert_array_equal(solved_with.uncertainty.laplace, alone.uncertainty.laplace)
    assert np.all(declared_tight.uncertainty.laplace[3:] < 0.5 * alone.uncertainty.laplace[3:])


def test_a_translation_the_images_cannot_see_stays_at_the_guess_and_is_reported_unknown():
    """Edges 200-800 km away: the lever arm moves none of them. The guess's weak prior holds the translation
    (without it the solve runs off by metres and is not a minimum); the reported sigma is the data's (huge)."""
    from calib.pipeline import CalibParams, calibrate

    far = [make_pair(1, scale=1e5), make_pair(2, scale=1e5)]
    guess = Transform.from_rpy_xyz(TRUTH.rpy_deg + [1.0, -1.0, 1.0], TRUTH.translation_m + [0.04, -0.03, 0.03])
    held = calibrate(far, guess, CalibParams(), trust=TrustOptions(restarts=1))
    loose = calibrate(far, guess, CalibParams(guess_sigma_m=0.0), trust=TrustOptions(restarts=1))
    assert held.assessment is not None and loose.assessment is not None
    assert np.linalg.norm(held.T_camera_lidar.translation_m - guess.translation_m) < 0.01
    assert held.assessment.uncertainty.is_minimum  # of what the solve minimised
    assert np.all(held.assessment.uncertainty.sigma[3:] > 100.0)  # cm: the images say nothing of it
    assert set(held.assessment.verdict.weak_axes) >= {"x", "y", "z"}
    assert np.linalg.norm(loose.T_camera_lidar.translation_m - guess.translation_m) > 1.0
    assert not loose.assessment.uncertainty.is_minimum


def test_restarts_run_one_level_more_when_folds_are_on_every_level(pairs):
    """Fold edges on the last levels make the finest cost rugged within the restarts' offsets: the restarts
    then start one level wider, as the solve itself came down from a wider level."""
    opts = dataclasses.replace(OptimOptions(), alternative_schedules=0)
    result = optimise(pairs, TRUTH.tau, opts, FIELD)
    widths = [[t.sigma_in_deg for t in run.levels]
              for folds in (opts.fold_levels, len(opts.sigmas_deg))
              for run in _run_restarts(pairs, result, dataclasses.replace(opts, fold_levels=folds), FIELD, None,
                                       TrustOptions(restarts=1), None)[1]]
    assert widths == [list(opts.sigmas_deg[-2:]), list(opts.sigmas_deg[-3:])]


def test_a_left_out_solve_that_carries_most_of_the_spread_holds_the_pose_short_of_the_kernel_width():
    radius, scale = 1.0, np.ones(6)
    steps = np.zeros((5, 6))
    steps[:, 5] = [0.02, -0.26, -0.04, 0.16, 0.71]  # the Ford subset's left-out solves, in kernel widths (z)
    assert assess_module.holding_groups(steps, [0, 1, 2, 3, 4], scale, radius) == (4,)
    even = np.zeros((5, 6))
    even[:, 5] = [0.6, -0.6, 0.55, -0.58, 0.62]  # far, but no place carries most of it: noise, not one place
    assert assess_module.holding_groups(even, [0, 1, 2, 3, 4], scale, radius) == ()
    small = steps * 0.5  # the same shares, nowhere near the width: the pose is held
    assert assess_module.holding_groups(small, [0, 1, 2, 3, 4], scale, radius) == ()


def test_pairs_at_one_place_vouch_for_no_axis():
    """A sharp result from pairs of one place: weak, every axis named (the place's biases are common to every pair);
    from two places the usual verdict; a failed one stays failed."""
    from calib.assess import AXES, Status, TrustOptions, Uncertainty, verdict_of

    sharp = np.full(6, 0.01)
    unc = Uncertainty(np.eye(6) * 1e-4, sharp, sharp, None, 0, "", True, 1.0, 0.9)
    trust = TrustOptions()
    one = verdict_of(unc, [], trust, places=1)
    assert one.status is Status.WEAK and one.weak_axes == AXES and "one place" in one.reasons[-1]
    assert verdict_of(unc, [], trust, places=2).status is Status.TRUSTED
    assert verdict_of(unc, [], trust).status is Status.TRUSTED
    lost = Uncertainty(np.eye(6), sharp, sharp, None, 0, "", False, 1.0, 0.9)
    assert verdict_of(lost, [], trust, places=1).status is Status.FAILED
