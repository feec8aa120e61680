"""Is a calibration to be trusted? Restarts, jackknife, Laplace covariance and a verdict (docs/trust.md).

After the coarse-to-fine solve:
1. Restarts: the last levels rerun from poses around the solution. One that ends lower replaces the
   solution (the objective decides); one that ends elsewhere at a cost the data cannot tell apart from the
   solution's (a log-likelihood difference below ``ambiguity_nll``, with the cost's NLL scale kappa) makes
   the axes it moved ambiguous.
2. Uncertainty: the sandwich covariance of the finest level (calib.uncertainty) and a delete-a-group
   jackknife (each pair left out, or, with fewer than ``jackknife_min_pairs`` pairs, each of
   ``jackknife_groups`` random groups of angular image cells), each left-out solve one Newton step of the
   finest level from the solution with the per-cluster Hessians. Each axis takes the larger of the two
   sigmas; correlations come from the sandwich.
3. Verdict: ``trusted`` when every axis is known to within the field tolerance (``2.5 sigma <= tolerance``)
   and no restart found a different, equally good pose; ``weak`` naming the axes that are not; ``failed`` when
   the solution is not a minimum, is ambiguous by several tolerances, most restarts ended at other, higher
   minima instead of coming back (``min_returned_share``), or most axes are far from known.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from calib.edges_points import FOLD
from calib.geometry import rotation_angle_deg, so3_exp
from calib.gmm import GmmOptions, PairFeatures, in_image, transform_points
from calib.handed import Progress, shared_calls
from calib.optimize import (
    OptimOptions,
    OptimResult,
    hessian_steps,
    level_model,
    optimise,
    tail_options,
    typical_range_m,
)
from calib.prior import Prior
from calib.uncertainty import (
    AXES,
    TO_DISPLAY,
    Clusters,
    clusters_at,
    hessian,
    local_gradient,
    matched_points,
    nll_scale,
    places,
    positive_part,
    sandwich,
    scatter,
    sigmas_display,
    symmetric,
    tau_at,
    weakest_direction,
    xi_of,
)

F64 = NDArray[np.float64]


class Status(Enum):
    TRUSTED = "trusted"
    WEAK = "weak"
    FAILED = "failed"
    NOT_ASSESSED = "not_assessed"  # a method without an assessment (calib.methods): nothing is claimed


@dataclass(frozen=True)
class TrustOptions:
    """``tolerance_rot_deg`` / ``tolerance_trans_cm``: the field tolerance per axis (the rig file may change
    it). ``sigma_factor``: an axis is known when ``sigma_factor * sigma`` is within tolerance (2.5: measured,
    docs/trust.md)."""

    tolerance_rot_deg: float = 0.2
    tolerance_trans_cm: float = 2.0
    # Each axis's own tolerance (roll, pitch, yaw deg; x, y, z cm), where the application needs one axis tighter
    # than the others (a yaw that sets a map's heading, a z that matters little); (): the two above.
    tolerance_per_axis: tuple[float, ...] = ()
    sigma_factor: float = 2.5
    restarts: int = 4
    restart_levels: int = 2
    restart_rot_deg: float = 2.0  # beyond the finest level's basin (docs/trust.md: 0.5 deg stayed inside it)
    restart_trans_m: float = 0.05
    ambiguity_nll: float = 4.5  # 2 * delta NLL < 9: within 3 sigma of the best, statistically a tie
    jackknife_min_pairs: int = 4  # fewer pairs: the jackknife leaves out groups of image cells instead
    jackknife_min_rings: int = 4  # rings with edge points needed for the jackknife over rings
    jackknife_groups: int = 8
    min_places: int = 2  # fewer places: the sigmas cannot be checked across places, nothing is vouched for
    prior_max_z: float = 3.0  # a result beyond this many of the prior's sigmas from its values disagrees with it
    fixed_worse_nll: float = 12.5  # held axes fitting this much worse than free (2 dNLL > 25): the values disagree
    search_runners_up: int = 1  # without an initial guess: the global search's next starts solved in full
    failed_tolerances: float = 5.0  # ambiguity or sigma beyond this many tolerances on most axes: failed
    min_returned_share: float = 0.5  # fewer restarts back at the solution: the cost has several minima nearby
    max_move_deg: float = 20.0  # a solve that ends farther from its start ran to another alignment (docs/trust.md)
    # A translation that ends this far from its start was pulled there by a lever arm that is not this rig's (a
    # prior typed in cm where metres are meant): a rig's lever arm is known to decimetres before any calibration.
    max_move_m: float = 1.0
    # A single camera's principal point known to so many rad about the camera's x and y axes (rig.yaml's
    # principal_point_sigma_px over fy and fx): it turns the image as a tilt of the LiDAR would, which one camera
    # cannot tell apart, so it is part of the rotation's sigma (docs/trust.md). 0: K taken as exact.
    intrinsics_sigma_rad: tuple[float, float] = (0.0, 0.0)
    # The LiDAR's elevation offset known to so many deg (rig.yaml's elevation_offset_sigma_deg; 0: exact): the
    # calibration turns it into the pose's change below (calib.elevation.elevation_slope).
    elevation_sigma_deg: float = 0.0
    # The pose's change (6,) in local coordinates (rad, m) for one sigma of the LiDAR's elevation offset, fitted
    # or declared (calib.elevation); () when neither.
    elevation_sigma_pose: tuple[float, ...] = ()
    # Where a second method's answer lies from the solution (6,) in local coordinates (rad, m): the GMM's edges
    # refined from NID's solution (calib.methods); () when none was asked for or the edges could not be read.
    cross_check_pose: tuple[float, ...] = ()
    seed: int = 0

    @property
    def tolerance_display(self) -> F64:
        if self.tolerance_per_axis:
            return np.array(self.tolerance_per_axis, dtype=np.float64)
        return np.array([self.tolerance_rot_deg] * 3 + [self.tolerance_trans_cm] * 3)


@dataclass(frozen=True)
class Uncertainty:
    """``covariance`` (6,6) of the local coordinates [rad, rad, rad, m, m, m] (calib.uncertainty);
    ``sigma`` (6,) deg/cm the reported per-axis sigma, the largest of its sources: ``laplace``, ``jackknife``
    (over places) and ``jackknife_rings`` (6,) deg/cm (the jackknives None when they could not be formed);
    ``kappa`` the cost's NLL scale."""

    covariance: F64
    sigma: F64
    laplace: F64
    jackknife: F64 | None
    jackknife_groups: int
    weakest: str
    is_minimum: bool
    kappa: float
    matched_share: float
    # Places (pair indices) the pose rests on: without any one of them the others' cost does not hold it (the
    # jackknife's solve without it ran to the finest kernel's width, or half as far while carrying most of the
    # jackknife's spread; either sets the jackknife's sigma, which then says "held by these", not how it would
    # fall with more pairs). () when the groups are image cells.
    held_by: tuple[int, ...] = ()
    # The jackknife over the LiDAR's rings (each left out in turn, in every place; None: no rings known, or too
    # few): how much the pose depends on where the rings fall on the scene's edges, which every place shares
    # and the jackknife over places cannot see (docs/trust.md).
    jackknife_rings: F64 | None = None
    ring_groups: int = 0
    # How far apart the restarts and the solve landed (6,) deg/cm, RMS of their offsets from the solution, where
    # it enters the sigma (calib.assess_photo: Nelder-Mead on a cost rough below a pixel stops wherever its
    # simplex shrinks); None for the GMM, whose restarts are judged by the rules of the verdict instead.
    restart_spread: F64 | None = None
    # The camera model's part of the sigma (6,) deg/cm: the principal point's uncertainty as a rotation (None:
    # K taken as exact; :func:`with_intrinsics`).
    intrinsics: F64 | None = None
    # The LiDAR elevation offset's part of the sigma (6,) deg/cm (None: exact; :func:`with_elevation`).
    elevation: F64 | None = None
    # A second method's disagreement (6,) deg/cm, d / sqrt(2) (None: no second method; :func:`with_cross_check`):
    # the verdict vouches for no axis it alone leaves unknown; not part of ``sigma``.
    cross_check: F64 | None = None


