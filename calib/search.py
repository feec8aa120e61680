"""Global search for the initial guess: no hand-typed start (docs/method.md, "Automatic initial guess").

After a reassembly the camera may sit at any yaw about the LiDAR's up axis and be tilted by tens of degrees,
far outside the basin of the coarse-to-fine solve (about 5-10 deg). The search:

1. evaluates the weighted GMM cost (eqs. 8-10) with one wide Gaussian for every point (``sigma_deg``, the
   uniform-sigma model: a single rung of the precomputed edge fields serves all points, and all mounts of a
   pair are projected in one batch) on a grid of mounts ``R = R_base @ Rz(yaw) Ry(pitch) Rx(roll)`` (yaw over
   ``yaw_range_deg``, roll and pitch within ``tilt_deg``), the translation held at the lever arm;
2. polishes the ``keep`` best grid minima (one per neighbourhood) by a pattern search over rotations with
   steps halving from 8 to 1 deg and the Gaussian narrowing with them (the same batched cost; at ranges of
   metres a lever-arm error of decimetres moves edges by a few degrees, so rotation alone is searched);
3. merges polished poses closer than ``distinct_deg`` and sorts them by their cost at the last width, which
   every candidate shares, so the costs compare. The coarse-to-fine solve starts from the best.

``R_base`` turns the LiDAR's axes (x forward, z up) into the camera's: the identity for a panorama (whose
frame is x forward, z up), the OpenCV optical frame (z forward, y down) for a pinhole camera, whose search
keeps roll and pitch within ``tilt_deg`` of looking level along the LiDAR's horizon.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from calib.camera import CameraModel, Equirectangular, Mounted, Pinhole, project_rotated
from calib.errors import InitialGuessError
from calib.geometry import rotation_angle_deg, rpy_deg_to_matrix, so3_exp, so3_log
from calib.gmm import PairFeatures
from calib.handed import Handed, collect, hand
from calib.photometric import PhotoPair
from calib.search_mi import MiSearchPair, mi_costs, prepare

F64 = NDArray[np.float64]

# The grid scores at most this many edge points per pair (every k-th along the rings): a 6 deg Gaussian needs no
# more, and a head projects each place's points through all its sensors (a Ford head's grid took 320 s).
SEARCH_POINTS = 2000
# LiDAR axes (x forward, y left, z up) -> OpenCV optical axes (x right, y down, z forward).
OPTICAL_FROM_LIDAR_AXES = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


@dataclass(frozen=True)
class SearchOptions:
    """The grid, the refinement and what counts as a distinct candidate (angles in degrees)."""

    sigma_deg: float = 6.0  # the grid's Gaussian width (uniform; capped by the fields' widest rung)
    batch: int = 64  # mounts projected at once (memory: batch x edge points x 24 bytes)
    yaw_range_deg: float = 180.0  # yaw in [-range, range)
    yaw_step_deg: float = 15.0
    tilt_deg: float = 30.0  # roll and pitch in [-tilt, tilt]
    tilt_step_deg: float = 15.0
    keep: int = 3  # grid minima polished (each the best mount of its neighbourhood)
    polish: tuple[tuple[float, float], ...] = ((8.0, 6.0), (4.0, 4.0), (2.0, 3.0), (1.0, 3.0))  # (step, sigma) deg
    polish_rounds: int = 4  # moves per step at most
    distinct_deg: float = 5.0
    # With LiDAR reflectivity (calib.search_mi): the grid's image blur, and the polish's (step, blur) in deg.
    mi_blur_deg: float = 2.0
    mi_polish: tuple[tuple[float, float], ...] = ((8.0, 2.0), (4.0, 1.0), (2.0, 1.0), (1.0, 0.5))


@dataclass(frozen=True)
class Candidate:
    """A refined start: ``tau`` (6,) [omega rad, t m], the grid mount it came from (roll, pitch, yaw deg),
    its cost at the last refine level, its rank in the grid (0 = the lowest grid cost) and the score it was
    found by (``edges`` or ``mutual information``: costs compare within one score only)."""

    tau: F64
    grid_rpy_deg: F64
    cost: float
    grid_rank: int
    score: str = "edges"


@dataclass(frozen=True)
class SearchResult:
    """``candidates`` distinct refined starts, best first (with two scores, each score's best before the
    runners-up); ``evaluations`` the grid's mounts (each scored by every one of ``scores``); ``wall_s`` the
    search's own wall time in seconds (grid and polish, not the solves after it)."""

    candidates: tuple[Candidate, ...]
    evaluations: int
    scores: tuple[str, ...] = ("edges",)
    wall_s: float = 0.0

    @property
    def best(self) -> Candidate:
        return self.candidates[0]


