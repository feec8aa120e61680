"""Statistics of repeated calibrations (calib.evaluate) on hand-made results; expected numbers worked out by hand."""

import math

import numpy as np
import pytest

from calib.evaluate import (
    EvaluationError,
    OutlierRule,
    StartAxes,
    coverage,
    random_starts,
    random_subsets,
    run_stats,
)
from calib.geometry import Transform, rotation_angle_deg
from calib.uncertainty import TO_DISPLAY, tau_at, xi_of

REF_RPY = np.array([1.0, 2.0, 30.0])
REF_XYZ = np.array([0.1, 0.2, 0.3])
REFERENCE = Transform.from_rpy_xyz(REF_RPY, REF_XYZ)


def offset(d_rpy_deg, d_xyz_m, rpy=REF_RPY, xyz=REF_XYZ):
    return Transform.from_rpy_xyz(rpy + np.asarray(d_rpy_deg, float), xyz + np.asarray(d_xyz_m, float))


def hand_made_runs():
    # Roll offsets 0.1, 0.3, 0.2, 2.0, 0.2 deg; x offset 1 cm on run 1; y offset 4 cm on run 4; run 5 failed.
    return [
        offset([0.1, 0, 0], [0, 0, 0]),
        offset([0.3, 0, 0], [0.01, 0, 0]),
        offset([0.2, 0, 0], [0, 0, 0]),
        offset([2.0, 0, 0], [0, 0, 0]),
        offset([0.2, 0, 0], [0, 0.04, 0]),
        None,
    ]


def test_paper_rule_flags_runs_far_from_the_per_parameter_median():
    stats = run_stats(REFERENCE, hand_made_runs(), OutlierRule.PER_PARAMETER)
    # Median roll offset of the 5 finished runs: sorted 0.1 0.2 0.2 0.3 2.0 -> 0.2; x and y medians: 0.
    assert stats.median.roll_deg == pytest.approx(REF_RPY[0] + 0.2, abs=1e-9)
    assert stats.median.x_m == pytest.approx(REF_XYZ[0], abs=1e-12)
    # Run 3 is 1.8 deg off in roll, run 4 is 4 cm off in y; run 5 failed: 3 of 6 converged.
    assert stats.converged.tolist() == [True, True, True, False, False, False]
    assert (stats.runs, stats.finished, stats.converged_count) == (6, 5, 3)
    assert stats.converged_percent == pytest.approx(50.0)
    assert np.isnan(stats.values[5]).all()


def test_standard_deviations_are_sample_ones():
    stats = run_stats(REFERENCE, hand_made_runs())
    # Converged roll offsets 0.1 0.3 0.2: mean 0.2, squared deviations 0.01 + 0.01 + 0, / (3 - 1) -> std 0.1.
    assert stats.std_converged.roll_deg == pytest.approx(0.1, abs=1e-9)
    # Converged x offsets 0, 0.01, 0: (0, 0, a) has sample std a / sqrt(3).
    assert stats.std_converged.x_m == pytest.approx(0.01 / math.sqrt(3), abs=1e-12)
    assert stats.std_converged.pitch_deg == pytest.approx(0.0, abs=1e-9)
    # All 5 finished roll offsets 0.1 0.3 0.2 2.0 0.2: mean 0.56, squared deviations
    # 0.2116 + 0.0676 + 0.1296 + 2.0736 + 0.1296 = 2.612, / 4 = 0.653.
    assert stats.std.roll_deg == pytest.approx(math.sqrt(0.653), abs=1e-9)
    assert stats.mean.roll_deg == pytest.approx(REF_RPY[0] + 0.56, abs=1e-9)


def test_solution_and_errors_against_the_reference():
    stats = run_stats(REFERENCE, hand_made_runs())
    # Converged roll offsets 0.1 0.3 0.2 -> median 0.2; x offsets 0 0.01 0 -> median 0. R = Rz Ry Rx(roll), so a
    # pure roll change of 0.2 deg is a relative rotation of exactly 0.2 deg.
    err = stats.solution_error
    assert err.rotation_deg == pytest.approx(0.2, abs=1e-7)
    assert err.roll_deg == pytest.approx(0.2, abs=1e-9) and err.yaw_deg == pytest.approx(0.0, abs=1e-9)
    assert err.translation_cm == pytest.approx(0.0, abs=1e-9)
    # Each converged run's own error: rotation 0.1, 0.3, 0.2 deg -> median 0.2; translation 0, 1, 0 cm -> 0.
    assert stats.run_error_median.rotation_deg == pytest.approx(0.2, abs=1e-7)
    assert stats.run_error_median.translation_cm == pytest.approx(0.0, abs=1e-9)