def with_intrinsics(unc: Uncertainty, tau: F64, trust: TrustOptions) -> Uncertainty:
    """``unc`` with the principal point's uncertainty (``trust.intrinsics_sigma_rad``, rotations delta about the
    camera's x and y axes) added: in local coordinates xi = R^T delta (the solution's R: camera from LiDAR).
    Independent of the data's, it adds in quadrature."""
    sx, sy = trust.intrinsics_sigma_rad
    if (sx <= 0.0 and sy <= 0.0) or not unc.is_minimum:
        return unc
    r = so3_exp(np.asarray(tau[:3], dtype=np.float64))
    extra = np.zeros((6, 6))
    extra[:3, :3] = r.T @ np.diag([sx**2, sy**2, 0.0]) @ r
    return replace(_with_part(unc, extra, trust), intrinsics=sigmas_display(extra))


def _with_part(unc: Uncertainty, extra: F64, trust: TrustOptions) -> Uncertainty:
    """``unc`` with an independent source's covariance ``extra`` (6,6) added in quadrature."""
    cov = unc.covariance + extra
    sigma = np.sqrt(np.square(unc.sigma) + np.square(sigmas_display(extra)))
    return replace(unc, covariance=cov, sigma=sigma, weakest=weakest_direction(cov, trust.tolerance_display))


def with_elevation(unc: Uncertainty, trust: TrustOptions) -> Uncertainty:
    """``unc`` with the elevation offset's uncertainty (``trust.elevation_sigma_pose``, fitted or declared) added:
    the pose moves along the slope as the offset does (calib.elevation). Independent of the data's jackknife,
    which holds the offset, it adds in quadrature."""
    if not trust.elevation_sigma_pose or not unc.is_minimum:
        return unc
    part = np.asarray(trust.elevation_sigma_pose, dtype=np.float64)
    extra = np.outer(part, part)
    return replace(_with_part(unc, extra, trust), elevation=sigmas_display(extra))