def base_rotation(camera: CameraModel) -> F64:
    """R_base (3,3): the identity for panoramas and multi-camera heads (their frames are x forward, z up as the
    LiDAR's), LiDAR axes to the optical frame for pinhole cameras."""
    if isinstance(camera, Equirectangular | Mounted):
        return np.eye(3)
    return OPTICAL_FROM_LIDAR_AXES.copy()


def default_search(camera: CameraModel) -> SearchOptions:
    """The search's range for ``camera`` when the rig file sets none: every yaw and +-30 deg of tilt for a
    panorama; for a pinhole camera the rotations that keep the LiDAR's forward axis in the field of view
    (yaw within half the horizontal, roll and pitch within half the vertical field of view), with grid steps
    of an eighth of the horizontal field and the Gaussian narrowed with them."""
    opts = SearchOptions()
    if not isinstance(camera, Pinhole):
        return opts
    fx, fy = float(camera.K[0, 0]), float(camera.K[1, 1])
    hfov = float(np.degrees(2.0 * np.arctan(camera.width / (2.0 * fx))))
    vfov = float(np.degrees(2.0 * np.arctan(camera.height / (2.0 * fy))))
    step = min(opts.yaw_step_deg, hfov / 8.0)
    return replace(opts, yaw_range_deg=min(opts.yaw_range_deg, hfov / 2.0), tilt_deg=min(opts.tilt_deg, vfov / 2.0),
                   yaw_step_deg=step, tilt_step_deg=step, sigma_deg=min(opts.sigma_deg, step / 2.5))


def grid_mounts(opts: SearchOptions) -> F64:
    """(K,3) roll, pitch, yaw in degrees of every grid mount."""
    full_turn = opts.yaw_range_deg >= 180.0  # -180 and +180 are one mount
    yaws = np.arange(-opts.yaw_range_deg, opts.yaw_range_deg + (-1e-9 if full_turn else 1e-9), opts.yaw_step_deg)
    n_tilt = int(np.floor(opts.tilt_deg / opts.tilt_step_deg + 1e-9))
    tilts = opts.tilt_step_deg * np.arange(-n_tilt, n_tilt + 1)
    r, p, y = np.meshgrid(tilts, tilts, yaws, indexing="ij")
    return np.stack([r.ravel(), p.ravel(), y.ravel()], axis=1)