def test_pose_rule_uses_angle_and_distance():
    zero = np.zeros(3)
    at_ref = [offset(zero, zero, zero, zero)] * 4
    # 2 cm in x and in y: each within 2.5 cm, but sqrt(2^2 + 2^2) = 2.83 cm from the median (the reference).
    moved = offset(zero, [0.02, 0.02, 0.0], zero, zero)
    # 0.4 deg roll and 0.4 deg pitch: each within 0.5 deg, together about sqrt(0.4^2 + 0.4^2) = 0.57 deg.
    turned = offset([0.4, 0.4, 0.0], zero, zero, zero)
    assert rotation_angle_deg(np.eye(3), turned.rotation) == pytest.approx(math.hypot(0.4, 0.4), abs=1e-3)
    runs = [*at_ref, moved, turned]
    assert run_stats(at_ref[0], runs, OutlierRule.PER_PARAMETER).converged.all()
    assert run_stats(at_ref[0], runs, OutlierRule.POSE).converged.tolist() == [True] * 4 + [False, False]


def test_yaw_across_the_wrap_stays_next_to_the_reference():
    ref = offset(zero := np.zeros(3), zero, np.array([0.0, 0.0, 179.9]), zero)
    runs = [Transform.from_rpy_xyz(np.array([0.0, 0.0, -179.9]), zero)] * 3  # 0.2 deg past +180
    stats = run_stats(ref, runs)
    assert stats.values[:, 2] == pytest.approx([180.1] * 3, abs=1e-9)
    assert stats.converged.all()
    assert stats.solution_error.yaw_deg == pytest.approx(0.2, abs=1e-9)
    assert stats.solution_error.rotation_deg == pytest.approx(0.2, abs=1e-7)


def test_too_few_runs_give_no_statistics():
    failed = run_stats(REFERENCE, [None, None])
    assert failed.converged_percent == 0.0 and failed.median is None and failed.solution_error is None
    single = run_stats(REFERENCE, [REFERENCE])
    assert single.converged_count == 1 and single.std is None and single.std_converged is None
    with pytest.raises(EvaluationError, match="tolerances"):
        run_stats(REFERENCE, [REFERENCE], rot_tol_deg=0.0)


def test_random_starts_are_uniform_within_the_box():
    starts = random_starts(REFERENCE, 3000, rot_deg=5.0, trans_m=0.1, seed=7)
    d_rpy = np.array([s.rpy_deg for s in starts]) - REF_RPY
    d_xyz = np.array([s.translation_m for s in starts]) - REF_XYZ
    assert np.abs(d_rpy).max() <= 5.0 + 1e-9 and np.abs(d_xyz).max() <= 0.1 + 1e-12
    # U(-a, a) has standard deviation a / sqrt(3); 3000 draws estimate it to about 1.3 %.
    assert d_rpy.std(axis=0) == pytest.approx([5.0 / math.sqrt(3)] * 3, rel=0.05)
    assert d_xyz.std(axis=0) == pytest.approx([0.1 / math.sqrt(3)] * 3, rel=0.05)
    assert np.abs(d_rpy.mean(axis=0)).max() < 0.2
    again = random_starts(REFERENCE, 3, 5.0, 0.1, seed=7)  # a shorter run of a seed is a prefix of a longer one
    assert all(np.allclose(a.matrix, b.matrix) for a, b in zip(again, starts[:3], strict=True))
    other = random_starts(REFERENCE, 3, 5.0, 0.1, seed=8)
    assert not np.allclose(other[0].matrix, starts[0].matrix)


def test_a_pinhole_reference_is_turned_about_the_lidars_axes():
    reference = _pinhole_reference()
    local = np.array([np.degrees(xi_of(reference.tau, s.tau)[:3]) for s in random_starts(reference, 3000, 2.0,
                                                                                             0.05, seed=7)])
    assert np.abs(local).max() <= 2.0 + 1e-9
    assert local.std(axis=0) == pytest.approx([2.0 / math.sqrt(3)] * 3, rel=0.05)
    # Roll/pitch/yaw draws at pitch -88.6 deg barely turn about the LiDAR's z axis (the image's pan).
    rpy = np.array([np.degrees(xi_of(reference.tau, s.tau)[:3])
                    for s in random_starts(reference, 3000, 2.0, 0.05, seed=7, axes=StartAxes.RPY)])
    assert rpy[:, 2].std() < 0.1 and rpy[:, 0].std() > 1.3
    # A panorama keeps the paper's draws: AUTO is RPY there, start for start.
    same = zip(random_starts(REFERENCE, 5, 5.0, 0.1, seed=7),
               random_starts(REFERENCE, 5, 5.0, 0.1, seed=7, axes=StartAxes.RPY), strict=True)
    assert all(np.array_equal(a.matrix, b.matrix) for a, b in same)


def test_zero_ranges_start_at_the_reference_and_bad_ranges_are_refused():
    (start,) = random_starts(REFERENCE, 1, 0.0, 0.0, seed=0)
    assert np.allclose(start.matrix, REFERENCE.matrix)
    with pytest.raises(EvaluationError, match="at least 1"):
        random_starts(REFERENCE, 0, 5.0, 0.1, seed=0)
    with pytest.raises(EvaluationError, match="ranges"):
        random_starts(REFERENCE, 1, -1.0, 0.1, seed=0)
    with pytest.raises(EvaluationError, match="seed"):
        random_starts(REFERENCE, 1, 5.0, 0.1, seed=-1)