def with_cross_check(unc: Uncertainty, trust: TrustOptions) -> Uncertainty:
    """``unc`` with a second method's disagreement (``trust.cross_check_pose``, d from the solution) as its part:
    two answers from independent evidence (the image's edges, its intensities) that land d apart cannot both be
    right; were both unbiased with one sigma, d would have that sigma times sqrt(2), so d / sqrt(2) along d is
    the bias neither can rule out. The verdict vouches for no axis it disputes (:func:`verdict_of`); it is kept
    out of the sigma, which says how well this method's own data hold it."""
    if not trust.cross_check_pose or not unc.is_minimum:
        return unc
    part = np.asarray(trust.cross_check_pose, dtype=np.float64) / np.sqrt(2.0)
    return replace(unc, cross_check=sigmas_display(np.outer(part, part)))


def disputed_axes(unc: Uncertainty, trust: TrustOptions) -> tuple[str, ...]:
    """The axes a second method's disagreement alone leaves unknown: ``sigma_factor`` times its part beyond the
    tolerance."""
    if unc.cross_check is None:
        return ()
    over = trust.sigma_factor * unc.cross_check > trust.tolerance_display
    return tuple(AXES[k] for k in np.flatnonzero(over))


def _disputed(unc: Uncertainty, trust: TrustOptions) -> list[tuple[tuple[str, ...], str]]:
    """:func:`disputed_axes` with why: not vouched for, but no reason to fail a result, as the second method (the
    GMM's edges on one pinhole camera) may be the biased one."""
    over = [AXES.index(ax) for ax in disputed_axes(unc, trust)]
    if not over or unc.cross_check is None:
        return []
    moves = ", ".join(f"{AXES[k]} {np.sqrt(2.0) * unc.cross_check[k]:.2g}{'°' if k < 3 else ' cm'}" for k in over)
    return [(tuple(AXES[k] for k in over), f"the image's edges refined from this answer move {moves}: the two costs "
                                           "disagree, so neither vouches for these axes")]


UNHELD_SHARE = 0.999  # a left-out solve this close to the kernel's width ran to it (trust_region_step's bound)
# A left-out solve at least this share of the kernel's width away, carrying more than HOLDING_SPREAD of the
# left-out solves' squared distances, holds the pose too. Ford head, places 0003, 0004, 0006, 0008 and 0009:
# without 0009 the solve moves 0.71 of the width (z 13 cm) and carries 84 % of that spread (the next 0.26 of
# the width); the jackknife's z sigma 11.8 cm would read "1081 pairs needed", where all ten places give 0.7 cm.
HOLDING_REACH = 0.5
HOLDING_SPREAD = 0.5
LOCAL_ORIGINS = ("restart", "solution")  # solves from around the solution (not from the search's other starts)


@dataclass(frozen=True)
class Restart:
    """One restart: its offset from the solution in deg/cm (6,) and the NLL above the best (>= 0 unless it
    replaced the solution)."""

    offset: F64
    delta_nll: float
    # or "search runner-up" / "search start": a full solve from one of the global search's starts; "solution":
    # the first solution, when a restart ended lower
    origin: str = "restart"


@dataclass(frozen=True)
class Verdict:
    """``weak_axes``: the axes not vouched for; ``fixed_axes``: axes held at the values given, reported as given
    (not checked, never vouched for)."""

    status: Status
    weak_axes: tuple[str, ...]
    reasons: tuple[str, ...]
    fixed_axes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Evidence:
    """What the verdict weighs besides the sigmas and the restarts: how far the solve moved from its nearest start
    (deg, m), how many places its pairs were taken at, how far it lies from the prior's values in their sigmas
    (rotation, translation; None: no such prior), the axes held at given values, and how much worse (NLL) the
    held solution fits than one with those axes free."""

    moved_deg: float | None = None
    moved_m: float | None = None
    places: int | None = None
    prior_z: tuple[float | None, float | None] = (None, None)
    fixed: tuple[str, ...] = ()
    fixed_worse_nll: float | None = None


@dataclass(frozen=True)
class Assessment:
    tau: F64
    optim: OptimResult
    uncertainty: Uncertainty
    restarts: tuple[Restart, ...]
    verdict: Verdict
    moved_deg: float | None = None  # rotation from the nearest start of a solve to the solution; None: unknown
    moved_m: float | None = None  # translation from the nearest start to the solution; None: unknown
    evidence: Evidence | None = None  # what the verdict weighed besides the sigmas and restarts


