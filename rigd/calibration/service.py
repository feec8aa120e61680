"""The calibration job used by the CLI, the demo and the HTTP service."""

from __future__ import annotations

import ctypes
import dataclasses
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import NotRequired, TypedDict, TypeVar

import cv2
import numpy as np
from numpy.typing import NDArray

from calib.assess import Assessment, Status, TrustOptions
from calib.camera import CameraModel
from calib.elevation import ElevationFit, raise_elevation
from calib.errors import CalibError, FeaturelessError
from calib.geometry import Transform, rotation_angle_deg
from calib.gmm import PairFeatures
from calib.initial import SearchOptions, SearchResult, default_search
from calib.methods import Method, calibrate_method, gmm_params, photo_params
from calib.optimize import typical_range_m
from calib.photometric import PhotoCost, PhotoPair, PhotoParams, photo_pair
from calib.pipeline import (
    CalibParams,
    CalibResult,
    PairInput,
    extract_features,
    extract_place,
    paper_params,
    sigmas_for,
    with_sigmas,
)
from calib.pipeline import edge_points as edge_points_of
from calib.prior import Prior
from calib.uncertainty import TO_DISPLAY, xi_of
from rigd.calibration.advice import SceneFacts, next_steps
from rigd.calibration.elevation_plot import plot_elevation_profile
from rigd.calibration.pool import FeaturePool, preload
from rigd.calibration.visuals import (
    CLOUD_STAGE,
    OVERLAY_STAGES,
    cloud_top_view,
    colour_points,
    edge_views,
    write_coloured_ply,
)
from rigd.dataset import Dataset, Pair, open_dataset
from rigd.dataset.records import CameraConfig, CameraKind, prior_to_yaml, transform_to_yaml
from rigd.dataset.reference import agreement
from rigd.dataset.store import write_yaml
from rigd.dataset.working import WORKING_WIDTH_PX
from rigd.errors import RigdError
from rigd.report import (
    Assessed,
    CalibrationReport,
    ElevationOffset,
    GroundTruthError,
    InitialSearch,
    Level,
    MethodSettings,
    PairQuality,
    PriorYaml,
    Quality,
    ReferenceAgreement,
    Restart,
    Tolerance,
    Uncertainty,
)

# Paper defaults: sigma_in = 15, 10, 5 px of a 1024-wide panorama, as angles at 1 m.
PAPER_SIGMAS_DEG = paper_params().optim.sigmas_deg
DEFAULT_SIGMAS_DEG = CalibParams().optim.sigmas_deg


@dataclass(frozen=True)
class CalibrationRequest:
    dataset: Path
    out_dir: Path
    initial: Transform | None = None  # None: the dataset's rig.yaml initial_guess
    sigmas_deg: tuple[float, ...] | None = None  # None: the method's own schedule
    write_visuals: bool = True
    method: Method | None = None  # None: default_method
    prior: Prior | None = None  # None: the dataset's rig.yaml prior (if any)
    fix_translation: bool = False  # hold the translation at the prior's (or the initial guess's) lever arm
    tolerance: TrustOptions | None = None  # None: rig.yaml's tolerance, else 0.2 deg / 2 cm
    search: bool = False  # True: the global search even if a guess exists (it runs anyway without one)
    workers: int = 2  # processes for the pairs' edges and the independent solves (the rig computer's 2+ cores)
    max_width: int | None = WORKING_WIDTH_PX  # px: wider images are halved on load (rigd.dataset.working); None: as is
    fit_elevation: bool = False  # also fit the LiDAR's common elevation offset (calib.elevation)


@dataclass(frozen=True)
class CalibrationOutcome:
    T_camera_lidar: Transform
    initial: Transform
    report: CalibrationReport
    out_dir: Path


Progress = Callable[[str, float], None]


def _initial(request: CalibrationRequest, dataset: Dataset) -> Transform | None:
    """The request's guess, else rig.yaml's; None (the global search) when neither or ``request.search``."""
    if request.search:
        return None
    return request.initial if request.initial is not None else dataset.rig.initial_guess


