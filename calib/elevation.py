"""The LiDAR's common elevation offset, fitted beside the pose where cameras look all round.

A LiDAR whose beams all fire a little higher or lower than its elevation table says, or a head whose cameras
share an error of the principal point along the image's vertical, puts every edge point the same angle too
high or too low in every direction. One camera cannot tell this from a tilt. Cameras looking all round can:
a tilt raises edges on one side and lowers them on the other, the offset raises them everywhere, and a shift
in z moves near edges more than far ones. Left out of the model, the offset leaks into z and the tilt, and
how much depends on which rings cross which edges (docs/method.md item 18, docs/results.md).

The fit profiles the finest level's cost (paper eq. 8) over a grid of offsets, each a refinement of the pose
from the solution without an offset, and takes the vertex of a parabola through the lowest points. Its sigma
is the spread of that vertex with each place, and each ring, left out in turn (the poses held at the profile's:
first order), the larger of the two: where the rings fall on the edges biases the offset as it does the pose.
The pose's covariance then gains ``slope slope^T sigma^2``, ``slope`` the pose's change per degree of offset
along the profile.
"""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from calib.errors import CalibError
from calib.gmm import GmmOptions, PairFeatures, pair_terms
from calib.handed import collect, hand
from calib.optimize import OptimOptions, OptimResult, level_model, optimise, tail_options
from calib.prior import Prior
from calib.uncertainty import places, xi_of

F64 = NDArray[np.float64]

GRID_DEG = (-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0)  # beyond +-1 deg the LiDAR is out of its spec
FIT_SPAN_DEG = 0.5  # the parabola goes through the grid points this near the lowest one
MIN_PLACES = 3  # the sigma is a jackknife over places


@dataclass(frozen=True)
class ElevationFit:
    """``offset_deg`` the LiDAR's elevation offset (its points raised by it fit best) and ``sigma_deg`` its
    sigma, the larger of the jackknives over places and over rings (``sigma_places_deg``, ``sigma_rings_deg``);
    ``slope`` (6,) the pose's change in local coordinates (rad, rad, rad, m, m, m) per degree
    of offset; ``grid_deg`` and ``costs`` the profile; ``at_bound``: the lowest cost lies at the grid's end."""

    offset_deg: float
    sigma_deg: float
    slope: F64
    grid_deg: tuple[float, ...]
    costs: tuple[float, ...]
    at_bound: bool
    sigma_places_deg: float = 0.0
    sigma_rings_deg: float = 0.0


def raise_elevation(points_lidar: F64, offset_deg: float) -> F64:
    """``points_lidar`` (N,3) m, LiDAR frame, each turned ``offset_deg`` up in elevation, range and azimuth
    kept. A point straight above or below (no azimuth) stays where it is."""
    x, y, z = points_lidar[:, 0], points_lidar[:, 1], points_lidar[:, 2]
    horizontal = np.hypot(x, y)
    rng = np.linalg.norm(points_lidar, axis=1)
    elevation = np.arctan2(z, horizontal) + np.radians(offset_deg)
    scale = np.divide(rng * np.cos(elevation), horizontal, out=np.ones_like(rng), where=horizontal > 0)
    new_z = np.where(horizontal > 0, rng * np.sin(elevation), z)
    return np.column_stack([x * scale, y * scale, new_z])


def offset_features(feats: list[PairFeatures], offset_deg: float) -> list[PairFeatures]:
    """``feats`` with every edge point raised by ``offset_deg`` (:func:`raise_elevation`)."""
    if offset_deg == 0.0:
        return list(feats)
    return [replace(f, points=replace(f.points, points_lidar=raise_elevation(f.points.points_lidar, offset_deg)))
            for f in feats]


def _refine(feats: list[PairFeatures], offset_deg: float, tau: F64, finest: OptimOptions, gmm: GmmOptions,
            prior: Prior | None, kappa: float) -> OptimResult:
    return optimise(offset_features(feats, offset_deg), tau, finest, gmm, prior=prior, kappas=(kappa,))


def _refinements(feats: list[PairFeatures], solution: OptimResult, opts: OptimOptions, gmm: GmmOptions,
                 prior: Prior | None, executor: Executor | None, offsets_deg: tuple[float, ...]) -> list[OptimResult]:
    """The finest level of ``opts`` from ``solution`` with the points raised by each offset (its prior weight
    held at the solution's, so the costs compare), side by side in ``executor`` if given."""
    finest = tail_options(opts, 1)
    kappa = solution.levels[-1].kappa
    return collect([hand(executor, _refine, feats, d, solution.tau, finest, gmm, prior, kappa) for d in offsets_deg])


def _ring_labels(feats: list[PairFeatures]) -> list[NDArray[np.int64]] | None:
    """Per pair, (N_i,) the ring of each edge point numbered 0.. over all pairs (the same laser, the same
    number); None when a pair's rings are not known."""
    rings = [f.points.ring for f in feats]
    if any(r is None for r in rings):
        return None
    known = np.unique(np.concatenate([r for r in rings if r is not None]))
    return [np.searchsorted(known, r).astype(np.int64) for r in rings if r is not None]