def _run_restarts(feats: list[PairFeatures], best: OptimResult, opts: OptimOptions, gmm: GmmOptions,
                  prior: Prior | None, trust: TrustOptions,
                  executor: Executor | None, while_waiting: Callable[[], None] | None = None,
                  on_progress: Progress | None = None) -> tuple[OptimResult, list[OptimResult]]:
    """Rerun the last levels from ``trust.restarts`` poses around the solution; returns the best run (the
    solution itself unless a restart ended lower) and every restart (shared with the pool, calib.handed.share,
    with ``while_waiting``).
    Each level weighs the prior as the solution's did: the restarts minimise the objective the solution
    minimised, so their final costs compare with its."""
    rng = np.random.default_rng(trust.seed)
    tail, kappas = _tail(best, opts, trust)
    fixed_t = prior is not None and prior.fix_translation
    starts = []
    for _ in range(trust.restarts):
        offset = np.concatenate([np.radians(rng.uniform(-1, 1, 3) * trust.restart_rot_deg),
                                 np.zeros(3) if fixed_t else rng.uniform(-1, 1, 3) * trust.restart_trans_m])
        starts.append(tau_at(best.tau, offset))
    # This process uses the field bands the main solve built here, a worker those its own solves built (the
    # application's pool hands a features list back to the worker that holds it). Same results as without a pool.
    runs = shared_calls(executor, _restart_solve, [(feats, s, tail, gmm, prior, kappas) for s in starts],
                        while_waiting, on_progress)
    winner = min([best, *runs], key=lambda r: r.final_cost)
    return winner, runs


def _tail(best: OptimResult, opts: OptimOptions, trust: TrustOptions) -> tuple[OptimOptions,
                                                                                 tuple[float | None, ...]]:
    """The restarts' levels (the schedule's last ``trust.restart_levels``) and the solution's prior weight on each,
    so their final costs compare with the solution's."""
    # Fold edges on the last levels (a pinhole's schedule, calib.pipeline.schedule) make the finest cost
    # rugged within the restarts' 2 deg: one level more smooths it as the solve's own coarser level did.
    levels = trust.restart_levels + (1 if opts.fold_levels >= len(opts.sigmas_deg) else 0)
    tail = tail_options(opts, min(levels, len(opts.sigmas_deg)))
    # By level width: the solution may come from a shorter schedule than the tail (the alternative one).
    solved = {round(t.sigma_in_deg, 9): t.kappa for t in best.levels}
    return tail, tuple(solved.get(round(s, 9)) for s in tail.sigmas_deg)


def _fixed_worse(feats: list[PairFeatures], best: OptimResult, opts: OptimOptions, gmm: GmmOptions,
                 prior: Prior, trust: TrustOptions, kappa: float) -> float:
    """How much worse (NLL) the solution with its translation held fits than the restarts' levels from it with the
    translation free (the rotation prior, if any, kept)."""
    tail, kappas = _tail(best, opts, trust)
    free = Prior(rotation=prior.rotation, sigma_rot_rad=prior.sigma_rot_rad) if prior.rotation is not None else None
    loose = optimise(feats, best.tau, tail, gmm, prior=free, kappas=kappas)
    return max(float(best.final_cost - loose.final_cost) / kappa, 0.0)


def _restart_solve(feats: list[PairFeatures], start: F64, tail: OptimOptions, gmm: GmmOptions,
                   prior: Prior | None, kappas: tuple[float | None, ...]) -> OptimResult:
    """One restart: the tail levels from ``start`` with the solution's prior weights."""
    return optimise(feats, start, tail, gmm, prior=prior, kappas=kappas)


def _groups(clusters: Clusters, n_pairs: int, trust: TrustOptions) -> tuple[NDArray[np.int64], int]:
    """Jackknife group (C,) of each cluster, and the number of groups: the place (``n_pairs`` places), or (few
    places) a random group of angular image cells."""
    if n_pairs >= trust.jackknife_min_pairs:
        return clusters.pair, n_pairs
    rng = np.random.default_rng(trust.seed)
    return (rng.permutation(clusters.cells) % trust.jackknife_groups)[clusters.cell], trust.jackknife_groups


def _ring_groups(clusters: Clusters, trust: TrustOptions) -> tuple[NDArray[np.int64], int] | None:
    """Jackknife group (C,) of each cluster by its ring, and the number of rings; None when the points carry no
    rings or fewer than ``trust.jackknife_min_rings`` hold edge points."""
    if clusters.count == 0 or np.any(clusters.ring < 0):
        return None
    rings, group = np.unique(clusters.ring, return_inverse=True)
    if len(rings) < trust.jackknife_min_rings:
        return None
    return np.asarray(group, dtype=np.int64).reshape(-1), len(rings)


