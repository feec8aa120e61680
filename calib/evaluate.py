"""Statistics of repeated calibrations: the paper's precision (8.2.2, Table 1) and convergence (8.5, Fig. 19)
protocols on arrays.

Convergence: calibrate from starts drawn uniformly within +-rot_deg on each of roll, pitch, yaw and +-trans_m
on each of x, y, z around a reference; a run is an outlier ("not converged") when it is too far from the
median of all runs (Fig. 19: 0.5 deg / 2.5 cm). Precision: calibrate random subsets of the pairs from one
start and report the per-parameter standard deviation (Table 1) and the deviations from the mean (Fig. 11).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from calib.errors import CalibError
from calib.geometry import Transform, rotation_angle_deg
from calib.uncertainty import TO_DISPLAY, tau_at, xi_of

F64 = NDArray[np.float64]

class EvaluationError(CalibError):
    """Invalid settings of an evaluation protocol (counts, ranges, subset sizes)."""


class OutlierRule(Enum):
    # Paper Fig. 19: an outlier if any of roll/pitch/yaw is more than rot_tol from its median, or any of
    # x/y/z more than trans_tol from its median.
    PER_PARAMETER = "per-parameter"
    # The rotation angle to the median pose exceeds rot_tol, or the translation distance exceeds trans_tol.
    POSE = "pose"


class Params6(NamedTuple):
    """One value per calibration parameter: roll, pitch, yaw in degrees, x, y, z in metres."""

    roll_deg: float
    pitch_deg: float
    yaw_deg: float
    x_m: float
    y_m: float
    z_m: float

    @classmethod
    def from_array(cls, values: F64) -> Params6:
        v = [float(x) for x in np.asarray(values, dtype=np.float64).reshape(6)]
        return cls(v[0], v[1], v[2], v[3], v[4], v[5])


class PoseError(NamedTuple):
    """A pose minus a reference: rotation angle of the relative rotation, translation distance, and per axis
    (the rotation from the reference about the LiDAR's x, y, z in degrees, named roll, pitch, yaw as they are
    for a panorama (:func:`parameter_values`); x, y, z in centimetres)."""

    rotation_deg: float
    translation_cm: float
    roll_deg: float
    pitch_deg: float
    yaw_deg: float
    x_cm: float
    y_cm: float
    z_cm: float


class ErrorMedian(NamedTuple):
    """Median over runs of each run's own rotation angle (deg) and translation distance (cm) error."""

    rotation_deg: float
    translation_cm: float


@dataclass(frozen=True)
class RunStats:
    """Statistics of N calibration runs of one protocol against a reference pose.

    ``values`` (N,6) float64: :func:`parameter_values` of every run (roll, pitch, yaw columns: the reference's
    plus the run's rotation about the LiDAR's x, y, z, deg; x, y, z m); a row of NaN for a run that failed
    (raised). ``converged`` (N,) bool: finished and not an outlier. ``median``: the pose at the per-column
    median of the finished runs (the outlier rule's centre), as roll, pitch, yaw and x, y, z. ``mean``/``std``:
    over all finished runs (Table 1, Fig. 11; ``mean`` the pose at the column means, ``std`` of the columns:
    about the LiDAR's axes); ``std_converged``: over the converged runs (Fig. 19); standard deviations are
    sample ones (ddof=1) and None with fewer than two runs. ``solution``: the pose at the per-column median of
    the converged runs and ``solution_error`` its error vs the reference; ``run_error_median``: the median of
    the converged runs' own errors.
    """

    values: F64
    converged: NDArray[np.bool_]
    rule: OutlierRule
    rot_tol_deg: float
    trans_tol_m: float
    median: Params6 | None
    mean: Params6 | None
    std: Params6 | None
    std_converged: Params6 | None
    solution: Params6 | None
    solution_error: PoseError | None
    run_error_median: ErrorMedian | None

    @property
    def runs(self) -> int:
        return len(self.converged)

    @property
    def finished(self) -> int:
        return int(np.isfinite(self.values[:, 0]).sum())

    @property
    def converged_count(self) -> int:
        return int(self.converged.sum())

    @property
    def converged_percent(self) -> float:
        return 100.0 * self.converged_count / self.runs if self.runs else 0.0


def parameter_values(reference: Transform, results: Sequence[Transform | None]) -> F64:
    """(N,6) per run: roll, pitch, yaw columns as the reference's roll, pitch, yaw (deg) plus the run's rotation
    from the reference about the LiDAR's x, y, z (deg, the axes of the reported sigmas), and x, y, z (m); NaN rows
    for None. Where roll, pitch, yaw turn about three distinct axes (a panorama: roll and pitch near 0) this is the
    run's own roll, pitch, yaw to first order; near pitch +-90 deg (every forward pinhole camera under a ROS
    LiDAR) roll and yaw turn about one axis, so their own values swing by degrees between poses a tenth of a
    degree apart, and medians and spreads of them mean nothing."""
    values = np.full((len(results), 6), np.nan)
    ref_rpy, ref_tau = reference.rpy_deg, reference.tau
    for i, t in enumerate(results):
        if t is not None:
            values[i, :3] = ref_rpy + np.degrees(xi_of(ref_tau, t.tau)[:3])
            values[i, 3:] = t.translation_m
    return values