def _group_costs(feats: list[PairFeatures], finest: OptimOptions, gmm: GmmOptions, tau: F64,
                 rings: list[NDArray[np.int64]] | None, n_rings: int) -> tuple[F64, F64]:
    """(P,) the finest level's cost (its GMM part, eq. 8) of each place at ``tau``, and (R,) of each ring."""
    model = level_model(feats, finest, gmm, 0)
    terms = pair_terms(list(model.feats), model.freeze(tau), tau, list(model.sigma_in_px), model.gmm)
    place = places(feats)
    by_place = np.zeros(int(place.max()) + 1)
    np.add.at(by_place, place, [-float(t.value.sum()) for t in terms])
    by_ring = np.zeros(n_rings)
    for t, labels in zip(terms, rings or [], strict=False):
        np.add.at(by_ring, labels[t.index], -t.value)
    return by_place, by_ring


def _jackknife(grid: F64, costs: F64, parts: F64) -> float:
    """The jackknife sigma of the profile's vertex, each group's cost (G, K) left out in turn (poses held)."""
    k = parts.shape[1]
    if k < MIN_PLACES:
        return 0.0
    left_out = np.array([_vertex(grid, costs - parts[:, j]) for j in range(k)])
    return float(np.sqrt((k - 1) / k * np.sum((left_out - left_out.mean()) ** 2)))


def _vertex(grid: F64, costs: F64) -> float:
    """The minimum of the parabola through the points within FIT_SPAN_DEG of the lowest (its grid point if
    the parabola opens downward)."""
    low = int(np.argmin(costs))
    near = np.abs(grid - grid[low]) <= FIT_SPAN_DEG + 1e-9
    a, b, _ = np.polyfit(grid[near], costs[near], 2)
    if a <= 0:
        return float(grid[low])
    return float(np.clip(-b / (2 * a), grid[0], grid[-1]))


def check_places(feats: list[PairFeatures]) -> None:
    """CalibError unless there are enough places to fit the offset."""
    n_places = int(places(feats).max()) + 1
    if n_places < MIN_PLACES:
        raise CalibError(f"fitting the LiDAR's elevation offset needs {MIN_PLACES} or more places, got {n_places}")


def fit_elevation_offset(
    feats: list[PairFeatures],
    solution: OptimResult,
    opts: OptimOptions,
    gmm: GmmOptions,
    *,
    prior: Prior | None = None,
    executor: Executor | None = None,
    grid_deg: tuple[float, ...] = GRID_DEG,
) -> ElevationFit:
    """The elevation offset that fits ``feats`` best, around ``solution`` (a solve of ``opts`` without one);
    the refinements run side by side in ``executor`` if given."""
    check_places(feats)
    solves = _refinements(feats, solution, opts, gmm, prior, executor, grid_deg)
    finest = tail_options(opts, 1)
    grid = np.asarray(grid_deg, dtype=np.float64)
    costs = np.array([s.final_cost for s in solves])
    rings = _ring_labels(feats)
    n_rings = 0 if rings is None else int(max((int(r.max()) + 1 for r in rings if r.size), default=0))
    parts = [_group_costs(offset_features(feats, d), finest, gmm, s.tau, rings, n_rings)
             for d, s in zip(grid_deg, solves, strict=True)]
    by_place = np.array([p for p, _ in parts])  # (G, P)
    by_ring = np.array([r for _, r in parts])  # (G, R)
    offset = _vertex(grid, costs)
    sigma_places, sigma_rings = _jackknife(grid, costs, by_place), _jackknife(grid, costs, by_ring)
    return ElevationFit(offset, max(sigma_places, sigma_rings), _slope(grid, [s.tau for s in solves], offset),
                        tuple(grid_deg), tuple(float(c) for c in costs), bool(np.argmin(costs) in (0, len(grid) - 1)),
                        sigma_places, sigma_rings)


def _slope(grid: F64, taus: list[F64], offset: float) -> F64:
    """(6,) the profile's poses' change per degree (local coordinates), a line through the grid points within
    FIT_SPAN_DEG of ``offset``."""
    near = np.flatnonzero(np.abs(grid - offset) <= FIT_SPAN_DEG + 1e-9)
    if near.size < 2:
        near = np.argsort(np.abs(grid - offset))[:2]
    origin = taus[int(near[np.argmin(np.abs(grid[near] - offset))])]
    xi = np.array([xi_of(origin, taus[i]) for i in near])
    return np.asarray(np.polyfit(grid[near], xi, 1)[0], dtype=np.float64)


SLOPE_STEP_DEG = 0.25  # a declared offset's slope: refinements this far either side (one profile step)


def elevation_slope(feats: list[PairFeatures], solution: OptimResult, opts: OptimOptions, gmm: GmmOptions,
                    prior: Prior | None = None, executor: Executor | None = None) -> F64:
    """(6,) the pose's change in local coordinates per degree of elevation offset around ``solution``, from
    refinements of the finest level with the points raised and lowered by SLOPE_STEP_DEG: how a declared
    offset's uncertainty moves the pose."""
    low, high = _refinements(feats, solution, opts, gmm, prior, executor, (-SLOPE_STEP_DEG, SLOPE_STEP_DEG))
    return np.asarray((xi_of(solution.tau, high.tau) - xi_of(solution.tau, low.tau)) / (2 * SLOPE_STEP_DEG),
                      dtype=np.float64)