def _grid_costs(feat: PairFeatures, rotations: F64, translation_m: F64, sigma_px: float) -> F64:
    """The weighted GMM cost (eqs. 8-10) of one pair at every mount (K,), all points at one width
    ``sigma_px`` (the uniform-sigma model) so one rung of the precomputed fields serves every point and
    every mount is sampled in one batch. ``rotations`` (K,3,3)."""
    if feat.fields is None:
        raise InitialGuessError("the global search needs the edge fields (Evaluator.FIELD or AUTO)")
    every = -(-len(feat.points) // SEARCH_POINTS)  # every k-th point along the rings, at most SEARCH_POINTS
    pts = feat.points.points_lidar[::every]
    uv, valid = project_rotated(feat.camera, rotations, translation_m, pts)
    sel = np.flatnonzero(valid)
    sums = feat.fields.sample(uv[sel], np.full(len(sel), sigma_px))
    count = (np.maximum(sums[:, 6], 0.0) ** 4 + (6.0 * sigma_px) ** 4) ** 0.25  # |Omega_i| as in calib.gmm
    score = np.tile(feat.points.score[::every], len(rotations))[sel]
    value = (sums[:, 0] + score * sums[:, 3]) / (2.0 * count)
    return np.asarray(-np.bincount(sel // len(pts), weights=value, minlength=len(rotations)), dtype=np.float64)


def _rotations(base: F64, mounts: F64) -> F64:
    return np.stack([base @ rpy_deg_to_matrix(m) for m in mounts])


def _costs(feats: list[PairFeatures], rotations: F64, translation_m: F64, sigma_deg: float, batch: int) -> F64:
    """The grid cost (K,) of every rotation (K,3,3), summed over the pairs."""
    total = np.zeros(len(rotations))
    for feat in feats:
        sigma_px = float(np.radians(sigma_deg)) * feat.camera.pixels_per_radian
        for lo in range(0, len(rotations), batch):
            total[lo:lo + batch] += _grid_costs(feat, rotations[lo:lo + batch], translation_m, sigma_px)
    return total


# The 27 rotations {-1, 0, 1}^3 about the LiDAR's axes that a polishing round tries around its centre.
_STENCIL = np.stack(np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], indexing="ij"), -1).reshape(-1, 3)


Score = Callable[[F64, F64, float], F64]  # (rotations (K,3,3), translation (3,), width deg) -> costs (K,)


def _edge_score(feats: list[PairFeatures], opts: SearchOptions) -> Score:
    return lambda rotations, translation_m, sigma_deg: _costs(feats, rotations, translation_m, sigma_deg, opts.batch)


def _mi_score(photo: list[PhotoPair]) -> Score:
    """Minus the mutual information (calib.search_mi) with the images blurred by the width, one blur held at a
    time (a Ladybug5-size head's 60 sensor images blurred are 300 MB per width; callers go width by width)."""
    prepared: dict[float, list[MiSearchPair]] = {}

    def score(rotations: F64, translation_m: F64, blur_deg: float) -> F64:
        if blur_deg not in prepared:
            prepared.clear()
            prepared[blur_deg] = prepare(photo, blur_deg)
        return mi_costs(prepared[blur_deg], rotations, translation_m)

    return score


def _polish(score: Score, rotation: F64, translation_m: F64, steps: tuple[tuple[float, float], ...],
            rounds: int) -> tuple[F64, float]:
    """Pattern search from a grid mount: the best of the 27 neighbours ``step`` apart, at a width (the
    Gaussian's, or the image blur of the MI score) that narrows with the step, until the centre is best; then
    the next step. Returns the rotation and its cost at the last width (the same for every candidate, so the
    costs compare)."""
    return _polish_all(score, [rotation], translation_m, steps, rounds)[0]


def _polish_all(score: Score, rotations: list[F64], translation_m: F64, steps: tuple[tuple[float, float], ...],
                rounds: int) -> list[tuple[F64, float]]:
    """:func:`_polish` of each of ``rotations``, step by step for all of them (each one's path is its own), so a
    score that holds one width at a time prepares each width once."""
    polished = [(rotation, 0.0) for rotation in rotations]
    for step_deg, width_deg in steps:
        offsets = [so3_exp(np.radians(step_deg) * s) for s in _STENCIL]
        polished = [_polish_step(score, rotation, translation_m, offsets, width_deg, rounds)
                    for rotation, _ in polished]
    return polished


def _polish_step(score: Score, rotation: F64, translation_m: F64, offsets: list[F64], width_deg: float,
                 rounds: int) -> tuple[F64, float]:
    cost = 0.0
    for _ in range(rounds):
        costs = score(np.stack([rotation @ o for o in offsets]), translation_m, width_deg)
        best = int(np.argmin(costs))
        rotation, cost = rotation @ offsets[best], float(costs[best])
        if np.all(_STENCIL[best] == 0.0):
            break
    return rotation, cost


def _polish_edges(feats: list[PairFeatures], rotation: F64, translation_m: F64,
                  opts: SearchOptions) -> tuple[F64, float]:
    """:func:`_polish` with the edge score (features passed as themselves: the pool holds them)."""
    return _polish(_edge_score(feats, opts), rotation, translation_m, opts.polish, opts.polish_rounds)


def _grid_minima(rotations: F64, costs: F64, opts: SearchOptions) -> list[int]:
    """The ``keep`` lowest grid mounts that are each the lowest within 1.5 grid steps (one per basin)."""
    radius = 1.5 * max(opts.yaw_step_deg, opts.tilt_step_deg)
    kept: list[int] = []
    for k in np.argsort(costs):
        if all(rotation_angle_deg(rotations[k], rotations[j]) > radius for j in kept):
            kept.append(int(k))
            if len(kept) == opts.keep:
                break
    return kept


def _distinct(cands: list[Candidate], distinct_deg: float) -> list[Candidate]:
    kept: list[Candidate] = []
    for c in sorted(cands, key=lambda c: c.cost):
        if all(rotation_angle_deg(so3_exp(c.tau[:3]), so3_exp(k.tau[:3])) > distinct_deg for k in kept):
            kept.append(c)
    return kept


def _pair_grid(feats: list[PairFeatures], pair: int, rotations: F64, translation_m: F64,
               opts: SearchOptions) -> F64:
    """The grid cost (K,) of pair ``pair`` of ``feats`` (the whole list travels: a pool sends it once and its
    worker keeps the fields' rungs for the polish and the solves after)."""
    return _costs([feats[pair]], rotations, translation_m, opts.sigma_deg, opts.batch)


def _mi_grid(photo: list[PhotoPair], rotations: F64, translation_m: F64, opts: SearchOptions,
             on_progress: Callable[[int, int], None] | None) -> F64:
    """The MI score (K,) of every grid rotation, in batches (progress per batch)."""
    score = _mi_score(photo)
    out = np.zeros(len(rotations))
    batches = range(0, len(rotations), opts.batch)
    for done, lo in enumerate(batches):
        out[lo:lo + opts.batch] = score(rotations[lo:lo + opts.batch], translation_m, opts.mi_blur_deg)
        if on_progress is not None:
            on_progress(done + 1, len(batches))
    return out


def _edge_candidates(feats: list[PairFeatures], grid: list[Handed[F64]], rotations: F64, mounts: F64,
                     translation_m: F64, opts: SearchOptions, on_progress: Callable[[int, int], None] | None,
                     executor: Executor | None) -> list[Candidate]:
    costs = np.zeros(len(mounts))
    for pair_costs in collect(grid, None if on_progress is None else lambda done: on_progress(done, len(grid))):
        costs += pair_costs  # in the pairs' order, wherever each was computed
    if not np.any(costs < 0):
        raise InitialGuessError("global search: no grid mount brings any LiDAR edge near an image edge")
    minima = _grid_minima(rotations, costs, opts)
    # The runners-up go to the pool; this process polishes the best, then takes back any no worker has started.
    others = [hand(executor, _polish_edges, feats, rotations[k], translation_m, opts) for k in minima[1:]]
    polished = [_polish_edges(feats, rotations[minima[0]], translation_m, opts), *collect(others)]
    return _candidates(minima, polished, mounts, translation_m, "edges")


def _mi_candidates(photo: list[PhotoPair], rotations: F64, mounts: F64, translation_m: F64,
                   opts: SearchOptions, on_progress: Callable[[int, int], None] | None) -> list[Candidate]:
    costs = _mi_grid(photo, rotations, translation_m, opts, on_progress)
    if not np.any(costs < 0):
        return []
    minima = _grid_minima(rotations, costs, opts)
    polished = _polish_all(_mi_score(photo), [rotations[k] for k in minima], translation_m, opts.mi_polish,
                           opts.polish_rounds)
    return _candidates(minima, polished, mounts, translation_m, "mutual information")


def _candidates(minima: list[int], polished: list[tuple[F64, float]], mounts: F64, translation_m: F64,
                score: str) -> list[Candidate]:
    return [Candidate(np.concatenate([so3_log(rotation), translation_m]), mounts[k].copy(), cost, rank, score)
            for rank, (k, (rotation, cost)) in enumerate(zip(minima, polished, strict=True))]


def _interleaved(first: list[Candidate], second: list[Candidate], distinct_deg: float) -> list[Candidate]:
    """Each score's distinct candidates, best first, taken in turn (first[0], second[0], first[1], ...), a
    candidate within ``distinct_deg`` of one already taken dropped."""
    ordered = [c for pair in zip(first, second, strict=False) for c in pair] + first[len(second):] + second[len(first):]
    kept: list[Candidate] = []
    for c in ordered:
        if all(rotation_angle_deg(so3_exp(c.tau[:3]), so3_exp(k.tau[:3])) > distinct_deg for k in kept):
            kept.append(c)
    return kept


def search_initial(
    feats: list[PairFeatures],
    translation_m: F64,
    opts: SearchOptions | None = None,
    on_progress: Callable[[int, int], None] | None = None,
    executor: Executor | None = None,
    photo: list[PhotoPair] | None = None,
) -> SearchResult:
    """Distinct starts for the coarse-to-fine solve, best first; ``translation_m`` (3,) the lever arm
    (the translation of T_camera_lidar) held during the search. ``on_progress(done, total)`` per batch of the
    MI grid, then per pair's edge grid.
    ``photo``: the pairs' images and LiDAR reflectivity; given, the mounts are scored by mutual information
    (:mod:`calib.search_mi`) too, and each score's best start comes before the runners-up: neither score finds
    every rig (the edges failed on a real head's street scenes, MI on a simulated set with sensor effects and
    on one real narrow camera), and the GMM solves from both (:func:`calib.pipeline.calibrate`) decide.
    ``executor`` (the application's process pool): the pairs' edge grids go there while this process scores
    mutual information, then takes back the pairs no worker has started; all edge candidates but the first are
    polished there (this process takes back those no worker has started). The same result (the per-pair grids are
    summed in the pairs' order either way)."""
    started = time.monotonic()
    opts = opts or default_search(feats[0].camera)
    mounts = grid_mounts(opts)
    rotations = _rotations(base_rotation(feats[0].camera), mounts)
    # The pairs' edge grids go to the pool while this process scores mutual information.
    grid = [hand(executor, _pair_grid, feats, i, rotations, translation_m, opts) for i in range(len(feats))]
    # Progress counts the MI grid's batches, then the pairs' edge grids (which the pool computes meanwhile).
    mi_steps = -(-len(rotations) // opts.batch) if photo else 0
    steps = mi_steps + len(feats)

    def mi_progress(done: int, _total: int) -> None:
        if on_progress is not None:
            on_progress(done, steps)

    def edge_progress(done: int, _total: int) -> None:
        if on_progress is not None:
            on_progress(mi_steps + done, steps)

    mi = _distinct(_mi_candidates(photo, rotations, mounts, translation_m, opts, mi_progress),
                   opts.distinct_deg) if photo else []
    edges = _distinct(_edge_candidates(feats, grid, rotations, mounts, translation_m, opts, edge_progress, executor),
                      opts.distinct_deg)
    if not photo:
        return SearchResult(tuple(edges), len(mounts), wall_s=time.monotonic() - started)
    found = tuple(_interleaved(edges, mi, opts.distinct_deg))
    return SearchResult(found, len(mounts), ("edges", "mutual information"), wall_s=time.monotonic() - started)