def default_method(dataset: Dataset, initial: Transform | None, prior: Prior | None) -> Method:
    """The method when none is asked for: NID with its assessment on a single pinhole camera, where on real
    frames the GMM's finest cost has no minimum near the reference and NID's has (docs/baselines.md), when NID
    can run: from a start (the global search scores the GMM's edges), on clouds with intensity, without a
    Gaussian prior (NID's cost is not a likelihood to weigh one against). Elsewhere the GMM."""
    camera = dataset.source_camera
    pinhole = isinstance(camera, CameraConfig) and camera.kind is CameraKind.PINHOLE
    if not pinhole or initial is None or (prior is not None and prior.active) or len(dataset) == 0:
        return Method.RIGD
    intensity = dataset.load_pair(0).cloud.intensity  # a field of one value (some drivers write 0) is none
    return Method.NID_ASSESSED if intensity is not None and np.ptp(intensity) > 0 else Method.RIGD


def with_camera_model(trust: TrustOptions, dataset: Dataset) -> TrustOptions:
    """``trust`` with rig.yaml's declared sensor uncertainties: the LiDAR's elevation offset sigma, and a single
    camera's principal-point sigma as rotations (at the size on disk; a head's and a panorama's stay K-exact)."""
    if dataset.rig.lidar_elevation_sigma_deg:
        trust = dataclasses.replace(trust, elevation_sigma_deg=dataset.rig.lidar_elevation_sigma_deg)
    camera = dataset.source_camera
    if not isinstance(camera, CameraConfig):
        return trust
    return dataclasses.replace(trust, intrinsics_sigma_rad=camera.intrinsics_sigma_rad())


def search_yaml(found: SearchResult, opts: SearchOptions, wall_s: float) -> InitialSearch:
    """The ``initial_search`` section of a report: which grid mount won and where the runners-up ended."""
    best = Transform.from_tau(found.best.tau)
    return {
        "grid": {"mounts": found.evaluations, "scores": list(found.scores), "sigma_deg": opts.sigma_deg,
                 "yaw_range_deg": opts.yaw_range_deg, "yaw_step_deg": opts.yaw_step_deg, "tilt_deg": opts.tilt_deg,
                 "tilt_step_deg": opts.tilt_step_deg},
        "start": {"grid_rpy_deg": found.best.grid_rpy_deg.tolist(), "rpy_deg": best.rpy_deg.tolist(),
                  "xyz_m": best.translation_m.tolist()},
        "candidates": [{"grid_rpy_deg": c.grid_rpy_deg.tolist(), "rpy_deg": Transform.from_tau(c.tau).rpy_deg.tolist(),
                        "cost": c.cost, "grid_rank": c.grid_rank, "score": c.score,
                        "from_start_deg": rotation_angle_deg(best.rotation, Transform.from_tau(c.tau).rotation)}
                       for c in found.candidates],
        "wall_time_s": round(wall_s, 3),
    }


def _prior(request: CalibrationRequest, dataset: Dataset) -> Prior | None:
    prior = request.prior if request.prior is not None else dataset.rig.prior
    if not request.fix_translation:
        return prior
    if prior is None:
        return Prior(fix_translation=True)
    return dataclasses.replace(prior, fix_translation=True)


def _place_features(dataset: Dataset, params: CalibParams, i: int) -> list[PairFeatures]:
    """The features of pair ``i``: one per view (one camera, or each sensor of a head)."""
    pair = dataset.load_pair(i)
    cameras = list(dataset.rig.camera.models())
    if len(cameras) == 1:
        return [extract_features(PairInput(pair.image, pair.cloud.points_lidar, pair.cloud.ring, dataset.masks[0]),
                                 cameras[0], params, index=i)]
    inputs = [PairInput(image, pair.cloud.points_lidar, pair.cloud.ring, mask)
              for image, mask in zip(pair.images, dataset.masks, strict=True)]
    return extract_place(inputs, cameras, params, index=i)