def _pose(reference: Transform, values: F64) -> Transform:
    """The pose of one row of :func:`parameter_values` around ``reference``."""
    xi = np.concatenate([np.radians(values[:3] - reference.rpy_deg), values[3:] - reference.translation_m])
    return Transform.from_tau(tau_at(reference.tau, xi))


def _params(pose: Transform) -> Params6:
    return Params6.from_array(np.concatenate([pose.rpy_deg, pose.translation_m]))


def pose_error(pose: Transform, reference: Transform) -> PoseError:
    d_rpy = np.degrees(xi_of(reference.tau, pose.tau)[:3])  # about the LiDAR's x, y, z: see parameter_values
    d_xyz_cm = (pose.translation_m - reference.translation_m) * 100.0
    return PoseError(
        rotation_angle_deg(reference.rotation, pose.rotation), float(np.linalg.norm(d_xyz_cm)),
        float(d_rpy[0]), float(d_rpy[1]), float(d_rpy[2]),
        float(d_xyz_cm[0]), float(d_xyz_cm[1]), float(d_xyz_cm[2]),
    )


def _outliers(reference: Transform, values: F64, centre: F64, rule: OutlierRule, rot_tol_deg: float,
              trans_tol_m: float) -> NDArray[np.bool_]:
    """(N,) True for a finished run farther from ``centre`` (6,) than the rule allows; ``values`` finite."""
    if rule is OutlierRule.PER_PARAMETER:
        far_rot = (np.abs(values[:, :3] - centre[:3]) > rot_tol_deg).any(axis=1)
        far_trans = (np.abs(values[:, 3:] - centre[3:]) > trans_tol_m).any(axis=1)
        return np.asarray(far_rot | far_trans)
    centre_pose = _pose(reference, centre)
    angles = np.array([rotation_angle_deg(centre_pose.rotation, _pose(reference, v).rotation) for v in values])
    distances = np.linalg.norm(values[:, 3:] - centre[3:], axis=1)
    return np.asarray((angles > rot_tol_deg) | (distances > trans_tol_m))


def _std(values: F64) -> Params6 | None:
    return Params6.from_array(values.std(axis=0, ddof=1)) if len(values) >= 2 else None


def run_stats(
    reference: Transform,
    results: Sequence[Transform | None],
    rule: OutlierRule = OutlierRule.PER_PARAMETER,
    rot_tol_deg: float = 0.5,
    trans_tol_m: float = 0.025,
) -> RunStats:
    """Statistics of calibration ``results`` (None: the run failed) against ``reference`` (module docstring)."""
    if not (rot_tol_deg > 0 and trans_tol_m > 0):
        raise EvaluationError(f"outlier tolerances must be positive, got {rot_tol_deg} deg, {trans_tol_m} m")
    values = parameter_values(reference, results)
    finished = np.isfinite(values[:, 0])
    done = values[finished]
    converged = np.zeros(len(values), dtype=bool)
    if len(done) == 0:
        return RunStats(values, converged, rule, rot_tol_deg, trans_tol_m, None, None, None, None, None, None, None)
    centre = np.median(done, axis=0)
    converged[finished] = ~_outliers(reference, done, centre, rule, rot_tol_deg, trans_tol_m)
    good = values[converged]
    solution = solution_error = run_error = None
    if len(good):
        solution_pose = _pose(reference, np.median(good, axis=0))
        solution = _params(solution_pose)
        solution_error = pose_error(solution_pose, reference)
        errors = np.array([pose_error(_pose(reference, v), reference)[:2] for v in good])
        run_error = ErrorMedian(float(np.median(errors[:, 0])), float(np.median(errors[:, 1])))
    return RunStats(
        values, converged, rule, rot_tol_deg, trans_tol_m, _params(_pose(reference, centre)),
        _params(_pose(reference, done.mean(axis=0))), _std(done), _std(good), solution, solution_error, run_error,
    )


def _rng(seed: int) -> np.random.Generator:
    if seed < 0:
        raise EvaluationError(f"seed must be >= 0, got {seed}")
    return np.random.default_rng(seed)


class StartAxes(Enum):
    """How :func:`random_starts` turns the reference."""

    # The paper's: roll, pitch and yaw each plus a draw. Near pitch +-90 deg (a forward pinhole camera under a ROS
    # LiDAR) roll and yaw turn about one axis, so these draws turn it by up to twice the range and leave the
    # third axis (the image's pan) all but untouched.
    RPY = "rpy"
    # The reference turned about the LiDAR's x, y, z by a draw each (the sigmas' local axes).
    LIDAR = "lidar"
    # RPY where roll, pitch and yaw name three distinct axes (|pitch| <= 45 deg: panoramas, heads), else LIDAR.
    AUTO = "auto"

    def resolve(self, reference: Transform) -> StartAxes:
        if self is not StartAxes.AUTO:
            return self
        return StartAxes.RPY if abs(float(reference.rpy_deg[1])) <= 45.0 else StartAxes.LIDAR


