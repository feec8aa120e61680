"""The calibration report's sections (rigd/report.py's records), each built here from calib's results."""

from __future__ import annotations

from typing import NotRequired, TypedDict

import numpy as np
from numpy.typing import NDArray

from calib.assess import Assessment, Status, TrustOptions
from calib.camera import CameraModel
from calib.elevation import ElevationFit
from calib.geometry import Transform, rotation_angle_deg
from calib.methods import SolveRequest
from calib.pipeline import CalibResult, sigmas_for
from calib.search import SearchOptions, SearchResult
from calib.uncertainty import TO_DISPLAY, xi_of
from rigd.calibration.advice import Step
from rigd.calibration.request import Resolved
from rigd.dataset import Dataset
from rigd.dataset.records import prior_to_yaml, transform_to_yaml
from rigd.dataset.reference import agreement
from rigd.report import (
    Assessed,
    CalibrationReport,
    ElevationOffset,
    GroundTruthError,
    InitialSearch,
    Level,
    MethodSettings,
    NextStep,
    PairQuality,
    PriorYaml,
    Quality,
    ReferenceAgreement,
    Restart,
    Sigmas,
    StartYaml,
    Tolerance,
    Uncertainty,
)


def search_yaml(found: SearchResult, opts: SearchOptions) -> InitialSearch:
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
        "wall_time_s": round(found.wall_s, 3),
    }


def not_assessed_yaml(solve: SolveRequest) -> Assessed:
    """The ``uncertainty`` and ``verdict`` of a solve without an assessment: nothing is claimed."""
    method = solve.method
    why = (f"method {method.value} has no trust assessment (restarts, uncertainty, verdict are defined for the GMM "
           "and nid-assessed only)" if not method.spec.assessed else "the assessment was not asked for")
    return {
        "uncertainty": {"rpy_deg": [None, None, None], "xyz_cm": [None, None, None], "covariance": None,
                        "weakest": "not assessed: the uncertainty of docs/trust.md is defined for the GMM cost"},
        "verdict": {"status": Status.NOT_ASSESSED.value, "weak_axes": [],
                    "reasons": [f"{why}: check the overlays or run rigd check before use"]},
    }


def _finite(values: NDArray[np.float64]) -> list[float | None]:
    """A vector with non-finite entries as None (JSON has no infinity)."""
    return [float(v) if np.isfinite(v) else None for v in np.asarray(values, dtype=np.float64)]


def _sigmas(values: NDArray[np.float64]) -> Sigmas:
    """Six values per axis (roll, pitch, yaw deg; x, y, z cm) in the report's form."""
    return {"rpy_deg": _finite(values[:3]), "xyz_cm": _finite(values[3:])}


def _uncertainty_yaml(a: Assessment) -> Uncertainty:
    u = a.uncertainty
    restarts: list[Restart] = [{"offset_rpy_deg": _finite(r.offset[:3]), "offset_xyz_cm": _finite(r.offset[3:]),
                                "delta_nll": r.delta_nll} for r in a.restarts]
    return {
        **_sigmas(u.sigma),
        "covariance": [_finite(row) for row in u.covariance * np.outer(TO_DISPLAY, TO_DISPLAY)],
        "weakest": u.weakest,
        "laplace": {**_sigmas(u.laplace), "nll_scale": u.kappa},
        "jackknife": None if u.jackknife is None else {
            **_sigmas(u.jackknife), "groups": u.jackknife_groups, "held_by_pairs": list(u.held_by)},
        "jackknife_rings": None if u.jackknife_rings is None else {
            "rpy_deg": _finite(u.jackknife_rings[:3]), "xyz_cm": _finite(u.jackknife_rings[3:]),
            "groups": u.ring_groups},
        "restart_spread": None if u.restart_spread is None else _sigmas(u.restart_spread),
        "camera_model": None if u.intrinsics is None else _sigmas(u.intrinsics),
        "lidar_elevation": None if u.elevation is None else _sigmas(u.elevation),
        "cross_check": None if u.cross_check is None else _sigmas(u.cross_check),
        "matched_share": u.matched_share,
        "restarts": restarts,
    }


def step_yaml(step: Step) -> NextStep:
    return {"text": step.text, "actions": [a.value for a in step.actions], "axes": list(step.axes),
            "pairs": step.pairs}