def trust_region_step(h: F64, g: F64, scale: F64, radius: float) -> F64:
    """argmin over s of g.s + s.H s / 2 with |scale * s| <= radius (Moré & Sorensen's trust-region step, by
    the eigenvectors of the small H): the Newton step where H is positive definite and the step is short
    enough, else the step to the boundary along which the quadratic model falls most."""
    hy, gy = h / np.outer(scale, scale), g / scale  # y = scale * s: a ball in y
    w, v = np.linalg.eigh(0.5 * (hy + hy.T))
    gv = v.T @ gy

    def length(lam: float) -> float:
        with np.errstate(divide="ignore"):
            return float(np.linalg.norm(gv / (w + lam)))

    if w[0] > 0 and length(0.0) <= radius:
        return np.asarray(v @ (-gv / w) / scale, dtype=np.float64)
    lo = max(0.0, -float(w[0])) * (1.0 + 1e-12) + 1e-300
    if length(lo) <= radius:  # the "hard case": g has (almost) no component along the lowest curvature
        y = v @ (-gv / np.maximum(w + lo, 1e-300))
        rest = np.sqrt(max(radius**2 - float(y @ y), 0.0))
        return np.asarray((y + (1.0 if gv[0] <= 0 else -1.0) * rest * v[:, 0]) / scale, dtype=np.float64)
    hi = lo + float(np.linalg.norm(gy)) / radius + float(np.abs(w).max())
    for _ in range(200):  # |y(lam)| falls monotonically in lam: bisect for |y| = radius
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if length(mid) > radius else (lo, mid)
    return np.asarray(v @ (-gv / (w + hi)) / scale, dtype=np.float64)


def _jackknife(grads: F64, hessians: F64, extra_h: F64, groups: NDArray[np.int64], n_groups: int,
               free: NDArray[np.bool_], scale: F64, radius: float) -> tuple[F64 | None, tuple[int, ...]]:
    """Delete-a-group jackknife covariance (6,6) of the local coordinates. Each left-out solve is one Newton
    step of the finest level from the solution (the finite-difference Hessian is per cluster, so this costs
    no further evaluation): xi_g = -(H - H_g)^-1 (g - g_g), kept within the finest level's kernel width
    (``|scale * xi| <= radius``, :func:`trust_region_step`). Beyond it the quadratic model says nothing: where
    the other groups leave a direction flat or curved down, the left-out solve would slide along it to
    wherever the cost next rises, and an unbounded Newton step put thousands of degrees into the jackknife
    of one frame. ``free`` masks the estimated coordinates. Also returns the groups that hold the pose
    (:func:`holding_groups`)."""
    offsets, left_out = [], []
    total_g, total_h = grads.sum(axis=0), hessians.sum(axis=0)
    for g in range(n_groups):
        mine = groups == g
        if not mine.any():
            continue
        h_rest = symmetric(total_h - hessians[mine].sum(axis=0) + extra_h)[np.ix_(free, free)]
        step = np.zeros(6)
        step[free] = trust_region_step(h_rest, (total_g - grads[mine].sum(axis=0))[free], scale[free], radius)
        offsets.append(step)
        left_out.append(g)
    if len(offsets) < 3:
        return None, ()
    xs = np.array(offsets)
    centred = xs - xs.mean(axis=0)
    k = len(offsets)
    cov = np.asarray((k - 1.0) / k * centred.T @ centred, dtype=np.float64)
    return cov, holding_groups(xs, left_out, scale, radius)


def holding_groups(steps: F64, groups: list[int], scale: F64, radius: float) -> tuple[int, ...]:
    """The groups whose left-out solve (``steps`` (K,6), local coordinates) ran to the kernel's width, or
    ``HOLDING_REACH`` of it while carrying more than ``HOLDING_SPREAD`` of the solves' squared distances."""
    reach = np.linalg.norm(steps * scale, axis=1) / radius
    spread = reach**2 / max(float(np.sum(reach**2)), 1e-300)
    held = (reach >= UNHELD_SHARE) | ((reach >= HOLDING_REACH) & (spread > HOLDING_SPREAD))
    return tuple(g for g, h in zip(groups, held, strict=True) if h)


def _in_image_count(feats: tuple[PairFeatures, ...], tau: F64, use_folds: bool) -> int:
    """Edge points of the finest level that project into their image at ``tau``."""
    total = 0
    for f in feats:
        uv, valid = f.camera.project(transform_points(tau, f.points.points_lidar)[0])
        total += int(np.count_nonzero(in_image(f.camera, uv, valid) & (use_folds | (f.points.kind != FOLD))))
    return total