def feature_at(feats: list[PairFeatures], dataset: Dataset, pair: int, view: int = 0) -> PairFeatures:
    """The features of ``view`` of ``pair`` in :func:`dataset_features`' list (ordered view by view)."""
    return feats[view * len(dataset) + pair]


Item = TypeVar("Item")


def of_pairs(items: Sequence[Item], n_pairs: int, pairs: Sequence[int]) -> list[Item]:
    """Every view of ``pairs`` from a dataset's per-view list ``items`` (:func:`dataset_features`,
    :func:`dataset_photo_pairs`: ``n_pairs`` pairs, view by view), in the same order."""
    views = len(items) // n_pairs
    return [items[v * n_pairs + i] for v in range(views) for i in pairs]


def dataset_features(dataset: Dataset, params: CalibParams, progress: Progress | None,
                     executor: Executor | None = None) -> list[PairFeatures]:
    """Edge features of every pair of ``dataset``, one per view of a pair (FeaturelessError names a pair without
    enough edges), the pairs extracted side by side in ``executor`` (:func:`edge_threads`) if given. Ordered
    view by view (:func:`feature_at`)."""
    if len(dataset) == 0:
        raise RigdError(f"{dataset.root}: dataset has no pairs (pairs/NNNN)")
    if executor is None:
        per_pair = []
        for i in range(len(dataset)):
            if progress:
                progress(f"edges of pair {i + 1}/{len(dataset)}", i / len(dataset))
            per_pair.append(_place_features(dataset, params, i))
    else:
        futures = [executor.submit(_place_features, dataset, params, i) for i in range(len(dataset))]
        for done, _ in enumerate(as_completed(futures)):
            if progress:
                progress(f"edges of {done + 1}/{len(dataset)} pairs", done / len(dataset))
        per_pair = [f.result() for f in futures]
    # One camera object per view for all pairs (each pair's was made, or unpickled, on its own): the cost projects
    # and sums the pairs that share one camera object together (calib.gmm.pair_terms), not one pair at a time.
    cameras = dataset.rig.camera.models()
    return [dataclasses.replace(place[v], camera=camera) for v, camera in enumerate(cameras) for place in per_pair]


@contextmanager
def worker_pool(workers: int) -> Iterator[Executor | None]:
    """``workers - 1`` spawned processes beside this one for the independent solves of one calibration (the
    alternative schedules, half the restarts, the search's runners-up), or None (one worker, or inside a daemonic
    pool worker, which cannot have children). They start at once and import the solver while this process
    extracts the pairs' edges in threads (:func:`edge_threads`), and keep the features they are sent, with the
    field bands their solves build (:class:`FeaturePool`).

    Spawn, not fork (as rigd.evaluate): a child forked while OpenCV's or BLAS's own threads hold a lock can
    deadlock, and those threads are invisible to the threading module. Costs ~1 s of imports per worker."""
    if workers <= 1 or multiprocessing.current_process().daemon:
        yield None
        return
    with FeaturePool(workers - 1, initializer=preload, initargs=("calib.assess",)) as pool:
        yield pool


@contextmanager
def edge_threads(workers: int, n_pairs: int) -> Iterator[Executor | None]:
    """Threads of this process for the pairs' edges (and overlays), as many as ``workers`` and the cores allow
    (the FFTs, OpenCV and the compiled kernels release Python's lock; measured on out51 with two workers:
    processes spent 3.4 s more CPU, their imports and copies, than one process for the same wall time), or None
    for one."""
    n = min(workers, cores(), n_pairs)
    if n <= 1:
        yield None
        return
    with ThreadPoolExecutor(n) as threads:
        yield threads


# glibc's malloc_trim (None elsewhere): each thread allocates from an arena of its own, and what the edge threads
# freed stays in those arenas, mapped, unless given back (out51: the peak RSS 318 -> 298 MiB, the same time).
_MALLOC_TRIM = getattr(ctypes.CDLL(None), "malloc_trim", None) if sys.platform.startswith("linux") else None


