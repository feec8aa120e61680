"""Algorithm 1 end to end on arrays: edge extraction per pair, checks, coarse-to-fine optimisation."""

from __future__ import annotations

import functools
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from calib.assess import Assessment, TrustOptions, assess
from calib.camera import CameraModel, Equirectangular, Mounted
from calib.edges_image import ImageEdgeParams, image_edge_pixels
from calib.edges_points import (
    BOUNDARY,
    EdgePoints,
    PaperEdgeParams,
    ScanlineEdgeParams,
    paper_edge_points,
    scanline_edge_points,
)
from calib.elevation import GRID_DEG as ELEVATION_GRID_DEG
from calib.elevation import ElevationFit, check_places, elevation_slope, fit_elevation_offset, offset_features
from calib.errors import FeaturelessError, InitialGuessError
from calib.fields import EdgeFields
from calib.geometry import Transform
from calib.gmm import Evaluator, GmmOptions, KernelNorm, PairFeatures, in_image, transform_points
from calib.handed import Progress, collect, hand
from calib.optimize import OptimOptions, OptimResult, optimise
from calib.photometric import PhotoPair
from calib.pixel_grid import PixelGrid
from calib.prior import Prior
from calib.search import SearchOptions, SearchResult, search_initial

F64 = NDArray[np.float64]


class PointEdgeMethod(Enum):
    SCANLINE = "scanline"
    PAPER = "paper"


@dataclass(frozen=True)
class CalibParams:
    image_edges: ImageEdgeParams = field(default_factory=ImageEdgeParams)
    point_method: PointEdgeMethod = PointEdgeMethod.SCANLINE
    scanline: ScanlineEdgeParams = field(default_factory=ScanlineEdgeParams)
    paper_points: PaperEdgeParams = field(default_factory=PaperEdgeParams)
    gmm: GmmOptions = field(default_factory=GmmOptions)
    optim: OptimOptions = field(default_factory=OptimOptions)
    min_edge_pixels: int = 200
    min_edge_points: int = 30
    max_translation_m: float = 5.0  # camera and LiDAR share one rig: a longer baseline is a wrong guess
    min_boundary_points: int = 300  # fewer occlusion edge points in all pairs: folds stay in every level
    dense_ring_deg: float = 0.5  # a pinhole's schedule keeps folds in every level with rings this dense
    # The initial guess's lever arm (or the global search's: the prior's xyz_m, else zero) as a weak prior (sigma
    # per axis, m; 0: none) when no translation prior is given: where the images leave the translation
    # undetermined it stays near the guess. Without it a real street scene's translation ran 1.6 m off from a
    # searched start 0.9 deg from the truth, to a minimum 17 NLL above the truth's (docs/method.md).
    guess_sigma_m: float = 0.10
    # A multi-camera head's coarse-to-fine ladder (docs/method.md item 17); None: ``optim.sigmas_deg`` for every
    # camera (a ladder the user gives applies to a head as given).
    head_sigmas_deg: tuple[float, ...] | None = (10.5, 5.27, 1.76, 0.88)
    elevation_grid_deg: tuple[float, ...] = ELEVATION_GRID_DEG  # the offsets the elevation fit profiles


@dataclass(frozen=True)
class PairInput:
    """One pair as arrays: ``image`` (H,W[,3]) uint8, ``points_lidar`` (N,3) float64 m, ``ring`` (N,) or None,
    ``mask`` (H,W) bool, True where the image shows the scene (None: everywhere)."""

    image: NDArray[np.uint8]
    points_lidar: F64
    ring: NDArray[np.int16] | None
    mask: NDArray[np.bool_] | None = None


@dataclass(frozen=True)
class PairStats:
    """What a pair gave the solve: the GMM's edge pixels and edge points, and the LiDAR points a photometric
    cost compares with the image (its cloud's points with reflectivity)."""

    edge_pixels: int
    edge_points: int
    compared_points: int = 0


@dataclass(frozen=True)
class CalibResult:
    """The solution; ``assessment`` (restarts, uncertainty, verdict) unless the caller skipped it."""

    T_camera_lidar: Transform
    optim: OptimResult
    pairs: tuple[PairStats, ...]
    assessment: Assessment | None = None
    search: SearchResult | None = None  # the global search, when no initial guess was given
    guess_sigma_m: float | None = None  # the guess's lever arm entered the solve as a prior of this sigma
    elevation: ElevationFit | None = None  # the LiDAR's elevation offset, when it was fitted with the pose


