"""Trust assessment of an NID solution: the GMM's restarts, per-axis sigma and verdict (calib.assess) on the
photometric cost (docs/trust.md, "A photometric solution").

The cost is koide3's NID (calib.photometric): per pair a soft 16x16 joint histogram of LiDAR reflectivity and
grey level, ``NID = (H(X, Y) - MI) / H(X, Y)``, the mean over pairs. It is not a sum over points, so the
GMM's per-cluster gradients have no direct counterpart; what the sandwich needs is each cluster's part of
the gradient, and for a function of a histogram that is the cluster's *influence*: the gradient minus the
gradient without the cluster (for a sum over clusters exactly its terms; for a smooth function of the
histogram the first-order part). The soft histogram is additive over samples, so every cluster's histogram
is formed once per pose and "without the cluster" is a subtraction.

1. **Restarts.** The schedule's last ``trust.restart_levels`` levels rerun from ``trust.restarts`` poses
   around the solution (the GMM's draws: +-2 deg, +-5 cm, seeded), every one on the points the solve minimised
   (the random subset in view at its start), and compared by the finest level's cost on those points: scored on
   points they alone were fitted to, restarts would end lower for that alone. One that ends lower by more than a
   statistical tie, within their reach, is the solution.
2. **Uncertainty** at the solution, on the finest level (no blur): ``H`` the cost's Hessian by central second
   differences in local coordinates (steps of ``step_px`` pixels at the image, translation at the points'
   typical range), ``B`` the scatter of the clusters' influences on the gradient (clusters: 5 deg image cells
   of each pair, as the GMM's), ``kappa`` the cost's NLL scale (median ``B_kk / H_kk``), the sandwich
   ``H^-1 B H^-1`` with the information floored over +- the reach (the schedule's widest blur), and a
   delete-a-group jackknife (each pair left out, or with fewer than 4 pairs 8 random groups of cells), each
   left-out solve one bounded Newton step of the left-out cost with its own Hessian and gradient, and the
   GMM's jackknife over rings the same way (each ring left out in every pair: each laser has its own
   reflectivity response and elevation, shared by every place, so leaving out places cannot see them).
3. **A second method.** Where the GMM's edges were refined from the NID solution (calib.methods), how far they
   moved enters the sigma (:func:`calib.assess.with_cross_check`): NID alone cannot see a bias the image's
   intensities share across places and rings (the camera's model, the reflectivity's response).
4. **Verdict**: :func:`calib.assess.verdict_of`, the GMM's rules unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from calib.assess import (
    Assessment,
    Evidence,
    Restart,
    TrustOptions,
    Uncertainty,
    combine_covariance,
    holding_groups,
    moved_from,
    trust_region_step,
    verdict_of,
    with_cross_check,
    with_elevation,
    with_intrinsics,
)
from calib.elevation import SLOPE_STEP_DEG, raise_elevation
from calib.errors import CalibError
from calib.gmm import transform_points
from calib.handed import Progress, collect, hand, shared_calls
from calib.optimize import LevelTrace, OptimResult
from calib.photometric import (
    LevelPair,
    PhotoCost,
    PhotoPair,
    PhotoParams,
    PhotoResult,
    labelled_histograms,
    level_pairs,
    optimise_photometric,
    point_subsets,
    project_level,
    sample,
    subset_rings,
)
from calib.uncertainty import (
    AXES,
    TO_DISPLAY,
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
I64 = NDArray[np.int64]


@dataclass(frozen=True)
class PhotoTrustOptions:
    """``step_px``: the finite-difference step of the Hessian, in pixels of image motion (rotation: step_px /
    pixels per radian; translation: that angle times the points' typical range). Below about 2 px the NID's
    second differences are dominated by its bilinear sampling (measured on ours_3: 1e-4 of noise against
    5e-4 of curvature at 1.5 px); at 3 px, a few per cent. ``cell_deg``: the clusters' angular image cells."""

    step_px: float = 3.0
    cell_deg: float = 5.0


@dataclass(frozen=True)
class _Stencil:
    """The cost around a pose: ``offsets`` (S,6) local coordinates, and at each, ``full`` (S,) the cost,
    ``groups`` (S,G) the cost with each jackknife group left out, ``rings`` (S,R) with each ring left out in
    every pair, ``clusters`` (S,C) with each cluster left out (only at the first 13 offsets: the centre and +-h
    per axis, the gradient's)."""

    offsets: F64
    full: F64
    groups: F64
    rings: F64
    clusters: F64


def _offsets(h: F64) -> F64:
    """(73,6) central-difference stencil: 0, +-h_k e_k (the gradient's 12), then +-h_j e_j +-h_k e_k (j < k)."""
    rows = [np.zeros(6)]
    for k in range(6):
        for s in (1.0, -1.0):
            e = np.zeros(6)
            e[k] = s * h[k]
            rows.append(e)
    for j in range(6):
        for k in range(j + 1, 6):
            for sj, sk in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                e = np.zeros(6)
                e[j], e[k] = sj * h[j], sk * h[k]
                rows.append(e)
    return np.array(rows)


def _samples(lp: LevelPair, tau: F64, labels: I64) -> tuple[NDArray[np.bool_], F64, F64]:
    """Which points are in view at ``tau`` and labelled (``labels`` (M,), -1: none), and their reflectivity and
    grey level (K,): what every histogram of the stencil at ``tau`` counts."""
    uv, inside = project_level(lp, tau)
    keep = inside & (labels >= 0)
    return keep, lp.reflectivity[keep], sample(lp.grey, lp.camera, uv[keep])


def _cluster_hists(lp: LevelPair, tau: F64, labels: I64, n_clusters: int, bins: int) -> F64:
    """(n_clusters, bins, bins) soft joint histograms (calib.photometric.labelled_histograms) of each
    cluster's samples at ``tau`` (``labels`` (M,) cluster of each point, -1: none)."""
    keep, refl, grey = _samples(lp, tau, labels)
    return labelled_histograms(refl, grey, labels[keep], n_clusters, bins)


def _entropies(p: F64) -> F64:
    """Entropy (nats) of each distribution of ``p`` (..., n), its last axis."""
    return np.asarray(-np.sum(np.where(p > 0, p * np.log(np.where(p > 0, p, 1.0)), 0.0), axis=-1), dtype=np.float64)


def _nids(joints: F64) -> F64:
    """:func:`calib.photometric.nid` of each histogram of ``joints`` (..., bins, bins) at once; 1 for an empty
    one (the stencil evaluates some 10^5 of them)."""
    total = joints.sum(axis=(-2, -1))
    filled = total > 1e-9
    p = joints / np.where(filled, total, 1.0)[..., None, None]
    hx, hy = _entropies(p.sum(axis=-1)), _entropies(p.sum(axis=-2))
    hxy = _entropies(p.reshape(*p.shape[:-2], -1))
    value = np.where(hxy > 0, (hxy - (hx + hy - hxy)) / np.where(hxy > 0, hxy, 1.0), 0.0)
    return np.where(filled, value, 1.0)


def _means_without(hists: F64, drops: F64) -> F64:
    """(G,) the NID cost (the mean over pairs) with ``drops[g, i]`` removed from pair i's histogram
    ``hists[i]`` (``hists`` (P,bins,bins), ``drops`` (G,P,bins,bins)); a pair left empty leaves the mean."""
    rest = hists[None] - drops
    filled = rest.sum(axis=(-2, -1)) > 1e-9
    count = filled.sum(axis=1)
    total = np.where(filled, _nids(rest), 0.0).sum(axis=1)
    return np.asarray(np.where(count > 0, total / np.maximum(count, 1), 1.0), dtype=np.float64)


def _mean_nid(hists: F64) -> float:
    """The NID cost of pairs' histograms ``hists`` (P,bins,bins): the mean over the pairs not empty."""
    return float(_means_without(hists, np.zeros_like(hists)[None])[0])


def _without_each_cluster(hists: F64, per: list[F64], cluster_pair: I64) -> F64:
    """(C,) the cost with each cluster left out (``per[i]`` (C,bins,bins) pair i's clusters' histograms): only
    the cluster's own pair changes, so the mean's sum and count adjust."""
    filled = hists.sum(axis=(-2, -1)) > 1e-9
    base = np.where(filled, _nids(hists), 0.0)
    out = np.ones(len(cluster_pair))
    for i in range(len(hists)):
        mine = np.flatnonzero(cluster_pair == i)
        rest = hists[i][None] - per[i][mine]
        kept = rest.sum(axis=(-2, -1)) > 1e-9
        total = float(base.sum() - base[i]) + np.where(kept, _nids(rest), 0.0)
        count = int(filled.sum()) - int(filled[i]) + kept
        out[mine] = np.where(count > 0, total / np.maximum(count, 1), 1.0)
    return out


def _stencil(lps: list[LevelPair], tau: F64, labels: list[I64], cluster_pair: I64, group_of: I64, n_groups: int,
             offsets: F64, bins: int, rings: tuple[list[I64], int] | None = None) -> _Stencil:
    """The cost at ``tau`` + each of ``offsets``, in full, without each jackknife group, without each ring
    (``rings``: each point's ring index (M,) per pair, and the number of rings), and (first 13 offsets) without
    each cluster (``cluster_pair`` (C,) the pair of each cluster; ``group_of`` (C,) its group)."""
    n_c = len(cluster_pair)
    n_r = 0 if rings is None else rings[1]
    member = (group_of[None, :] == np.arange(n_groups)[:, None]).astype(np.float64)  # (G, C)
    full = np.zeros(len(offsets))
    groups = np.zeros((len(offsets), n_groups))
    by_ring = np.zeros((len(offsets), n_r))
    clusters = np.zeros((13, n_c))
    for s, xi in enumerate(offsets):
        at = tau_at(tau, xi)
        seen = [_samples(lp, at, lab) for lp, lab in zip(lps, labels, strict=True)]
        per = [labelled_histograms(a, b, lab[keep], n_c, bins) for (keep, a, b), lab in zip(seen, labels, strict=True)]
        hists = np.stack([p.sum(axis=0) for p in per])
        full[s] = _mean_nid(hists)
        drops = np.stack([(member @ p.reshape(n_c, -1)).reshape(n_groups, bins, bins) for p in per], axis=1)
        groups[s] = _means_without(hists, drops)
        if rings is not None:  # the same samples, counted by ring (a ring label is -1 where its cluster's is)
            per_ring = [labelled_histograms(a, b, lab[keep], n_r, bins)
                        for (keep, a, b), lab in zip(seen, rings[0], strict=True)]
            by_ring[s] = _means_without(hists, np.stack(per_ring, axis=1))
        if s < 13:
            clusters[s] = _without_each_cluster(hists, per, cluster_pair)
    return _Stencil(offsets, full, groups, by_ring, clusters)


def _gradient(values: F64, h: F64) -> F64:
    """Central-difference gradient (..., 6) from the stencil's first 13 values (..., 13)."""
    return np.stack([(values[..., 1 + 2 * k] - values[..., 2 + 2 * k]) / (2 * h[k]) for k in range(6)], axis=-1)


def _hessian(values: F64, h: F64) -> F64:
    """Central second-difference Hessian (6,6) from the 73 stencil values."""
    out = np.zeros((6, 6))
    for k in range(6):
        out[k, k] = (values[1 + 2 * k] - 2 * values[0] + values[2 + 2 * k]) / h[k] ** 2
    i = 13
    for j in range(6):
        for k in range(j + 1, 6):
            pp, pm, mp, mm = values[i:i + 4]
            out[j, k] = out[k, j] = (pp - pm - mp + mm) / (4 * h[j] * h[k])
            i += 4
    return out


def _clusters(lps: list[LevelPair], tau: F64, cell_deg: float) -> tuple[list[I64], I64]:
    """Each point's cluster (the ``cell_deg`` angular image cell it projects into at ``tau``, per pair; -1 for
    points out of view), and (C,) the pair of each cluster."""
    labels, pair_of = [], []
    first = 0
    for i, lp in enumerate(lps):
        uv, inside = project_level(lp, tau)
        cell = np.floor(np.where(inside[:, None], uv, 0.0) / (np.radians(cell_deg) * lp.camera.pixels_per_radian))
        key = cell[:, 0].astype(np.int64) * 1_000_003 + cell[:, 1].astype(np.int64)
        uniq, inv = np.unique(key[inside], return_inverse=True)
        lab = np.full(len(uv), -1, np.int64)
        lab[inside] = np.asarray(inv, np.int64).reshape(-1) + first
        labels.append(lab)
        pair_of.append(np.full(len(uniq), i, np.int64))
        first += len(uniq)
    return labels, (np.concatenate(pair_of) if pair_of else np.zeros(0, np.int64))


def typical_range(lps: list[LevelPair], tau: F64) -> float:
    """Harmonic mean range (m) of the points in view at ``tau``: how far a translation's parallax is seen."""
    ranges = []
    for lp in lps:
        _, inside = project_level(lp, tau)
        ranges.append(np.linalg.norm(transform_points(tau, lp.points_lidar[inside])[0], axis=1))
    r = np.concatenate(ranges) if ranges else np.zeros(0)
    r = r[r > 0.1]
    return float(len(r) / np.sum(1.0 / r)) if r.size else 10.0


def _groups(cluster_pair: I64, n_pairs: int, trust: TrustOptions) -> tuple[I64, int, bool]:
    """The jackknife group of each cluster: its pair (``n_pairs`` >= trust.jackknife_min_pairs), else one of
    ``trust.jackknife_groups`` random groups of clusters (cells); and whether the groups are pairs."""
    if n_pairs >= trust.jackknife_min_pairs:
        return cluster_pair, n_pairs, True
    rng = np.random.default_rng(trust.seed)
    return rng.permutation(len(cluster_pair)) % trust.jackknife_groups, trust.jackknife_groups, False


def photo_uncertainty(pairs: list[PhotoPair], tau: F64, params: PhotoParams, trust: TrustOptions,
                      fixed_translation: bool = False, opts: PhotoTrustOptions | None = None) -> Uncertainty:
    """The per-axis uncertainty of the NID solution ``tau`` (module docstring, step 2), on the points in view at
    ``tau``. ``fixed_translation``: the translation was held (sigma 0)."""
    opts = opts or PhotoTrustOptions()
    if params.cost is not PhotoCost.NID:
        raise CalibError(f"the photometric assessment is defined for NID, not {params.cost.value}")
    lps = level_pairs(pairs, tau, params, len(params.blur_deg) - 1, point_subsets(pairs, tau, params))
    labels, cluster_pair = _clusters(lps, tau, opts.cell_deg)
    place = places(pairs)  # the jackknife leaves out places (a pair without one is a place of its own)
    groups, n_groups, by_pair = _groups(place[cluster_pair], int(place.max()) + 1, trust)
    ppr = float(np.median([lp.camera.pixels_per_radian for lp in lps]))
    r_typ = typical_range(lps, tau)
    h = np.array([opts.step_px / ppr] * 3 + [opts.step_px / ppr * r_typ] * 3)
    rings = _ring_labels(subset_rings(pairs, tau, params), labels, trust)
    st = _stencil(lps, tau, labels, cluster_pair, groups, n_groups, _offsets(h), params.n_bins, rings)
    free = np.array([True] * 3 + [not fixed_translation] * 3)
    hess = symmetric(_hessian(st.full, h))[np.ix_(free, free)]
    grad = _gradient(st.full[:13], h)[free]
    influence = grad[None, :] - _gradient(st.clusters.T, h)[:, free]  # (C, free): each cluster's part
    b = scatter(influence) if len(influence) > int(free.sum()) else np.full((int(free.sum()),) * 2, np.nan)
    known = bool(np.all(np.isfinite(b)))
    kappa = nll_scale(hess, b) if known else 1.0
    _, is_min = positive_part(hess)
    # Beyond the schedule's widest blur the level that shaped the basin no longer holds the pose.
    radius = float(np.radians(max(params.blur_deg)))
    scale = np.array([1.0] * 3 + [1.0 / r_typ] * 3)
    cov_l = np.zeros((6, 6))
    cov_l[np.ix_(free, free)] = sandwich(hess, b, np.zeros_like(hess), radius / scale[free]) if known \
        else np.diag(np.full(int(free.sum()), np.inf))
    present = [g for g in range(n_groups) if np.any(groups == g)]
    steps = _left_out_steps(st.groups[:, present], h, free, scale, radius)
    jack = held = None
    if len(steps) >= 3:
        jack = _jackknife_sigma(steps)
        held = holding_groups(steps, present, scale, radius) if by_pair else ()
    ring_sigma = None if rings is None else _jackknife_sigma(_left_out_steps(st.rings, h, free, scale, radius))
    laplace = sigmas_display(cov_l)
    sigma = np.maximum.reduce([s for s in (laplace, jack, ring_sigma) if s is not None])
    if not is_min:
        sigma = np.where(free, np.inf, 0.0)
    cov = combine_covariance(cov_l, sigma)
    weakest = weakest_direction(cov, trust.tolerance_display) if np.all(np.isfinite(cov)) else \
        "the solution is not a minimum of the cost: no axis is known"
    return Uncertainty(cov, sigma, laplace, jack, n_groups if jack is not None else 0, weakest, is_min, kappa,
                       _in_view_share(lps, tau), held or (), ring_sigma, 0 if rings is None else rings[1])


def _ring_labels(rings: list[I64] | None, labels: list[I64], trust: TrustOptions) -> tuple[list[I64], int] | None:
    """Each evaluated point's ring as an index into the rings in view at the solution (-1 for points out of
    view, as their ``labels``), and the number of those rings; None without rings or with fewer than
    ``trust.jackknife_min_rings``: the GMM's jackknife over rings (calib.assess), on the NID cost."""
    if rings is None:
        return None
    seen = np.unique(np.concatenate([r[lab >= 0] for r, lab in zip(rings, labels, strict=True)]))
    if len(seen) < trust.jackknife_min_rings:
        return None
    index = [np.where(lab >= 0, np.searchsorted(seen, r), -1).astype(np.int64) for r, lab in zip(rings, labels,
                                                                                                 strict=True)]
    return index, len(seen)


def _left_out_steps(values: F64, h: F64, free: NDArray[np.bool_], scale: F64, radius: float) -> F64:
    """(G,6) the bounded Newton step of each left-out cost (``values`` (73,G): the stencil without each group)
    from the solution: the delete-a-group solves of the jackknife."""
    steps = np.zeros((values.shape[1], 6))
    for g in range(values.shape[1]):
        h_rest = symmetric(_hessian(values[:, g], h))[np.ix_(free, free)]
        steps[g, free] = trust_region_step(h_rest, _gradient(values[:13, g], h)[free], scale[free], radius)
    return steps


def _jackknife_sigma(steps: F64) -> F64:
    """Per-axis delete-a-group jackknife sigma (6,) deg/cm of the left-out solves ``steps`` (G,6)."""
    centred = steps - steps.mean(axis=0)
    k = len(steps)
    return sigmas_display((k - 1.0) / k * centred.T @ centred)


def _in_view_share(lps: list[LevelPair], tau: F64) -> float:
    """Share of the evaluated points that land in their image at ``tau`` (the GMM reports the share of its edge
    points matched; for NID every point in view takes part)."""
    total = sum(len(lp.points_lidar) for lp in lps)
    return sum(int(np.count_nonzero(project_level(lp, tau)[1])) for lp in lps) / max(total, 1)


def as_optim(result: PhotoResult) -> OptimResult:
    """A photometric solve's trace as the GMM optimiser's (a level per blur; its ``sigma_in_deg`` is the blur)."""
    levels = tuple(LevelTrace(lv.blur_deg, lv.evaluations, True, lv.costs, lv.tau) for lv in result.levels)
    return OptimResult(result.tau, levels, True, result.final_cost)


def _tail(params: PhotoParams, levels: int) -> PhotoParams:
    """The schedule's last ``levels`` levels, every one moving the translation too."""
    k = min(levels, len(params.blur_deg))
    return replace(params, blur_deg=params.blur_deg[-k:], step_rot_deg=params.step_rot_deg[-k:],
                   step_trans_m=params.step_trans_m[-k:], rotation_only_levels=0)


def _finest_cost(pairs: list[PhotoPair], at: F64, params: PhotoParams) -> Callable[[F64], float]:
    """The finest level's cost on the points in view at ``at`` (the restarts' common ground)."""
    lps = level_pairs(pairs, at, params, len(params.blur_deg) - 1, point_subsets(pairs, at, params))
    return lambda tau: _mean_nid(np.stack([_cluster_hists(lp, tau, np.zeros(len(lp.points_lidar), np.int64), 1,
                                                          params.n_bins)[0] for lp in lps]))


def _restart(pairs: list[PhotoPair], start: F64, tail: PhotoParams, fixed_translation: bool,
             anchor: F64) -> PhotoResult:
    """One restart's solve (module level: a pool's worker runs it; deterministic, so wherever it runs)."""
    return optimise_photometric(pairs, start, tail, fixed_translation, subset_tau=anchor)


def _raised(pairs: list[PhotoPair], offset_deg: float) -> list[PhotoPair]:
    return [replace(p, points_lidar=raise_elevation(p.points_lidar, offset_deg)) for p in pairs]


def photo_elevation_slope(pairs: list[PhotoPair], result: PhotoResult, params: PhotoParams, fixed_translation: bool,
                          executor: Executor | None = None) -> F64:
    """(6,) the pose's change in local coordinates per degree of the LiDAR's elevation offset around the NID
    solution ``result``: the finest level refined from it with the points raised and lowered by SLOPE_STEP_DEG,
    as calib.elevation.elevation_slope does for the GMM, so a declared offset's sigma enters NID's as the GMM's."""
    anchor = np.asarray(result.tau, dtype=np.float64)
    finest = _tail(params, 1)
    low, high = collect([hand(executor, _restart, _raised(pairs, d), anchor, finest, fixed_translation, anchor)
                         for d in (-SLOPE_STEP_DEG, SLOPE_STEP_DEG)])
    return np.asarray((xi_of(anchor, high.tau) - xi_of(anchor, low.tau)) / (2 * SLOPE_STEP_DEG), dtype=np.float64)


def assess_photometric(pairs: list[PhotoPair], result: PhotoResult, params: PhotoParams, trust: TrustOptions, *,
                       fixed_translation: bool = False, starts: tuple[F64, ...] = (),
                       opts: PhotoTrustOptions | None = None, executor: Executor | None = None,
                       on_progress: Progress | None = None) -> Assessment:
    """Restarts, uncertainty and verdict of the NID solution ``result`` (module docstring). ``starts``: the
    poses (6,) tau the solve started from (the rotation and translation moved from the nearest are reported,
    and beyond ``trust.max_move_deg`` / ``max_move_m`` fail the result, as the GMM's). ``executor``: the
    application's pool, whose workers take restarts beside this process (calib.handed: the same result).
    ``on_progress(done, total)``: the restarts."""
    anchor = np.asarray(result.tau, dtype=np.float64)
    fitted = np.asarray(result.subset_tau, dtype=np.float64)  # the restarts minimise the solve's own points
    rng = np.random.default_rng(trust.seed)
    tail = _tail(params, trust.restart_levels)
    calls = []
    for _ in range(trust.restarts):
        offset = np.concatenate([np.radians(rng.uniform(-1, 1, 3) * trust.restart_rot_deg),
                                 np.zeros(3) if fixed_translation else rng.uniform(-1, 1, 3) * trust.restart_trans_m])
        calls.append((pairs, tau_at(anchor, offset), tail, fixed_translation, fitted))
    if fixed_translation:  # the same levels with the translation free: do the values held fit the data?
        calls.append((pairs, anchor, tail, False, fitted))
    cost = _finest_cost(pairs, fitted, params)
    done = shared_calls(executor, _restart, calls, on_progress=on_progress)
    loose = done.pop() if fixed_translation else None
    runs: list[tuple[PhotoResult, float]] = [(result, cost(anchor)), *((run, cost(run.tau)) for run in done)]
    best, best_cost, unc = _taken(pairs, runs, params, trust, fixed_translation, opts)
    offsets = np.array([xi_of(best.tau, r.tau) * TO_DISPLAY for r, _ in runs])
    # Every run from around the solution (the solve's own included) lands where the simplex shrank: their spread
    # is how well the solve finds this cost's minimum, which its curvature alone does not say.
    spread = np.sqrt(np.sum(offsets**2, axis=0) / max(len(runs) - 1, 1))
    if unc.is_minimum:
        sigma = np.maximum(unc.sigma, spread)
        unc = replace(unc, sigma=sigma, covariance=combine_covariance(unc.covariance, sigma), restart_spread=spread)
        unc = replace(unc, weakest=weakest_direction(unc.covariance, trust.tolerance_display))
    restarts = tuple(Restart(xi_of(best.tau, r.tau) * TO_DISPLAY, (c - best_cost) / unc.kappa,
                             "solution" if r is result else "restart")
                     for r, c in runs if r is not best)
    moved, moved_m = moved_from(starts, best.tau)
    unc = with_cross_check(with_elevation(with_intrinsics(unc, best.tau, trust), trust), trust)
    worse = None if loose is None else max(best_cost - cost(loose.tau), 0.0) / unc.kappa
    evidence = Evidence(moved, moved_m, len(np.unique(places(pairs))), fixed=AXES[3:] if fixed_translation else (),
                        fixed_worse_nll=worse)
    verdict = verdict_of(unc, list(restarts), trust, evidence=evidence)
    return Assessment(np.asarray(best.tau, dtype=np.float64), as_optim(best), unc, restarts, verdict, moved, moved_m,
                      evidence)


def _taken(pairs: list[PhotoPair], runs: list[tuple[PhotoResult, float]], params: PhotoParams, trust: TrustOptions,
           fixed_translation: bool, opts: PhotoTrustOptions | None) -> tuple[PhotoResult, float, Uncertainty]:
    """The run the assessment answers with, its cost and the uncertainty there, of ``runs``: the solve's own
    (first) and the restarts, each with its cost on the solve's points. NID's cost is not a likelihood, and its
    lowest minimum need not be the truth's: a restart is taken only within the restarts' own reach of the
    solution (the same basin solved better; one lower beyond it is another minimum, an ambiguity the verdict
    weighs) and only when lower by more than a statistical tie (``trust.ambiguity_nll`` in the cost's NLL scale:
    closer, the points cannot tell the two apart, and the solve's own answer is kept)."""
    (own, own_cost), anchor = runs[0], runs[0][0].tau
    unc = photo_uncertainty(pairs, anchor, params, trust, fixed_translation, opts)
    reach = np.array([trust.restart_rot_deg] * 3 + [trust.restart_trans_m * 100.0] * 3)
    near = [r for r in runs[1:] if bool(np.all(np.abs(xi_of(anchor, r[0].tau) * TO_DISPLAY) <= reach))]
    if near:
        run, run_cost = min(near, key=lambda r: r[1])
        if (own_cost - run_cost) / unc.kappa >= trust.ambiguity_nll:
            return run, run_cost, photo_uncertainty(pairs, run.tau, params, trust, fixed_translation, opts)
    return own, own_cost, unc
