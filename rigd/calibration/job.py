"""The calibration job, the one path from a :class:`CalibrationRequest` to a report: `rigd calibrate`, the demo and
the service's worker run it; the evaluation's runs take its first half (:func:`prepare`) and solve on the
features it extracts."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.geometry import Transform
from calib.methods import solve
from calib.optimize import typical_range_m
from calib.pipeline import CalibResult
from rigd.calibration.advice import SceneFacts, Step, next_steps
from rigd.calibration.elevation_plot import plot_elevation_profile
from rigd.calibration.features import Features, features_for, worker_pool
from rigd.calibration.outputs import write_visuals
from rigd.calibration.progress import OnIter, Progress, Stage
from rigd.calibration.request import CalibrationRequest, Resolved, resolve
from rigd.calibration.sections import build_report
from rigd.dataset import Dataset, open_dataset
from rigd.dataset.store import write_yaml
from rigd.errors import RigdError
from rigd.report import CalibrationReport


@dataclass(frozen=True)
class CalibrationOutcome:
    T_camera_lidar: Transform
    initial: Transform
    report: CalibrationReport
    out_dir: Path | None


def prepare(request: CalibrationRequest) -> tuple[Dataset, Resolved]:
    """The request's dataset, opened at its working width, and the request read against it (before any work:
    a request its method cannot honour is refused here)."""
    dataset = open_dataset(request.dataset, request.max_width)
    return dataset, resolve(request, dataset)


def _typical_range_m(features: Features) -> float:
    """The harmonic mean range (m) of the GMM's edge points, else of the points a photometric cost compares."""
    if features.gmm:
        return typical_range_m(features.gmm)
    ranges = np.concatenate([np.linalg.norm(p.points_lidar, axis=1) for p in features.photo or []] or [np.zeros(0)])
    near = ranges[ranges > 0.1]
    return float(len(near) / np.sum(1.0 / near)) if near.size else 10.0


def _scene_facts(dataset: Dataset, features: Features, resolved: Resolved) -> SceneFacts:
    prior = resolved.solve.prior
    return SceneFacts(len(dataset), _typical_range_m(features),
                      dataset.rig.camera.models()[0].pixels_per_radian,
                      prior is not None and (prior.xyz_m is not None or prior.fix_translation),
                      tuple(f"pairs/{d.name}" for d in dataset.pair_dirs), features.places)


def _steps(result: CalibResult, dataset: Dataset, features: Features, resolved: Resolved) -> tuple[Step, ...]:
    trust = resolved.solve.trust
    if result.assessment is None or trust is None:
        return ()
    return next_steps(result.assessment, _scene_facts(dataset, features, resolved), trust)


def _write(request: CalibrationRequest, dataset: Dataset, features: Features, initial: Transform,
           result: CalibResult, report: CalibrationReport, progress: Progress | None) -> None:
    """extrinsics.yaml, and with ``request.write_visuals`` the overlays and clouds, into ``request.out_dir``."""
    out = request.out_dir
    assert out is not None
    out.mkdir(parents=True, exist_ok=True)
    write_yaml(out / "extrinsics.yaml", report)
    if not request.write_visuals:
        return
    if progress:
        progress(Stage.OVERLAYS, 0, 1)
    elevation = 0.0 if result.elevation is None else result.elevation.offset_deg
    write_visuals(dataset, features.gmm, initial, result.T_camera_lidar, out, request.workers, elevation)
    if result.elevation is not None:
        plot_elevation_profile(out / "overlays" / "elevation_profile.png", result.elevation,
                               dataset.rig.lidar_elevation_offset_deg)


def run_calibration(request: CalibrationRequest, progress: Progress | None = None, on_iter: OnIter | None = None,
                    prepared: tuple[Dataset, Resolved] | None = None) -> CalibrationOutcome:
    """Calibrate ``request.dataset`` as the request says (``prepared``: :func:`prepare`'s answer, if the caller
    has it); with an ``out_dir``, write ``extrinsics.yaml``, overlays/ and clouds/ there."""
    started = time.monotonic()
    dataset, resolved = prepared or prepare(request)
    solve_request = resolved.solve

    def on_search(done: int, total: int) -> None:
        if progress:
            progress(Stage.SEARCH, done, total)

    def on_assess(done: int, total: int) -> None:
        if progress:
            progress(Stage.ASSESSING, done, total)

    with worker_pool(request.workers) as pool:
        try:
            features = features_for(dataset, solve_request, progress, request.workers)
            if progress:
                progress(Stage.OPTIMISING if solve_request.initial is not None else Stage.SEARCH, 0, 1)
            result = solve(solve_request, feats=features.gmm, photo=features.photo,
                           search_photo=features.search_photo, executor=pool, on_iter=on_iter, on_search=on_search,
                           on_assess=on_assess)
        except CalibError as exc:
            raise RigdError(f"{dataset.root}: {exc}") from exc
        initial = solve_request.initial
        if initial is None:
            assert result.search is not None  # no start: the search gave it
            initial = Transform.from_tau(result.search.best.tau)
        report = build_report(result=result, resolved=resolved, initial=initial, dataset=dataset,
                              wall_s=time.monotonic() - started, places=features.places,
                              steps=_steps(result, dataset, features, resolved))
        if request.out_dir is not None:
            _write(request, dataset, features, initial, result, report, progress)
    return CalibrationOutcome(result.T_camera_lidar, initial, report, request.out_dir)