def paper_params() -> CalibParams:
    """The paper's method as printed (section 8.2 settings), for the ablations and comparisons."""
    return CalibParams(
        image_edges=ImageEdgeParams(texture_radius_deg=0.0),
        point_method=PointEdgeMethod.PAPER,
        gmm=replace(GmmOptions(), kernel_norm=KernelNorm.PAPER, sigma_range_cap_m=1e9, sigma_floor_deg=0.0),
        optim=replace(OptimOptions(), sigmas_deg=(5.27, 3.52, 1.76), precondition=False, rotation_only_levels=0,
                      fold_levels=99, quasi_newton=False),  # eq. 24: plain gradient descent
        head_sigmas_deg=None,
    )


def with_sigmas(params: CalibParams, sigmas_deg: tuple[float, ...]) -> CalibParams:
    """``params`` with the ladder ``sigmas_deg`` for every camera, a head's too."""
    return replace(params, optim=replace(params.optim, sigmas_deg=tuple(sigmas_deg)), head_sigmas_deg=None)


def sigmas_for(params: CalibParams, cameras: list[CameraModel]) -> tuple[float, ...]:
    """The coarse-to-fine ladder for ``cameras``: ``params.head_sigmas_deg`` for a head (all its sensors
    ``Mounted``; docs/method.md item 17), else ``params.optim.sigmas_deg``."""
    if params.head_sigmas_deg is not None and cameras and all(isinstance(c, Mounted) for c in cameras):
        return params.head_sigmas_deg
    return params.optim.sigmas_deg


def edge_points(points_lidar: F64, ring: NDArray[np.int16] | None, params: CalibParams) -> EdgePoints:
    """The LiDAR edge points of one cloud (paper 4.2, or the scan-line edges of docs/method.md item 1)."""
    if params.point_method is PointEdgeMethod.PAPER:
        return paper_edge_points(points_lidar, ring, params.paper_points)
    return scanline_edge_points(points_lidar, ring, params.scanline)


def _features(pair: PairInput, camera: CameraModel, params: CalibParams, points: EdgePoints,
              place: int | None) -> PairFeatures:
    """The features of one image with the cloud's ``points``: edge pixels, their fields and pixel grid."""
    wrap = isinstance(camera, Equirectangular)
    pixels = image_edge_pixels(pair.image, params.image_edges, wrap, camera.pixels_per_radian, pair.mask)
    fields = None
    if params.gmm.evaluator is not Evaluator.EXACT:
        floor = max(params.gmm.sigma_floor_px, np.radians(params.gmm.sigma_floor_deg) * camera.pixels_per_radian)
        fields = EdgeFields.build(pixels.uv, pixels.score, camera.width, camera.height, wrap_u=wrap,
                                  sigma_min=floor, sigma_max=params.gmm.sigma_ceiling_px)
    grid = PixelGrid.build(pixels.uv, pixels.score, camera.width, camera.height, wrap)
    return PairFeatures(camera, pixels, points, fields, grid, place)


def _featureless(index: int, n_pixels: int, n_points: int, params: CalibParams) -> FeaturelessError | None:
    if n_pixels >= params.min_edge_pixels and n_points >= params.min_edge_points:
        return None
    return FeaturelessError(
        f"pair {index}: featureless scene ({n_pixels} edge pixels, need {params.min_edge_pixels}; "
        f"{n_points} edge points, need {params.min_edge_points})")


def extract_features(pair: PairInput, camera: CameraModel, params: CalibParams, index: int = 0) -> PairFeatures:
    """Edge pixels and edge points of one pair (paper 4.3); raises FeaturelessError naming the pair."""
    feat = _features(pair, camera, params, edge_points(pair.points_lidar, pair.ring, params), None)
    error = _featureless(index, len(feat.pixels.uv), len(feat.points), params)
    if error is not None:
        raise error
    return feat


def extract_place(images: list[PairInput], cameras: list[CameraModel], params: CalibParams,
                  index: int) -> list[PairFeatures]:
    """The features of one place of a multi-camera head: one per sensor (``images[k]`` seen by ``cameras[k]``,
    every one with the same cloud), sharing the cloud's edge points, their ``place`` ``index``. A sensor that
    sees only sky holds few edges; the place is featureless only when all its sensors together are."""
    if not images or len(images) != len(cameras):
        raise FeaturelessError(f"place {index}: {len(images)} images for {len(cameras)} sensors")
    points = edge_points(images[0].points_lidar, images[0].ring, params)
    feats = [_features(pair, camera, params, points, index) for pair, camera in zip(images, cameras, strict=True)]
    error = _featureless(index, sum(len(f.pixels.uv) for f in feats), len(points), params)
    if error is not None:
        raise error
    return feats


def _in_view(feat: PairFeatures, points_lidar: F64, tau: F64) -> int:
    """How many of ``points_lidar`` (N,3) m project into ``feat``'s image at the pose ``tau``."""
    uv, valid = feat.camera.project(transform_points(tau, points_lidar)[0])
    return int(np.count_nonzero(in_image(feat.camera, uv, valid)))