def random_starts(reference: Transform, count: int, rot_deg: float, trans_m: float, seed: int,
                  axes: StartAxes = StartAxes.AUTO) -> tuple[Transform, ...]:
    """``count`` starts: ``reference`` turned by U(-rot_deg, rot_deg) about each of ``axes`` (:class:`StartAxes`;
    paper 8.5: roll, pitch, yaw, +-5 deg) and its x, y, z each plus U(-trans_m, trans_m) (paper: +-10 cm), from
    ``numpy.random.default_rng(seed)``; the first k of n starts equal the k starts of the same seed."""
    if count < 1:
        raise EvaluationError(f"the number of starts must be at least 1, got {count}")
    if not (np.isfinite(rot_deg) and np.isfinite(trans_m) and rot_deg >= 0 and trans_m >= 0):
        raise EvaluationError(f"start ranges must be finite and >= 0, got +-{rot_deg} deg, +-{trans_m} m")
    # One row of 6 draws per start, so the first k of n starts are the k starts of the same seed.
    unit = _rng(seed).uniform(-1.0, 1.0, size=(count, 6))
    rpy, xyz = reference.rpy_deg, reference.translation_m
    if axes.resolve(reference) is StartAxes.RPY:
        return tuple(Transform.from_rpy_xyz(rpy + rot_deg * u[:3], xyz + trans_m * u[3:]) for u in unit)
    return tuple(Transform.from_tau(tau_at(reference.tau, np.concatenate([np.radians(rot_deg * u[:3]),
                                                                          trans_m * u[3:]])))
                 for u in unit)


def random_subsets(n_pairs: int, size: int, count: int, seed: int) -> tuple[tuple[int, ...], ...]:
    """``count`` subsets of ``size`` distinct pair indices out of ``range(n_pairs)``, each sorted (paper 8.2.2:
    100 subsets of 12 pairs), from ``numpy.random.default_rng(seed)``. Subsets may repeat."""
    if count < 1:
        raise EvaluationError(f"the number of subsets must be at least 1, got {count}")
    if not 1 <= size <= n_pairs:
        raise EvaluationError(f"subset size must be between 1 and the dataset's {n_pairs} pairs, got {size}")
    rng = _rng(seed)
    return tuple(tuple(sorted(int(i) for i in rng.choice(n_pairs, size=size, replace=False))) for _ in range(count))


@dataclass(frozen=True)
class Coverage:
    """How honest the reported uncertainty and verdicts were over a set of runs against a reference.

    ``z`` (N,6): each run's error in the uncertainty's local axes (deg about the LiDAR's x, y, z; cm) over its
    reported sigma (NaN where a run has none); ``within_3_sigma`` the share of finite axes with |z| <= 3 (the
    issue's calibration target: >= 95 %), per axis in ``per_axis``; ``verdicts`` the count of each verdict;
    ``trusted_but_wrong`` the runs called trusted whose error exceeds the tolerance on some axis (the worst
    defect: it must be 0)."""

    z: F64
    within_3_sigma: float
    per_axis: tuple[float, ...]
    verdicts: dict[str, int]
    trusted_but_wrong: int


def coverage(reference: Transform, results: Sequence[Transform | None], sigmas: Sequence[F64 | None],
             verdicts: Sequence[str | None], tolerance: F64, reference_sigma: F64 | None = None) -> Coverage:
    """Coverage of ``results`` (with their per-axis ``sigmas`` (6,) deg/cm and verdict names) around
    ``reference``; ``tolerance`` (6,) deg/cm. ``reference_sigma`` (6,) deg/cm: the reference is itself an
    estimate (real data) with this one-sigma per axis: a difference is then weighed against both sigmas, and a
    trusted run counts as wrong only beyond the tolerance plus 2.5 of the reference's sigmas (closer, the
    reference cannot tell)."""
    z = np.full((len(results), 6), np.nan)
    wrong = 0
    ref_sigma = np.zeros(6) if reference_sigma is None else np.asarray(reference_sigma, dtype=np.float64)
    for i, (t, s, v) in enumerate(zip(results, sigmas, verdicts, strict=True)):
        if t is None or s is None:
            continue
        err = xi_of(reference.tau, t.tau) * TO_DISPLAY
        both = np.sqrt(np.asarray(s, dtype=np.float64) ** 2 + ref_sigma**2)
        with np.errstate(divide="ignore", invalid="ignore"):
            z[i] = np.where(both > 0, err / both, np.where(np.abs(err) < 1e-9, 0.0, np.inf))
        wrong += int(v == "trusted" and bool((np.abs(err) > tolerance + 2.5 * ref_sigma).any()))
    finite = ~np.isnan(z)
    share = float((np.abs(z[finite]) <= 3.0).mean()) if finite.any() else float("nan")
    per_axis = tuple(float((np.abs(z[finite[:, k], k]) <= 3.0).mean()) if finite[:, k].any() else float("nan")
                     for k in range(6))
    counts: dict[str, int] = {}
    for v in verdicts:
        if v is not None:
            counts[v] = counts.get(v, 0) + 1
    return Coverage(z, share, per_axis, counts, wrong)