def return_freed_memory() -> None:
    """Give the heap that this process's threads freed back to the system (glibc), before a phase that allocates
    anew, so the process's peak does not hold both."""
    if _MALLOC_TRIM is not None:
        _MALLOC_TRIM(0)


def cores() -> int:
    """The processors this process may run on (Linux: its affinity, as a pinned service's)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


T = TypeVar("T")


def _per_pair(dataset: Dataset, what: str, progress: Progress | None, make: Callable[[Pair, int], T]) -> list[T]:
    """``make(pair, index)`` for every pair of ``dataset``, reporting ``what`` of pair i/n to ``progress``."""
    if len(dataset) == 0:
        raise RigdError(f"{dataset.root}: dataset has no pairs (pairs/NNNN)")
    out = []
    for i in range(len(dataset)):
        pair = dataset.load_pair(i)
        if progress:
            progress(f"{what} of pair {i + 1}/{len(dataset)}", i / len(dataset))
        out.append(make(pair, i))
    return out


def dataset_photo_pairs(dataset: Dataset, params: PhotoParams, progress: Progress | None) -> list[PhotoPair]:
    """The photometric costs' arrays of every pair, one per view, view by view as :func:`dataset_features`
    (FeaturelessError names a pair whose cloud has no intensity)."""
    cameras = dataset.rig.camera.models()
    per_pair = _per_pair(dataset, "reflectivity and image", progress, lambda pair, i: [photo_pair(
        image, pair.cloud.points_lidar, pair.cloud.intensity, pair.cloud.ring, camera, params, index=i, mask=mask)
        for image, camera, mask in zip(pair.images, cameras, dataset.masks, strict=True)])
    return [views[v] for v in range(len(cameras)) for views in per_pair]


def not_assessed_yaml(method: Method) -> Assessed:
    """The ``uncertainty`` and ``verdict`` of a method without an assessment: nothing is claimed."""
    return {
        "uncertainty": {"rpy_deg": [None, None, None], "xyz_cm": [None, None, None], "covariance": None,
                        "weakest": "not assessed: the uncertainty of docs/trust.md is defined for the GMM cost"},
        "verdict": {"status": Status.NOT_ASSESSED.value, "weak_axes": [],
                    "reasons": [f"method {method.value} has no trust assessment (restarts, uncertainty, verdict are "
                                "defined for the GMM cost only): check the overlays or run rigd check before use"]},
    }


def _finite(values: NDArray[np.float64]) -> list[float | None]:
    """A vector with non-finite entries as None (JSON has no infinity)."""
    return [float(v) if np.isfinite(v) else None for v in np.asarray(values, dtype=np.float64)]


def _uncertainty_yaml(a: Assessment) -> Uncertainty:
    u = a.uncertainty
    restarts: list[Restart] = [{"offset_rpy_deg": _finite(r.offset[:3]), "offset_xyz_cm": _finite(r.offset[3:]),
                                "delta_nll": r.delta_nll} for r in a.restarts]
    return {
        "rpy_deg": _finite(u.sigma[:3]),
        "xyz_cm": _finite(u.sigma[3:]),
        "covariance": [_finite(row) for row in u.covariance * np.outer(TO_DISPLAY, TO_DISPLAY)],
        "weakest": u.weakest,
        "laplace": {"rpy_deg": _finite(u.laplace[:3]), "xyz_cm": _finite(u.laplace[3:]), "nll_scale": u.kappa},
        "jackknife": None if u.jackknife is None else {
            "rpy_deg": _finite(u.jackknife[:3]), "xyz_cm": _finite(u.jackknife[3:]), "groups": u.jackknife_groups,
            "held_by_pairs": list(u.held_by)},
        "jackknife_rings": None if u.jackknife_rings is None else {
            "rpy_deg": _finite(u.jackknife_rings[:3]), "xyz_cm": _finite(u.jackknife_rings[3:]),
            "groups": u.ring_groups},
        "restart_spread": None if u.restart_spread is None else {
            "rpy_deg": _finite(u.restart_spread[:3]), "xyz_cm": _finite(u.restart_spread[3:])},
        "camera_model": None if u.intrinsics is None else {
            "rpy_deg": _finite(u.intrinsics[:3]), "xyz_cm": _finite(u.intrinsics[3:])},
        "lidar_elevation": None if u.elevation is None else {
            "rpy_deg": _finite(u.elevation[:3]), "xyz_cm": _finite(u.elevation[3:])},
        "matched_share": u.matched_share,
        "restarts": restarts,
    }


def assessment_yaml(a: Assessment, steps: tuple[str, ...] = ()) -> Assessed:
    """The ``uncertainty`` and ``verdict`` sections of a report (docs/trust.md); ``steps``: what to do next
    (rigd.calibration.advice)."""
    v = a.verdict
    return {
        "uncertainty": _uncertainty_yaml(a),
        "verdict": {"status": v.status.value, "weak_axes": list(v.weak_axes), "reasons": list(v.reasons),
                    "next_steps": list(steps), "moved_from_start_deg": a.moved_deg},
    }


def _scene_facts(dataset: Dataset, feats: list[PairFeatures], prior: Prior | None) -> SceneFacts:
    return SceneFacts(len(dataset), typical_range_m(feats), dataset.rig.camera.models()[0].pixels_per_radian,
                      prior is not None and (prior.xyz_m is not None or prior.fix_translation),
                      tuple(f"pairs/{d.name}" for d in dataset.pair_dirs))


def _pairs_yaml(result: CalibResult, dataset: Dataset) -> list[PairQuality]:
    """Edge pixels and points per pair (a head's pixels summed over its sensors, and per sensor)."""
    out = []
    for i in range(len(dataset)):
        stats = [result.pairs[v * len(dataset) + i] for v in range(len(dataset.views))]
        entry: PairQuality = {"edge_pixels": sum(p.edge_pixels for p in stats), "edge_points": stats[0].edge_points}
        if len(stats) > 1:
            entry["edge_pixels_per_sensor"] = dict(zip(dataset.views, [p.edge_pixels for p in stats], strict=True))
        out.append(entry)
    return out


def _quality_yaml(result: CalibResult, dataset: Dataset, wall_s: float) -> Quality:
    levels: list[Level] = [{"sigma_in_deg": lv.sigma_in_deg, "iterations": lv.iterations, "converged": lv.converged,
                            "final_cost": lv.costs[-1]} for lv in result.optim.levels]
    return {
        "final_cost": result.optim.final_cost,
        "converged": result.optim.converged,
        "levels": levels,
        "pairs": _pairs_yaml(result, dataset),
        # the initial guess's lever arm as a weak prior of the solve (docs/method.md), not of the uncertainty
        "guess_prior_sigma_cm": None if result.guess_sigma_m is None else result.guess_sigma_m * 100.0,
        "wall_time_s": round(wall_s, 3),
        # the images as solved on (rigd.dataset.working) and as on disk
        "image_size_px": [dataset.rig.camera.width, dataset.rig.camera.height],
        "source_image_size_px": [dataset.source_camera.width, dataset.source_camera.height],
    }


def _truth_yaml(gt: Transform, T: Transform) -> GroundTruthError:
    return {
        "rotation_deg": rotation_angle_deg(gt.rotation, T.rotation),
        "translation_cm": float(np.linalg.norm(T.translation_m - gt.translation_m) * 100.0),
        "rpy_deg": (T.rpy_deg - gt.rpy_deg).tolist(),
        "xyz_cm": ((T.translation_m - gt.translation_m) * 100.0).tolist(),
        # the same error in the uncertainty's axes (rotation about the LiDAR's x, y, z: docs/trust.md)
        "local_deg_cm": (xi_of(gt.tau, T.tau) * TO_DISPLAY).tolist(),
    }


# The report's parts around the assessment, each with the optional sections it may hold: unpacked into one
# literal, they keep the sections in extrinsics.yaml's order and mypy checks every key.
class _Compared(TypedDict, total=False):
    error_vs_ground_truth: GroundTruthError  # simulated datasets
    agreement_with_reference: ReferenceAgreement  # imported datasets with a reference.yaml


class _Searched(TypedDict, total=False):
    initial_search: InitialSearch


class _Settings(TypedDict):
    method: MethodSettings
    prior: NotRequired[PriorYaml]
    tolerance: Tolerance


def _compared(dataset: Dataset, T: Transform) -> _Compared:
    out: _Compared = {}
    if dataset.ground_truth is not None:
        out["error_vs_ground_truth"] = _truth_yaml(dataset.ground_truth, T)
    if dataset.reference is not None:
        out["agreement_with_reference"] = agreement(dataset.reference, T).to_yaml()
    return out


def _settings(method: MethodSettings, prior: Prior | None, trust: TrustOptions) -> _Settings:
    tolerance: Tolerance = {"rotation_deg": trust.tolerance_rot_deg, "translation_cm": trust.tolerance_trans_cm}
    if prior is None:
        return {"method": method, "tolerance": tolerance}
    return {"method": method, "prior": prior_to_yaml(prior), "tolerance": tolerance}


def _report(result: CalibResult, initial: Transform, dataset: Dataset, wall_s: float, assessed: Assessed,
            searched: _Searched, settings: _Settings) -> CalibrationReport:
    """The whole report, its sections in the order extrinsics.yaml lists them."""
    T = result.T_camera_lidar
    return {
        "T_camera_lidar": transform_to_yaml(T),
        "quality": _quality_yaml(result, dataset, wall_s),
        "change_from_initial": {
            "rotation_deg": rotation_angle_deg(initial.rotation, T.rotation),
            "translation_cm": float(np.linalg.norm(T.translation_m - initial.translation_m) * 100.0),
        },
        "dataset": str(dataset.root),
        **_compared(dataset, T),
        **assessed,
        **searched,
        **_elevation_yaml(result.elevation, dataset.rig.lidar_elevation_offset_deg),
        **settings,
    }


class _Elevation(TypedDict, total=False):
    lidar_elevation_offset: ElevationOffset


def _elevation_yaml(fit: ElevationFit | None, declared_deg: float) -> _Elevation:
    """The fitted offset as rig.yaml would declare it (the clouds were loaded raised by ``declared_deg``)."""
    if fit is None:
        return {}
    return {"lidar_elevation_offset": {"offset_deg": declared_deg + fit.offset_deg, "declared_deg": declared_deg,
                                       "sigma_deg": fit.sigma_deg, "sigma_places_deg": fit.sigma_places_deg,
                                       "sigma_rings_deg": fit.sigma_rings_deg,
                                       "at_bound": fit.at_bound, "grid_deg": list(fit.grid_deg),
                                       "cost": list(fit.costs)}}


def overlay_stem(dataset: Dataset, pair: int, view: int) -> str:
    """The file stem of a pair's overlays: ``NNNN`` for one camera, ``NNNN_SENSOR`` for a head's sensor."""
    return f"{pair:04d}" if len(dataset.views) == 1 else f"{pair:04d}_{dataset.views[view]}"


def _write_pair_visuals(dataset: Dataset, i: int, edge_points: list[NDArray[np.float64]] | None, initial: Transform,
                        T: Transform, out: Path, elevation_deg: float = 0.0) -> None:
    """Pair ``i``'s pictures: per view, the edge points (N,3) m, LiDAR frame, of ``edge_points[view]`` (None:
    the GMM's own edge points of the cloud, for a photometric method) over the image with the initial guess and
    with the solution, the close-up of where they moved most (overlays/NNNN[_SENSOR]_{before,after,closeup}.png);
    and the cloud coloured from the pair's images with the solution (clouds/NNNN.ply, and from above:
    overlays/NNNN_cloud.png). ``elevation_deg``: the LiDAR's fitted elevation offset, every point raised by it."""
    cameras = dataset.rig.camera.models()
    pair = dataset.load_pair(i)
    if edge_points is None:
        points = edge_points_of(pair.cloud.points_lidar, pair.cloud.ring, CalibParams()).points_lidar
        edge_points = [points] * len(cameras)
    edge_points = [raise_elevation(p, elevation_deg) for p in edge_points]
    cloud_lidar = raise_elevation(pair.cloud.points_lidar, elevation_deg)
    for v, (image, camera, mask) in enumerate(zip(pair.images, cameras, dataset.masks, strict=True)):
        views = edge_views(image, camera, initial, T, edge_points[v], mask)
        for name in OVERLAY_STAGES:
            cv2.imwrite(str(out / "overlays" / f"{overlay_stem(dataset, i, v)}_{name}.png"), getattr(views, name))
    seen = list(zip(pair.images, cameras, dataset.masks, strict=True))
    coloured = colour_points(seen, T, cloud_lidar)
    write_coloured_ply(out / "clouds" / f"{i:04d}.ply", seen, T, cloud_lidar, coloured=coloured)
    top = cloud_top_view(seen, T, cloud_lidar, coloured=coloured)
    cv2.imwrite(str(out / "overlays" / f"{i:04d}_{CLOUD_STAGE}.png"), top)


def _write_visuals(dataset: Dataset, feats: list[PairFeatures] | None, initial: Transform, T: Transform, out: Path,
                   executor: Executor | None = None, elevation_deg: float = 0.0) -> None:
    """:func:`_write_pair_visuals` of every pair, side by side in ``executor`` if given."""
    (out / "overlays").mkdir(parents=True, exist_ok=True)
    (out / "clouds").mkdir(parents=True, exist_ok=True)
    views = range(len(dataset.views))
    tasks = [(dataset, i, None if feats is None else [feature_at(feats, dataset, i, v).points.points_lidar
                                                       for v in views], initial, T, out, elevation_deg)
             for i in range(len(dataset))]
    if executor is None:
        for task in tasks:
            _write_pair_visuals(*task)
        return
    for future in [executor.submit(_write_pair_visuals, *task) for task in tasks]:
        future.result()


def _search_photo(dataset: Dataset, progress: Progress | None) -> list[PhotoPair] | None:
    """The pairs' images and LiDAR reflectivity for the global search's score (calib.search_mi), or None when a
    cloud has no intensity (the search then scores the edges)."""
    try:
        return dataset_photo_pairs(dataset, PhotoParams(cost=PhotoCost.MI), progress)
    except FeaturelessError:  # a cloud without intensity (the message names it): nothing to compare
        return None


def params_with_sigmas(params: CalibParams, sigmas_deg: tuple[float, ...]) -> CalibParams:
    """``params`` with the user's ladder ``sigmas_deg`` on every camera; RigdError unless they are positive angles."""
    if not sigmas_deg or not all(np.isfinite(s) and s > 0 for s in sigmas_deg):
        raise RigdError(f"sigmas must be positive angles in degrees, got {sigmas_deg}")
    return with_sigmas(params, tuple(sigmas_deg))


def _method_yaml(method: Method, params: CalibParams, photo: PhotoParams | None,
                 cameras: list[CameraModel]) -> MethodSettings:
    out: MethodSettings = {"name": method.value}
    if method.uses_gmm:
        out["sigmas_deg"] = list(sigmas_for(params, cameras))
    if photo is not None:
        out["photometric"] = {"cost": photo.cost.value, "blur_deg": list(photo.blur_deg), "bins": photo.n_bins}
    return out


def _check_elevation_fit(request: CalibrationRequest, dataset: Dataset) -> None:
    """The elevation offset is fitted only where cameras look all round: one camera cannot tell it from a tilt."""
    kind = dataset.rig.camera.kind
    if request.fit_elevation and kind not in (CameraKind.EQUIRECTANGULAR, CameraKind.HEAD):
        raise RigdError(f"{dataset.root}: fitting the LiDAR's elevation offset needs cameras that look all round (a "
                        f"panorama or a head); one {kind.value} camera cannot tell it from a tilt: declare it in "
                        "rig.yaml instead (lidar: {elevation_offset_deg: ..., elevation_offset_sigma_deg: ...})")


def run_calibration(request: CalibrationRequest, progress: Progress | None = None,
                    on_iter: Callable[[int, int, float], None] | None = None) -> CalibrationOutcome:
    """Calibrate ``request.dataset``; writes ``extrinsics.yaml``, overlays/ and clouds/ into ``out_dir``."""
    started = time.monotonic()
    dataset = open_dataset(request.dataset, request.max_width)
    _check_elevation_fit(request, dataset)
    initial = _initial(request, dataset)
    prior = _prior(request, dataset)
    method = request.method or default_method(dataset, initial, prior)
    params = gmm_params(method) or CalibParams()
    if request.sigmas_deg is not None:
        params = params_with_sigmas(params, request.sigmas_deg)
    trust = with_camera_model(request.tolerance or dataset.rig.tolerance or TrustOptions(), dataset)
    photo = photo_params(method)
    search = dataset.rig.search or default_search(dataset.rig.camera.models()[0])

    why = "" if request.search else "no initial guess: "  # chosen (--search), or no guess was given

    def on_search(done: int, total: int) -> None:
        if progress:
            progress(f"{why}global search over the mounts, pair {done}/{total}", 0.5 + 0.2 * done / total)

    searched_at = time.monotonic()
    with worker_pool(request.workers) as pool:
        try:
            with edge_threads(request.workers, len(dataset)) as threads:
                feats = dataset_features(dataset, params, progress, threads) if method.uses_gmm else None
            return_freed_memory()
            pairs = dataset_photo_pairs(dataset, photo, progress) if photo is not None else None
            search_photo = _search_photo(dataset, progress) if initial is None and method.uses_gmm else None
            if progress:
                progress("optimising" if initial is not None else f"{why}global search", 0.5)
            result = calibrate_method(method, feats, pairs, initial, params, on_iter, prior, trust, search,
                                      on_search, pool, search_photo, request.fit_elevation)
        except CalibError as exc:
            raise RigdError(f"{dataset.root}: {exc}") from exc
        if result.search is not None:
            initial = Transform.from_tau(result.search.best.tau)
        assert initial is not None
        steps = () if result.assessment is None or feats is None else next_steps(
            result.assessment, _scene_facts(dataset, feats, prior), trust)
        assessed = (not_assessed_yaml(method) if result.assessment is None
                    else assessment_yaml(result.assessment, steps))
        searched: _Searched = {} if result.search is None else {
            "initial_search": search_yaml(result.search, search, time.monotonic() - searched_at)}
        settings = _settings(_method_yaml(method, params, photo, list(dataset.rig.camera.models())), prior, trust)
        report = _report(result, initial, dataset, time.monotonic() - started, assessed, searched, settings)
        out = Path(request.out_dir)
        out.mkdir(parents=True, exist_ok=True)
        write_yaml(out / "extrinsics.yaml", report)
        if request.write_visuals:
            if progress:
                progress("writing overlays", 0.95)
            with edge_threads(request.workers, len(dataset)) as threads:
                _write_visuals(dataset, feats, initial, result.T_camera_lidar, out, threads,
                               0.0 if result.elevation is None else result.elevation.offset_deg)
            if result.elevation is not None:
                plot_elevation_profile(out / "overlays" / "elevation_profile.png", result.elevation,
                                       dataset.rig.lidar_elevation_offset_deg)
    return CalibrationOutcome(result.T_camera_lidar, initial, report, out)
