"""Coarse-to-fine gradient descent with Wolfe step sizes (paper section 6-7, eqs. 24-26, Algorithm 1).

Per level (one sigma_in): freeze sigma_i and |Omega_i| at the iterate, step along the (optionally
preconditioned) negative gradient with a step that satisfies the Wolfe conditions (eq. 25 sufficient
decrease, c1 = 1e-4; eq. 26 curvature, c2 = 0.9) on the frozen model, refreeze, repeat. A level stops when
the cost changed by less than ``tol_rel_cost`` for ``patience`` iterations in a row, when the step moved
less than ``tol_step`` (rad and m), or after ``max_iter`` iterations.

Preconditioning (default on; the paper uses plain gradient descent): one pixel of image motion costs
1/ppr rad of rotation but r/ppr m of translation for an edge at range r, so plain steepest descent crawls
along translation. Scaling the translation components of the direction by r_typ^2 (r_typ = the harmonic
mean range of the edge points) makes one step move rotation and translation by comparable image amounts.

Quasi-Newton directions (default on, ``quasi_newton``; docs/method.md item 15): after the first step of a
level the direction is -H g with H the BFGS estimate of the inverse Hessian, started from the
preconditioner scaled to the measured curvature, and the line search tries the full step first. The same
Wolfe conditions accept the step, and the minimum is the same; it takes fewer evaluations.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from calib.errors import CalibError
from calib.gmm import CostGrad, Evaluator, Frozen, GmmOptions, PairFeatures, cost_and_gradient, freeze_all
from calib.handed import collect, hand
from calib.prior import Prior
from calib.uncertainty import LevelModel, clusters_at, local_gradient, nll_scale, scatter

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class OptimOptions:
    """``sigmas_deg``: sigma_in of each level as an angle at 1 m (paper: 15, 10, 5 px of a 1024-wide
    panorama = 5.27, 3.52, 1.76 deg; rigd adds a 10.5 deg level in front, see docs/method.md)."""

    sigmas_deg: tuple[float, ...] = (10.5, 5.27, 3.52, 1.76)
    c1: float = 1e-4
    c2: float = 0.9
    max_iter: int = 100
    max_line_search: int = 30
    tol_rel_cost: float = 1e-5
    tol_step: float = 1e-6
    patience: int = 3
    # A level before the finest stops once two steps in a row moved edges by less than this share of its
    # sigma: it only has to place the next, narrower level's start, which that level refines anyway.
    coarse_step_share: float = 0.03
    precondition: bool = True
    rotation_only_levels: int = 1  # the first level(s) move rotation only (translation held)
    fold_levels: int = 2  # fold edge points take part in the first this-many levels only
    alternative_schedules: int = 1  # also run without the first 1..k levels; keep the lowest final cost
    # Also run only the last this-many levels from the start (0: not): where the start already lies in the
    # finest cost's deepest basin, a coarse level can carry it out (docs/method.md item 11).
    tail_from_start: int = 2
    numerical_gradient: bool = False
    cluster_cell_deg: float = 5.0  # edge points in one angular image cell of one pair share their errors
    quasi_newton: bool = True  # BFGS directions instead of (preconditioned) steepest descent


@dataclass(frozen=True)
class LevelTrace:
    sigma_in_deg: float
    iterations: int
    converged: bool
    costs: tuple[float, ...]
    tau: F64
    kappa: float = 1.0  # the weight of the prior's NLL in this level's cost (its scale in NLL units)


@dataclass(frozen=True)
class OptimResult:
    tau: F64
    levels: tuple[LevelTrace, ...]
    converged: bool
    final_cost: float


@dataclass
class _Problem:
    feats: list[PairFeatures]
    gmm: GmmOptions
    sigma_in_px: list[float]
    numerical: bool
    prior: Prior | None = None
    kappa: float = 1.0  # the GMM cost's scale in NLL units: the prior's weight
    frozen: list[Frozen] = field(default_factory=list)

    def refreeze(self, tau: F64) -> None:
        self.frozen = freeze_all(self.feats, tau, self.sigma_in_px, self.gmm)

    def evaluate(self, tau: F64) -> CostGrad:
        cg = self._evaluate_gmm(tau)
        if self.prior is None or not self.prior.active:
            return cg
        nll, grad = self.prior.nll_and_gradient(tau)  # the MAP term
        return CostGrad(cg.cost + self.kappa * nll, cg.gradient + self.kappa * grad, cg.n_active)

    def _evaluate_gmm(self, tau: F64) -> CostGrad:
        cg = cost_and_gradient(self.feats, self.frozen, tau, self.sigma_in_px, self.gmm)
        if not self.numerical:
            return cg
        grad = np.zeros(6)
        for k in range(6):  # central differences of the frozen model (the paper's numerical ablation)
            h = 1e-6 if k < 3 else 1e-5
            e = np.zeros(6)
            e[k] = h
            plus = cost_and_gradient(self.feats, self.frozen, tau + e, self.sigma_in_px, self.gmm).cost
            minus = cost_and_gradient(self.feats, self.frozen, tau - e, self.sigma_in_px, self.gmm).cost
            grad[k] = (plus - minus) / (2 * h)
        return CostGrad(cg.cost, grad, cg.n_active)


def wolfe_step(
    evaluate: Callable[[F64], CostGrad], tau: F64, here: CostGrad, direction: F64, alpha0: float, opts: OptimOptions,
    alpha_max: float = np.inf,
) -> tuple[float, CostGrad] | None:
    """A step alpha along ``direction`` satisfying eqs. 25-26 (bracketing and bisection), or None. No step
    longer than ``alpha_max`` is tried; there the sufficient decrease alone accepts it."""
    slope0 = float(here.gradient @ direction)
    if slope0 >= 0:
        return None
    lo, hi, alpha = 0.0, np.inf, min(alpha0, alpha_max)
    armijo: tuple[float, CostGrad] | None = None
    for _ in range(opts.max_line_search):
        trial = evaluate(tau + alpha * direction)
        if trial.cost > here.cost + opts.c1 * alpha * slope0 or trial.n_active == 0:  # eq. 25 fails
            hi = alpha
        elif float(trial.gradient @ direction) < opts.c2 * slope0:  # eq. 26 fails: step too short
            if alpha >= alpha_max:
                return alpha, trial
            lo = alpha
            armijo = (alpha, trial)
        else:
            return alpha, trial
        alpha = 0.5 * (lo + hi) if np.isfinite(hi) else min(2.0 * alpha, alpha_max)
        if (hi - lo) * float(np.abs(direction).max()) < opts.tol_step:
            break  # the bracket is narrower than a converged level's step: more bisection cannot matter
    # The interval shrank below what the interpolated fields resolve: keep the best decreasing step.
    return armijo


def typical_range_m(feats: list[PairFeatures]) -> float:
    """Harmonic mean range of the edge points: image motion per metre of translation is the mean of 1/r."""
    ranges = np.concatenate([np.linalg.norm(f.points.points_lidar, axis=1) for f in feats])
    return float(1.0 / np.mean(1.0 / np.maximum(ranges, 0.5))) if ranges.size else 1.0


def _run_level(
    prob: _Problem, tau: F64, opts: OptimOptions, scale: F64, sigma_rad: float, range_m: float,
    on_iter: Callable[[int, float], None] | None, finest: bool = True,
) -> tuple[F64, LevelTrace]:
    """One level from ``tau``; ``range_m`` the edge points' typical range, which turns a translation step into
    the angle it moves edges by. A level that is not the ``finest`` also stops at ``opts.coarse_step_share``."""
    prob.refreeze(tau)
    here = prob.evaluate(tau)
    if here.n_active == 0:
        raise CalibError("no edge point projects near an edge pixel: the initial guess is too far off")
    costs = [here.cost]
    alpha_prev: float | None = None
    inverse: F64 | None = None  # quasi-Newton: the inverse-Hessian estimate (None until the first step)
    quiet = 0
    small = 0  # consecutive steps below the coarse levels' share of sigma
    coarse_rad = 0.0 if finest else opts.coarse_step_share * sigma_rad
    converged = False
    it = 0
    for it in range(1, opts.max_iter + 1):
        direction = -(inverse @ here.gradient if inverse is not None else scale * here.gradient)
        if inverse is not None and float(direction @ here.gradient) >= 0:  # lost its way: steepest again
            inverse, alpha_prev = None, None
            direction = -scale * here.gradient
        # Step length as an angle: rotation plus translation seen at the typical range. No step goes beyond
        # one sigma, where the Gaussians' local picture of the cost ends (a quasi-Newton step along a flat
        # direction would otherwise land in another basin).
        length = float(np.linalg.norm(direction[:3])) + float(np.linalg.norm(direction[3:])) / range_m
        alpha_max = sigma_rad / max(length, 1e-12)
        if alpha_prev is None:  # first step: move about half a sigma
            alpha0 = 0.5 * alpha_max
        else:
            alpha0 = 1.0 if inverse is not None else 2.0 * alpha_prev
        found = wolfe_step(prob.evaluate, tau, here, direction, alpha0, opts, alpha_max)
        if found is None:
            converged = True  # no descent step exists on the frozen model: a (local) minimum
            break
        alpha_prev, _ = found
        step = alpha_prev * direction
        tau = tau + step
        prob.refreeze(tau)
        new = prob.evaluate(tau)
        if opts.quasi_newton:
            inverse = _bfgs_update(inverse, scale, step, new.gradient - here.gradient)
        rel = abs(new.cost - here.cost) / max(abs(here.cost), 1e-12)
        here = new
        costs.append(here.cost)
        if on_iter is not None:
            on_iter(it, here.cost)
        quiet = quiet + 1 if rel < opts.tol_rel_cost else 0
        small = small + 1 if alpha_prev * length < coarse_rad else 0  # the step's angle, as alpha_max measures it
        if quiet >= opts.patience or small >= 2 or (np.abs(step) < opts.tol_step).all():
            converged = True
            break
    return tau, LevelTrace(float(np.degrees(sigma_rad)), it, converged, tuple(costs), tau.copy())


def _bfgs_update(inverse: F64 | None, scale: F64, s: F64, y: F64) -> F64 | None:
    """BFGS update of the inverse-Hessian estimate with step ``s`` and gradient change ``y`` (Nocedal & Wright
    eq. 6.17); the first one starts from the preconditioner scaled to the measured curvature (eq. 6.20).
    Held axes (``scale`` 0) stay out of it. None (steepest descent) while no positive curvature is seen."""
    sy = float(s @ y)
    if sy <= 1e-12 * float(np.linalg.norm(s) * np.linalg.norm(y)):
        return inverse
    if inverse is None:
        inverse = np.diag(scale) * (sy / float(y @ (scale * y)))
    rho = 1.0 / sy
    left = np.eye(len(s)) - rho * np.outer(s, y)
    return np.asarray(left @ inverse @ left.T + rho * np.outer(s, s), dtype=np.float64)


def _level_gmm(gmm: GmmOptions, sigma_deg: float) -> GmmOptions:
    """Resolve ``Evaluator.AUTO`` for one level: the fields where sigma is wide, exact sums where it is
    narrow (few pixels per point, and the exact model's gradient lets the line search go further)."""
    if gmm.evaluator is not Evaluator.AUTO:
        return gmm
    return replace(gmm, evaluator=Evaluator.FIELD if sigma_deg >= gmm.exact_below_deg else Evaluator.EXACT)


def level_model(feats: list[PairFeatures], opts: OptimOptions, gmm: GmmOptions, level: int) -> LevelModel:
    """The cost of level ``level`` of ``opts.sigmas_deg`` (its evaluator, sigma cap and edge kinds)."""
    sigma_deg = opts.sigmas_deg[level]
    level_gmm = _level_gmm(gmm, sigma_deg)
    if level == len(opts.sigmas_deg) - 1:  # the finest level keeps eq. 23's full 1/r
        level_gmm = replace(level_gmm, sigma_range_cap_m=1e9)
    if level >= opts.fold_levels:
        level_gmm = replace(level_gmm, use_folds=False)
    sigma_rad = float(np.radians(sigma_deg))
    return LevelModel(tuple(feats), tuple(sigma_rad * f.camera.pixels_per_radian for f in feats), level_gmm)


def hessian_steps(feats: list[PairFeatures], gmm: GmmOptions) -> F64:
    """Finite-difference steps (6,) in local coordinates: a twentieth of the narrowest Gaussian, as an angle
    and as the translation that moves an edge at the typical range by that angle."""
    h_rot = 0.05 * max(float(np.radians(gmm.sigma_floor_deg)),
                       gmm.sigma_floor_px / min(f.camera.pixels_per_radian for f in feats))
    return np.array([h_rot] * 3 + [h_rot * typical_range_m(feats)] * 3)


def estimate_kappa(model: LevelModel, tau: F64, steps: F64, cell_deg: float) -> float:
    """The level cost's scale in NLL units at ``tau`` (:func:`calib.uncertainty.nll_scale`). Only the Hessian's
    diagonal enters, taken by one-sided differences of the gradient (7 evaluations, not the 13 of the full
    central-difference Hessian: the prior's weight needs its scale, not its last percent)."""
    frozen = model.freeze(tau)
    clusters = clusters_at(model, tau, cell_deg)
    per_cluster = local_gradient(model, frozen, tau, np.zeros(6), clusters)
    b = scatter(per_cluster)
    if not np.all(np.isfinite(b)):
        return 1.0
    g0 = per_cluster.sum(axis=0)
    diagonal = np.zeros(6)
    for k in range(6):
        e = np.zeros(6)
        e[k] = steps[k]
        diagonal[k] = (local_gradient(model, frozen, tau, e, clusters).sum(axis=0)[k] - g0[k]) / steps[k]
    return nll_scale(np.diag(diagonal), b)


def tail_options(opts: OptimOptions, k: int) -> OptimOptions:
    """``opts`` reduced to its last ``k`` levels, each level keeping the edge kinds it had."""
    drop = len(opts.sigmas_deg) - k
    return replace(opts, sigmas_deg=opts.sigmas_deg[drop:],
                   rotation_only_levels=max(0, opts.rotation_only_levels - drop),
                   fold_levels=max(0, opts.fold_levels - drop), alternative_schedules=0)


def _coarse_to_fine(
    feats: list[PairFeatures], tau0: F64, opts: OptimOptions, gmm: GmmOptions,
    on_iter: Callable[[int, int, float], None] | None, prior: Prior | None = None,
    kappas: tuple[float | None, ...] | None = None,
) -> OptimResult:
    """Algorithm 1: coarse-to-fine over ``opts.sigmas_deg`` (with the prior's MAP term if given, weighted per
    level by ``kappas`` if given, else by the level cost's scale estimated where the level starts)."""
    tau = np.asarray(tau0, dtype=np.float64).copy()
    range_m = typical_range_m(feats)
    r_typ = range_m if opts.precondition else 1.0
    scale = np.array([1.0, 1.0, 1.0, r_typ**2, r_typ**2, r_typ**2])
    fixed_t = prior is not None and prior.fix_translation
    steps = hessian_steps(feats, gmm) if prior is not None and prior.active else None
    levels = []
    for level, sigma_deg in enumerate(opts.sigmas_deg):
        sigma_rad = float(np.radians(sigma_deg))
        model = level_model(feats, opts, gmm, level)
        given = None if kappas is None else kappas[level]
        moves_t = not fixed_t and level >= opts.rotation_only_levels
        # A prior on the lever arm alone weighs nothing on a level that holds the translation: skip its scale.
        weighs = prior is not None and (moves_t or prior.sigma_rot_rad is not None)
        if given is not None:
            kappa = given
        else:
            kappa = estimate_kappa(model, tau, steps, opts.cluster_cell_deg) if steps is not None and weighs else 1.0
        prob = _Problem(feats, model.gmm, list(model.sigma_in_px), opts.numerical_gradient, prior, kappa)
        cb = (lambda i, c, lv=level: on_iter(lv, i, c)) if on_iter else None
        level_scale = scale * ([1.0] * 3 + [1.0 if moves_t else 0.0] * 3)
        finest = level == len(opts.sigmas_deg) - 1
        tau, trace = _run_level(prob, tau, opts, level_scale, sigma_rad, range_m, cb, finest)
        levels.append(replace(trace, kappa=kappa))
    return OptimResult(tau, tuple(levels), all(t.converged for t in levels), levels[-1].costs[-1])


def optimise(
    feats: list[PairFeatures],
    tau0: F64,
    opts: OptimOptions,
    gmm: GmmOptions,
    *,
    on_iter: Callable[[int, int, float], None] | None = None,
    prior: Prior | None = None,
    executor: Executor | None = None,
    kappas: tuple[float | None, ...] | None = None,
) -> OptimResult:
    """Coarse-to-fine from ``tau0``, also run with the first ``opts.alternative_schedules`` levels left out;
    the run ending at the lowest finest-level cost wins. ``on_iter(level, iteration, cost)``. ``kappas``
    (one per level, None to estimate): the prior's weight per level, to minimise the objective an earlier
    solve minimised (restarts); by default each level estimates it where it starts.

    A wide first level widens the basin on a 12-pair set (outdoor: 5/8 -> 10/10 converged from +-5 deg /
    +-10 cm) but on a small set (2 pairs) it can also pull a good start into a far minimum; every schedule
    ends on the same finest level, whose cost decides, so the extra run can only lower the objective.

    ``executor`` (the application's process pool): the other schedules run there while this process runs
    the main one, which then takes back those no worker has started (:mod:`calib.handed`); the result is the
    same as without it (each solve is deterministic, the fields' values do not depend on what was sampled
    before).
    """
    shorter = [replace(opts, sigmas_deg=opts.sigmas_deg[k:], rotation_only_levels=0)
               for k in range(1, min(opts.alternative_schedules, len(opts.sigmas_deg) - 1) + 1)]
    if 0 < opts.tail_from_start < len(opts.sigmas_deg) and opts.alternative_schedules > 0:
        shorter.append(tail_options(opts, opts.tail_from_start))
    cut = [None if kappas is None else kappas[len(opts.sigmas_deg) - len(s.sigmas_deg):] for s in shorter]
    runs = list(zip(shorter, cut, strict=True))
    handed = [hand(executor, _coarse_to_fine, feats, tau0, s, gmm, None, prior, k) for s, k in runs]
    best = _coarse_to_fine(feats, tau0, opts, gmm, on_iter, prior, kappas)
    for other in collect(handed):
        if other.final_cost < best.final_cost:
            best = other
    return best