def test_random_subsets_hold_distinct_sorted_indices():
    subsets = random_subsets(20, 12, 200, seed=3)
    assert len(subsets) == 200
    for s in subsets:
        assert len(s) == 12 and len(set(s)) == 12 and list(s) == sorted(s) and 0 <= s[0] and s[-1] < 20
    # Each index is in a subset with probability 12/20: over 200 subsets every one turns up.
    assert set().union(*subsets) == set(range(20))
    assert len(set(subsets)) > 150  # 125970 possible subsets: repeats are rare
    assert random_subsets(20, 12, 5, seed=3) == subsets[:5]
    assert random_subsets(12, 12, 2, seed=0) == (tuple(range(12)),) * 2


@pytest.mark.parametrize(("n", "size", "count"), [(5, 6, 1), (5, 0, 1), (5, 2, 0)])
def test_bad_subset_settings_are_refused(n, size, count):
    with pytest.raises(EvaluationError):
        random_subsets(n, size, count, seed=0)


def test_coverage_counts_axes_within_3_sigma_and_trusted_but_wrong_runs():
    ref = Transform.from_rpy_xyz(np.array([1.0, 15.0, -55.0]), np.array([0.1, 0.05, -0.17]))
    tol = np.array([0.2] * 3 + [2.0] * 3)
    # errors in deg/cm: run 0 small (trusted, fine), run 1 z 5 cm off with sigma 1 cm (trusted: wrong, 5 sigma)
    errs = np.array([[0.05, 0, 0, 0, 0, 0.5], [0, 0, 0, 0, 0, 5.0]])
    results = [Transform.from_tau(tau_at(ref.tau, e / TO_DISPLAY)) for e in errs]
    sigmas = [np.array([0.1] * 3 + [1.0] * 3)] * 2
    c = coverage(ref, [*results, None], [*sigmas, None], ["trusted", "trusted", None], tol)
    assert c.trusted_but_wrong == 1 and c.verdicts == {"trusted": 2}
    assert c.within_3_sigma == pytest.approx(11 / 12) and c.per_axis[5] == pytest.approx(0.5)
    assert np.allclose(c.z[0], [0.5, 0, 0, 0, 0, 0.5], atol=1e-9) and np.isnan(c.z[2]).all()


def test_coverage_against_an_uncertain_reference_weighs_both_sigmas() -> None:
    reference = Transform.identity()
    off = Transform(np.eye(3), np.array([0.0, 0.0, 0.05]))  # 5 cm off in z, trusted with a 0.7 cm sigma
    sigma = np.array([0.05, 0.05, 0.05, 0.7, 0.7, 0.7])
    tol = np.array([0.2, 0.2, 0.2, 2.0, 2.0, 2.0])
    truth = coverage(reference, [off], [sigma], ["trusted"], tol)
    assert truth.trusted_but_wrong == 1 and truth.per_axis[5] == 0.0
    ref_sigma = np.array([0.2, 0.2, 0.2, 2.9, 3.3, 2.5])  # a published estimate good to 2.5 cm in z
    estimate = coverage(reference, [off], [sigma], ["trusted"], tol, ref_sigma)
    assert estimate.trusted_but_wrong == 0 and estimate.per_axis[5] == 1.0
    far = Transform(np.eye(3), np.array([0.0, 0.0, 0.09]))  # beyond 2 cm + 2.5 x 2.5 cm: the reference can tell
    assert coverage(reference, [far], [sigma], ["trusted"], tol, ref_sigma).trusted_but_wrong == 1


def _pinhole_reference():
    # A forward pinhole camera under a ROS LiDAR: optical z = LiDAR x, so pitch is -88.6 deg, where roll and
    # yaw turn about nearly one axis.
    optical = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    tilt = Transform.from_rpy_xyz(np.array([0.0, 1.44, 0.0]), np.zeros(3)).rotation
    reference = Transform.from_tau(np.concatenate([
        Transform(optical @ tilt, np.zeros(3)).tau[:3], [-0.03, -0.35, -0.1]]))
    assert reference.rpy_deg[1] == pytest.approx(-88.56, abs=0.01)
    return reference


def test_a_pinhole_reference_at_pitch_minus_90_keeps_close_runs_close():
    # Runs 0.1 deg away about the LiDAR's axes swing roll and yaw by degrees.
    reference = _pinhole_reference()
    rng = np.random.default_rng(3)
    turns = rng.normal(size=(8, 3))
    turns *= np.radians(0.1) / np.linalg.norm(turns, axis=1, keepdims=True)
    runs = [Transform.from_tau(tau_at(reference.tau, np.concatenate([w, np.zeros(3)]))) for w in turns]
    assert np.ptp([r.rpy_deg[0] for r in runs]) > 1.0  # roll itself swings by degrees
    stats = run_stats(reference, runs, OutlierRule.PER_PARAMETER)
    assert stats.converged.all()
    assert max(stats.std_converged[:3]) < 0.1
    assert stats.solution_error.rotation_deg < 0.1
    assert rotation_angle_deg(_as_pose(stats.solution).rotation, reference.rotation) < 0.1


def _as_pose(p):
    return Transform.from_rpy_xyz(np.array(p[:3]), np.array(p[3:]))