def assessment_yaml(a: Assessment, steps: tuple[Step, ...] = ()) -> Assessed:
    """The ``uncertainty`` and ``verdict`` sections of a report (docs/trust.md); ``steps``: what to do next
    (rigd.calibration.advice)."""
    v = a.verdict
    return {
        "uncertainty": _uncertainty_yaml(a),
        "verdict": {"status": v.status.value, "weak_axes": list(v.weak_axes), "reasons": list(v.reasons),
                    "fixed_axes": list(v.fixed_axes),
                    "next_steps": [step_yaml(s) for s in steps], "moved_from_start_deg": a.moved_deg},
    }


def _pairs_yaml(result: CalibResult, dataset: Dataset) -> list[PairQuality]:
    """Edge pixels and points per pair (a head's pixels summed over its sensors, and per sensor)."""
    out = []
    for i in range(len(dataset)):
        stats = [result.pairs[v * len(dataset) + i] for v in range(len(dataset.views))]
        entry: PairQuality = {"edge_pixels": sum(p.edge_pixels for p in stats), "edge_points": stats[0].edge_points}
        if stats[0].compared_points:
            entry["compared_points"] = stats[0].compared_points
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
    start: StartYaml
    prior: NotRequired[PriorYaml]
    tolerance: Tolerance


def _compared(dataset: Dataset, T: Transform) -> _Compared:
    out: _Compared = {}
    if dataset.ground_truth is not None:
        out["error_vs_ground_truth"] = _truth_yaml(dataset.ground_truth, T)
    if dataset.reference is not None:
        out["agreement_with_reference"] = agreement(dataset.reference, T).to_yaml()
    return out


def _settings(resolved: Resolved, cameras: list[CameraModel]) -> _Settings:
    solve = resolved.solve
    trust = solve.trust or TrustOptions()
    tolerance: Tolerance = {"rotation_deg": trust.tolerance_rot_deg, "translation_cm": trust.tolerance_trans_cm,
                            "per_axis": trust.tolerance_display.tolist()}
    start: StartYaml = {"source": resolved.start.value, "choice": resolved.start_why.choice,
                        "why": resolved.start_why.why}
    if resolved.start_version is not None:
        start["version"] = resolved.start_version
    out: _Settings = {"method": _method_yaml(solve, resolved.method_why.why, cameras), "start": start,
                      "tolerance": tolerance}
    if solve.prior is not None:
        out["prior"] = prior_to_yaml(solve.prior)
    return out


def build_report(*, result: CalibResult, resolved: Resolved, initial: Transform, dataset: Dataset, wall_s: float,
                 places: tuple[int, ...], steps: tuple[Step, ...] = ()
                 ) -> CalibrationReport:
    """The whole report of ``result`` (solved as ``resolved`` says, from ``initial``), its sections in the order
    extrinsics.yaml lists them; ``steps``: what to do next (rigd.calibration.advice)."""
    T = result.T_camera_lidar
    solve = resolved.solve
    assessed = (not_assessed_yaml(solve) if result.assessment is None
                else assessment_yaml(result.assessment, steps))
    searched: _Searched = {} if result.search is None or solve.search is None else {
        "initial_search": search_yaml(result.search, solve.search)}
    return {
        "T_camera_lidar": transform_to_yaml(T),
        "quality": _quality_yaml(result, dataset, wall_s),
        "change_from_initial": {
            "rotation_deg": rotation_angle_deg(initial.rotation, T.rotation),
            "translation_cm": float(np.linalg.norm(T.translation_m - initial.translation_m) * 100.0),
        },
        "dataset": str(dataset.root),
        "places": {"count": len(set(places)), "of_pairs": list(places)},
        **_compared(dataset, T),
        **assessed,
        **searched,
        **_elevation_yaml(result.elevation, dataset.rig.lidar_elevation_offset_deg),
        **_settings(resolved, list(dataset.rig.camera.models())),
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


def _method_yaml(solve: SolveRequest, why: str, cameras: list[CameraModel]) -> MethodSettings:
    out: MethodSettings = {"name": solve.method.value, "why": why}
    if solve.gmm is not None:
        out["sigmas_deg"] = list(sigmas_for(solve.gmm, cameras))
    if solve.photo is not None:
        photo = solve.photo
        out["photometric"] = {"cost": photo.cost.value, "blur_deg": list(photo.blur_deg), "bins": photo.n_bins}
    return out