def check_initial_guess(feats: list[PairFeatures], tau0: F64) -> int:
    """Number of edge points that project into their image at ``tau0``; raises if none does."""
    total = sum(_in_view(f, f.points.points_lidar, tau0) for f in feats)
    if total == 0:
        raise InitialGuessError("no edge point projects into any image under the initial guess")
    return total


def schedule(feats: list[PairFeatures], params: CalibParams, tau0: F64) -> OptimOptions:
    """The optimiser's options for ``feats`` solved from ``tau0``: ``params.optim`` with the ladder of
    :func:`sigmas_for`, and fold edges kept on
    every level when the pairs hold too few occlusion edges in their cameras' view at ``tau0`` (a pinhole
    sees a fraction of the LiDAR's turn: points behind it pin nothing)."""
    optim = replace(params.optim, sigmas_deg=sigmas_for(params, [f.camera for f in feats]))
    boundaries = sum(_in_view(f, f.points.points_lidar[f.points.kind == BOUNDARY], tau0) for f in feats)
    narrow = not all(isinstance(f.camera, Equirectangular | Mounted) for f in feats)  # a head sees all round
    if boundaries < params.min_boundary_points or (narrow and _dense_rings(feats, params.dense_ring_deg)):
        # Too few occlusion edges to pin the finest levels alone (measured: 152 in 2 small pairs put the
        # finest cost's minimum 9.7 deg off; 108 in view in 3 simulated pinhole pairs 2.2 deg off, 0.57 deg
        # with the folds); fold edges are biased (~0.3 deg) but keep it anchored.
        # A narrow view with dense rings keeps them too: the occlusion edges found along the rings lie on
        # near-vertical image edges, which hold the image's horizontal only, so a rotation about the LiDAR's
        # lateral axis slides them along those edges; folds where dense rings cross horizontal creases (wall
        # bases, kerbs, sills) hold it. A panorama's vertical edges at its sides hold it through their tilt,
        # and a VLP-16's 2 deg rings cross too few creases (docs/method.md, item 9).
        return replace(optim, fold_levels=len(optim.sigmas_deg))
    return optim


def _dense_rings(feats: list[PairFeatures], max_deg: float) -> bool:
    """Whether the clouds' rings are at most ``max_deg`` apart in elevation: the edge points' elevations,
    split into rings where consecutive ones (sorted) differ by more than 0.1 deg (a VLP-16's laser offsets
    spread one ring over some 0.3 deg near the sensor, its rings are 2 deg apart; a 64-ring LiDAR's dense
    band is 0.17 deg apart), and the median spacing of neighbouring rings' median elevations."""
    spacings = []
    for f in feats:
        p = f.points.points_lidar
        elevation = np.sort(np.degrees(np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1]))))
        cuts = np.flatnonzero(np.diff(elevation) > 0.1) + 1
        rings = np.array([np.median(r) for r in np.split(elevation, cuts) if len(r)])
        if len(rings) > 1:
            spacings.append(np.diff(rings))
    return bool(spacings) and float(np.median(np.concatenate(spacings))) <= max_deg


def solve_prior(prior: Prior | None, guess: Transform, sigma_m: float) -> Prior | None:
    """The prior the solve uses: ``prior``, plus the guess's lever arm with ``sigma_m`` per axis when ``prior``
    says nothing of the translation. The assessment reports the data's uncertainty without it."""
    if sigma_m <= 0 or (prior is not None and (prior.sigma_xyz_m is not None or prior.fix_translation)):
        return prior
    sigma = np.full(3, sigma_m)
    if prior is None:
        return Prior(xyz_m=guess.translation_m, sigma_xyz_m=sigma)
    return replace(prior, xyz_m=guess.translation_m, sigma_xyz_m=sigma)


def _alternatives(feats: list[PairFeatures], starts: list[F64], optim: OptimOptions, gmm: GmmOptions,
                  prior: Prior | None, executor: Executor | None) -> Callable[[], list[OptimResult]]:
    """Full solves from ``starts``, the global search's next-best distinct starts (the assessment weighs
    them): started in ``executor`` now if given, so they run while this process solves from the best start;
    call the result to collect them (this process takes back those no worker has started: calib.handed)."""
    single = replace(optim, alternative_schedules=0)
    handed = [hand(executor, functools.partial(optimise, prior=prior), feats, s, single, gmm) for s in starts]
    return lambda: collect(handed)


def _checked_start(feats: list[PairFeatures], initial: Transform, prior: Prior | None,
                   params: CalibParams) -> Transform:
    """The start (its translation the held lever arm's, if held); InitialGuessError for a start no rig has, or one
    under which no edge point projects into any image."""
    if prior is not None and prior.fix_translation and prior.xyz_m is not None:
        initial = Transform(initial.rotation, prior.xyz_m)
    if float(np.linalg.norm(initial.translation_m)) > params.max_translation_m:
        raise InitialGuessError(
            f"initial guess puts the camera {np.linalg.norm(initial.translation_m):.2f} m from the LiDAR "
            f"(more than {params.max_translation_m} m): not a rig")
    check_initial_guess(feats, initial.tau)
    return initial