def combine_covariance(cov_l: F64, sigma: F64) -> F64:
    """The covariance with per-axis ``sigma`` (deg/cm) and the sandwich's correlations."""
    d_l = np.sqrt(np.maximum(np.diag(cov_l), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.where(np.outer(d_l, d_l) > 0, cov_l / np.outer(d_l, d_l), 0.0)
    corr = np.nan_to_num(corr) + np.diag(np.where(d_l > 0, 0.0, 1.0))
    d = sigma / TO_DISPLAY
    return np.asarray(corr * np.outer(d, d) if np.all(np.isfinite(d)) else np.diag(d**2), dtype=np.float64)


def _uncertainty(feats: list[PairFeatures], tau: F64, opts: OptimOptions, gmm: GmmOptions, prior: Prior | None,
                 trust: TrustOptions, solving: Prior | None) -> Uncertainty:
    """The data's (and the declared ``prior``'s) uncertainty at ``tau``; the jackknife's left-out solves use the
    prior the solve used (``solving``), so they vary as the solve itself would."""
    model = level_model(feats, opts, gmm, len(opts.sigmas_deg) - 1)
    frozen = model.freeze(tau)
    by_ring = all(f.points.ring is not None for f in feats)
    clusters = clusters_at(model, tau, opts.cluster_cell_deg, by_ring)
    grads = local_gradient(model, frozen, tau, np.zeros(6), clusters)
    hessians = hessian(model, frozen, tau, hessian_steps(feats, gmm), clusters)
    free = np.array([True] * 3 + [not (prior is not None and prior.fix_translation)] * 3)
    h = symmetric(hessians.sum(axis=0))[np.ix_(free, free)]
    b = scatter(clusters.per_cell(grads)[:, free])
    prior_info = (prior.information() if prior is not None else np.zeros((6, 6)))[np.ix_(free, free)]
    solving_info = (solving.information() if solving is not None else np.zeros((6, 6)))[np.ix_(free, free)]
    known = bool(np.all(np.isfinite(b)))
    kappa = nll_scale(h, b) if known else 1.0
    # A minimum of what the solve minimised; a direction only the guess's prior holds is reported below as
    # the data leave it (a large sigma), not as a failed solve.
    _, is_min = positive_part(h + kappa * solving_info)
    # The kernel's width at the finest level, where a Gaussian's curvature changes sign, ends any quadratic
    # model of the cost; a translation moves edges at the typical range by dt / range radians.
    radius = float(np.radians(opts.sigmas_deg[-1]))
    scale = np.array([1.0] * 3 + [1.0 / typical_range_m(feats)] * 3)
    cov_l = np.zeros((6, 6))
    cov_l[np.ix_(free, free)] = sandwich(h, b, prior_info, radius / scale[free]) if known \
        else np.diag(np.full(int(free.sum()), np.inf))
    n_places = int(places(feats).max()) + 1
    groups, n_groups = _groups(clusters, n_places, trust)
    extra = np.zeros((6, 6))
    extra[np.ix_(free, free)] = kappa * solving_info
    jack, unheld = _jackknife(grads, hessians, extra, groups, n_groups, free, scale, radius)
    by_place = n_places >= trust.jackknife_min_pairs  # else the groups are image cells, not places
    ring_groups = _ring_groups(clusters, trust)
    jack_rings = None if ring_groups is None else \
        _jackknife(grads, hessians, extra, *ring_groups, free, scale, radius)[0]
    laplace = sigmas_display(cov_l)
    jack_sigma = None if jack is None else sigmas_display(jack)
    ring_sigma = None if jack_rings is None else sigmas_display(jack_rings)
    sigma = np.maximum.reduce([s for s in (laplace, jack_sigma, ring_sigma) if s is not None])
    if not is_min:
        sigma = np.where(free, np.inf, 0.0)
    cov = combine_covariance(cov_l, sigma)
    weakest = weakest_direction(cov, trust.tolerance_display) if np.all(np.isfinite(cov)) else \
        "the solution is not a minimum of the cost: no axis is known"
    share = matched_points(model, frozen, tau) / max(_in_image_count(model.feats, tau, model.gmm.use_folds), 1)
    return Uncertainty(cov, sigma, laplace, jack_sigma, n_groups if jack is not None else 0, weakest, is_min,
                       kappa, share, unheld if by_place else (), ring_sigma,
                       ring_groups[1] if ring_groups is not None and jack_rings is not None else 0)


def restarts_elsewhere(unc: Uncertainty, restarts: list[Restart], trust: TrustOptions) -> str | None:
    """A reason to fail when most restarts ended at other, clearly higher minima instead of coming back to the
    solution (every axis within its tolerance or 3 sigma; a tie elsewhere is ambiguity, judged apart). The last
    levels' basin around a determined pose is wider than the restart offsets (simulated sets: every restart
    back within 0.01 of that bound), so minima this close mean the cost is rugged here and the solution is one
    of several (docs/trust.md). None otherwise."""
    local = [r for r in restarts if r.origin in LOCAL_ORIGINS]
    bound = np.maximum(trust.tolerance_display, 3.0 * unc.sigma)
    away = [r for r in local if r.delta_nll >= trust.ambiguity_nll and np.any(np.abs(r.offset) > bound)]
    if not local or len(away) <= (1.0 - trust.min_returned_share) * len(local):
        return None
    return (f"{len(local) - len(away)} of {len(local)} restarts came back to the solution; the others ended at "
            f"other minima (delta NLL {', '.join(f'{r.delta_nll:.1f}' for r in away)}): the cost has several "
            "minima within the restart offsets")


def moved_from(starts: tuple[F64, ...], tau: F64) -> tuple[float | None, float | None]:
    """How far the solution ``tau`` (6,) ended from the nearest of ``starts``: rotation (deg) and translation (m),
    each over the nearest start by that measure; None, None without starts."""
    moved_deg = min((rotation_angle_deg(so3_exp(s[:3]), so3_exp(tau[:3])) for s in starts), default=None)
    moved_m = min((float(np.linalg.norm(s[3:] - tau[3:])) for s in starts), default=None)
    return moved_deg, moved_m


def _moved_far(moved_m: float | None, trust: TrustOptions) -> Verdict | None:
    """Failed when the translation ended metres from every start; None otherwise."""
    if moved_m is None or moved_m <= trust.max_move_m:
        return None
    return Verdict(Status.FAILED, AXES, (
        f"the translation ended {moved_m:.2f} m from its start, more than {trust.max_move_m:g} m: no rig's lever "
        "arm is that far from its guess; check the lever arm given (the prior's xyz_m is in metres, not cm)",))


def verdict_of(unc: Uncertainty, restarts: list[Restart], trust: TrustOptions, *, moved_deg: float | None = None,
               moved_m: float | None = None, places: int | None = None,
               evidence: Evidence | None = None) -> Verdict:
    """The verdict of ``unc`` and the ``restarts`` (docs/trust.md), with the ``evidence`` of the solve around
    them (``moved_deg``, ``moved_m`` and ``places`` fill it when it is not given)."""
    ev = evidence or Evidence(moved_deg, moved_m, places)
    verdict = _verdict(unc, restarts, trust, ev.moved_deg, ev.moved_m)
    disagree = _disagreements(ev, trust) + _disputed(unc, trust)
    if verdict.status is Status.FAILED:
        return Verdict(Status.FAILED, verdict.weak_axes, (*verdict.reasons, *(r for _, r in disagree)), ev.fixed)
    nothing = _vouches_for_nothing(ev, trust)
    if nothing is not None:
        return Verdict(Status.WEAK, AXES, (*verdict.reasons, *(r for _, r in disagree), nothing), ev.fixed)
    weak, reasons = set(verdict.weak_axes), list(verdict.reasons)
    for axes, reason in disagree:
        weak.update(axes)
        reasons.append(reason)
    weak -= set(ev.fixed)
    if ev.fixed:
        reasons.append(f"{', '.join(ev.fixed)}: held at the values given, not checked")
    status = Status.WEAK if weak else verdict.status
    if status is Status.TRUSTED:
        return Verdict(status, (), tuple(reasons), ev.fixed)
    return Verdict(Status.WEAK, tuple(a for a in AXES if a in weak), tuple(reasons), ev.fixed)


def _disagreements(ev: Evidence, trust: TrustOptions) -> list[tuple[tuple[str, ...], str]]:
    """The axes whose result lies beyond ``trust.prior_max_z`` of the prior's sigmas from the values given, with
    why, in every verdict: a lever arm typed in the wrong unit is said whatever else the result is."""
    out: list[tuple[tuple[str, ...], str]] = []
    for axes, z, given in ((AXES[:3], ev.prior_z[0], "the rotation prior"), (AXES[3:], ev.prior_z[1],
                                                                              "the lever arm given")):
        if z is not None and z > trust.prior_max_z:
            out.append((axes, f"{', '.join(axes)}: the result lies {z:.0f} sigma from {given}: the data disagree "
                              "with it; check the values given and their unit"))
    return out


def _vouches_for_nothing(ev: Evidence, trust: TrustOptions) -> str | None:
    """Why no axis can be vouched for (pairs of one place; held values the data disagree with), or None."""
    if ev.places is not None and ev.places < trust.min_places:
        where = "one place" if ev.places == 1 else f"{ev.places} places"
        return (f"every pair was taken at {where}: the sigmas come from one scene seen alike and cannot be checked "
                "across places, so no axis is vouched for")
    if ev.fixed_worse_nll is not None and ev.fixed_worse_nll > trust.fixed_worse_nll:
        return (f"holding {', '.join(ev.fixed)} at the values given fits clearly worse than letting them free "
                f"(delta NLL {ev.fixed_worse_nll:.0f}): the values given disagree with the data; check them and their "
                "unit")
    return None


def _verdict(unc: Uncertainty, restarts: list[Restart], trust: TrustOptions, moved_deg: float | None,
             moved_m: float | None) -> Verdict:
    tol = trust.tolerance_display
    reasons: list[str] = []
    weak = set()
    if not unc.is_minimum:
        return Verdict(Status.FAILED, AXES, ("the solution is not a minimum of the finest-level cost",))
    if (far_verdict := _moved_far(moved_m, trust)) is not None:
        return far_verdict
    if moved_deg is not None and moved_deg > trust.max_move_deg:
        # Local evidence (sigmas, restarts) describes whatever minimum the solve reached; one this far from
        # every start is another alignment of the edges, or the start was that far off: neither is checked.
        return Verdict(Status.FAILED, AXES, (
            f"the solve ended {moved_deg:.1f} deg from its start, more than {trust.max_move_deg:g} deg: it ran "
            "to another alignment of the edges, or the start was that far off; the sigmas describe that "
            "alignment, not the distance to the truth",))
    over = trust.sigma_factor * unc.sigma > tol
    for k in np.flatnonzero(over):
        weak.add(AXES[k])
        unit = "°" if k < 3 else " cm"
        reasons.append(f"{AXES[k]} known to ±{trust.sigma_factor * unc.sigma[k]:.2f}{unit} (needs "
                       f"±{tol[k]:.2f}{unit})")
    ambiguous_far = False
    for i, r in enumerate(restarts):
        if r.delta_nll >= trust.ambiguity_nll:
            continue
        moved = np.abs(r.offset) > tol
        if moved.any():
            names = [AXES[k] for k in np.flatnonzero(moved)]
            weak.update(names)
            where = ", ".join(f"{AXES[k]} {r.offset[k]:+.3g}" for k in np.flatnonzero(moved))
            reasons.append(f"{r.origin} {i + 1} ended {where} away at a cost the data cannot tell apart "
                           f"(delta NLL {r.delta_nll:.2f})")
            ambiguous_far |= bool((np.abs(r.offset) > trust.failed_tolerances * tol).any())
    away = restarts_elsewhere(unc, restarts, trust)
    if away is not None:
        reasons.append(away)
        return Verdict(Status.FAILED, AXES, tuple(reasons))
    far = trust.sigma_factor * unc.sigma > trust.failed_tolerances * tol
    if ambiguous_far or int(far.sum()) >= 3:
        reasons.append("the pose is not determined: several axes are off by more than "
                       f"{trust.failed_tolerances:g} tolerances")
        return Verdict(Status.FAILED, tuple(a for a in AXES if a in weak), tuple(reasons))
    if len(weak) == len(AXES):  # `weak` vouches for the axes it does not name; here it would name none
        reasons.append("no axis is known to its tolerance: no part of this result can be used")
        return Verdict(Status.FAILED, AXES, tuple(reasons))
    if weak:
        return Verdict(Status.WEAK, tuple(a for a in AXES if a in weak), tuple(reasons))
    local = sum(r.origin in LOCAL_ORIGINS for r in restarts)  # the search's other starts need not agree
    return Verdict(Status.TRUSTED, (), (f"every axis within tolerance at {trust.sigma_factor:g} sigma; "
                                        f"{local} restarts agree",))


def assess(feats: list[PairFeatures], result: OptimResult, opts: OptimOptions, gmm: GmmOptions, *,
           prior: Prior | None, trust: TrustOptions, alternatives: tuple[OptimResult, ...] = (),
           solving: Prior | None = None, executor: Executor | None = None,
           starts: tuple[F64, ...] = (), on_progress: Progress | None = None) -> Assessment:
    """Restarts, uncertainty and verdict of ``result`` (the coarse-to-fine solution on ``feats``).
    ``alternatives``: full solves from other starts (the global search's runners-up); they count as
    restarts, so one that ends lower becomes the solution and one that ends elsewhere as low is ambiguity.
    ``prior``: the declared prior, part of the reported uncertainty; ``solving`` (default ``prior``): the prior
    the solve used (:func:`calib.pipeline.solve_prior`), with which the restarts run. ``executor``: the
    application's process pool, whose worker takes restarts beside this process (same result as without it;
    this process works out the uncertainty while the worker ends its last one). ``starts``: the
    poses (6,) tau the solves started from (the initial guess, the search's runners-up); the solution's
    rotation from the nearest one is reported, and beyond ``trust.max_move_deg`` fails the result; so does a
    translation beyond ``trust.max_move_m`` from the nearest start. ``on_progress(done, total)``: the restarts."""
    solving = prior if solving is None else solving
    # The restarts probe the basin of the lowest full solve: a search runner-up that ends lower than the
    # search's best start is the solution, and restarts around the start's would only find that start's basin.
    first = min([result, *alternatives], key=lambda r: r.final_cost)
    early: list[Uncertainty] = []  # the solution's, computed while the worker ends its last restart

    def uncertainty_early() -> None:
        early.append(_uncertainty(feats, first.tau, opts, gmm, prior, trust, solving))

    best, runs = _run_restarts(feats, first, opts, gmm, solving, trust, executor, uncertainty_early, on_progress)
    unc = early[0] if early and best is first else _uncertainty(feats, best.tau, opts, gmm, prior, trust, solving)
    searched = [(r, "search start" if r is result else "search runner-up")
                for r in [result, *alternatives] if r is not first]
    solves = [(first, "solution"), *((r, "restart") for r in runs), *searched]
    restarts = tuple(
        Restart(xi_of(best.tau, r.tau) * TO_DISPLAY, (r.final_cost - best.final_cost) / unc.kappa, origin)
        for r, origin in solves if r is not best
    )
    moved, moved_m = moved_from(starts, best.tau)
    unc = with_elevation(with_intrinsics(unc, best.tau, trust), trust)
    held = prior is not None and prior.fix_translation
    worse = _fixed_worse(feats, best, opts, gmm, solving or Prior(), trust, unc.kappa) if held else None
    evidence = Evidence(moved, moved_m, len(np.unique(places(feats))),
                        prior.distance(best.tau) if prior is not None else (None, None),
                        AXES[3:] if held else (), worse)
    return Assessment(best.tau, best, unc, restarts, verdict_of(unc, list(restarts), trust, evidence=evidence),
                      moved, moved_m, evidence)