def _fitted_elevation(feats: list[PairFeatures], first: OptimResult, optim: OptimOptions, params: CalibParams,
                      prior: Prior | None, executor: Executor | None) -> ElevationFit:
    """The LiDAR's elevation offset fitted around the first solve ``first`` (calib.elevation; 3 places or more)."""
    check_places(feats)
    return fit_elevation_offset(feats, first, optim, params.gmm, prior=prior, executor=executor,
                                grid_deg=params.elevation_grid_deg)


def _elevation_sigma(trust: TrustOptions | None, slope: F64, sigma_deg: float) -> TrustOptions | None:
    """``trust`` with the pose's change for one sigma of the LiDAR's elevation offset (calib.assess.with_elevation)."""
    if trust is None:
        return None
    return replace(trust, elevation_sigma_pose=tuple(float(v) for v in slope * sigma_deg))


def calibrate(
    feats: list[PairFeatures],
    initial: Transform | None,
    params: CalibParams,
    *,
    on_iter: Callable[[int, int, float], None] | None = None,
    prior: Prior | None = None,
    trust: TrustOptions | None = None,
    search: SearchOptions | None = None,
    on_search: Callable[[int, int], None] | None = None,
    executor: Executor | None = None,
    search_photo: list[PhotoPair] | None = None,
    fit_elevation: bool = False,
    on_assess: Progress | None = None,
) -> CalibResult:
    """Algorithm 1 from ``initial`` (with the prior's MAP term if given), then, with ``trust``, the restarts,
    per-axis uncertainty and verdict of :mod:`calib.assess` (a restart that ends lower is the solution).

    ``initial`` None: the global search of :mod:`calib.search` (``search`` options, the lever arm from the
    prior or zero; the mounts scored by mutual information with ``search_photo``, else by the edges) gives the
    start, and its runner-up is solved in full too and weighed by the assessment. Without a translation prior,
    the start's lever arm enters the solve as a weak prior (:func:`solve_prior`). ``executor`` (the
    application's pool): the independent solves run there beside this process's, to the same result.
    ``fit_elevation``: the LiDAR's common elevation offset fitted around a first solve (:mod:`calib.elevation`),
    the pose solved and assessed again with the edge points raised by it, the offset's sigma in the pose's.
    ``on_assess(done, total)``: the assessment's restarts."""
    found = None
    if initial is None:
        lever_arm = prior.xyz_m if prior is not None and prior.xyz_m is not None else np.zeros(3)
        found = search_initial(feats, lever_arm, search, on_search, executor, search_photo)
        initial = Transform.from_tau(found.best.tau)
    initial = _checked_start(feats, initial, prior, params)
    tau0 = initial.tau
    optim = schedule(feats, params, tau0)
    runners_up = 0 if trust is None or found is None else trust.search_runners_up
    runner_starts = [] if found is None else [c.tau for c in found.candidates[1:1 + runners_up]]
    solving = solve_prior(prior, initial, params.guess_sigma_m)
    guess_sigma = params.guess_sigma_m if solving is not prior else None
    elevation = None
    if fit_elevation:
        first = optimise(feats, tau0, optim, params.gmm, on_iter=on_iter, prior=solving, executor=executor)
        elevation = _fitted_elevation(feats, first, optim, params, solving, executor)
        feats = offset_features(feats, elevation.offset_deg)
        trust = _elevation_sigma(trust, elevation.slope, elevation.sigma_deg)
    others = _alternatives(feats, runner_starts, optim, params.gmm, solving, executor)
    result = optimise(feats, tau0, optim, params.gmm, on_iter=on_iter, prior=solving, executor=executor)
    if trust is not None and trust.elevation_sigma_deg > 0 and elevation is None:  # a declared offset's sigma
        slope = elevation_slope(feats, result, optim, params.gmm, solving, executor)
        trust = _elevation_sigma(trust, slope, trust.elevation_sigma_deg)
    stats = tuple(PairStats(len(f.pixels.uv), len(f.points)) for f in feats)
    if trust is None:
        return CalibResult(Transform.from_tau(result.tau), result, stats, search=found, guess_sigma_m=guess_sigma,
                           elevation=elevation)
    assessment = assess(feats, result, optim, params.gmm, prior=prior, trust=trust, alternatives=tuple(others()),
                        solving=solving, executor=executor, starts=(tau0, *runner_starts), on_progress=on_assess)
    return CalibResult(Transform.from_tau(assessment.tau), assessment.optim, stats, assessment, found, guess_sigma,
                       elevation)
