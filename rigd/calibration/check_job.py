"""``rigd check``: is an existing calibration still right for a dataset's pairs? (calib.drift, docs/check.md)"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

from calib.drift import DriftOptions, DriftResult, GroupChange, check_drift, percent
from calib.errors import CalibError
from calib.geometry import Transform
from calib.pipeline import CalibParams
from rigd.calibration.features import cores, dataset_features
from rigd.calibration.progress import Progress, Stage
from rigd.dataset import Dataset, open_dataset
from rigd.dataset.records import transform_from_yaml, transform_to_yaml
from rigd.dataset.store import read_yaml_mapping
from rigd.dataset.working import WORKING_WIDTH_PX
from rigd.errors import RigdError
from rigd.results import CheckReport, GroupYaml
from rigd.store import Database, VersionStore


def group_lines(rep: CheckReport) -> list[str]:
    """Each judged group's change as a length with the largest the pairs allow and the threshold, in the words
    ``rigd check`` prints (the page words them in its own: rigd/web/words.py)."""
    lines = []
    for name, unit in (("rotation", "deg"), ("translation", "cm")):
        if (g := rep["groups"].get(name)) is not None:
            lines.append(f"{name}: {g['length']:.3g} {unit}, at most {g['upper']:.3g} at "
                         f"{percent(rep['confidence']['ok'])} confidence (threshold {g['threshold']:g})")
    return lines


@dataclass(frozen=True)
class CheckOutcome:
    result: DriftResult
    checked: Transform
    report: CheckReport


def extrinsics_from_file(path: Path) -> Transform:
    """``T_camera_lidar`` of an extrinsics.yaml (or of any YAML holding a transform, or a bare transform)."""
    data = read_yaml_mapping(path)
    return transform_from_yaml(data.get("T_camera_lidar", data), str(path))


def extrinsics_from_store(data_dir: Path, number: int) -> Transform:
    """Version ``number`` of the service's store in ``data_dir`` (read only; the service may be running)."""
    path = Path(data_dir) / "rigd.db"
    if not path.is_file():
        raise RigdError(f"{path}: no rigd store here (give the service's --data-dir)")
    db = Database(path)
    try:
        return VersionStore(db).get(number).T_camera_lidar
    finally:
        db.close()


def _group_yaml(g: GroupChange) -> GroupYaml:
    return {"length": g.length, "upper": g.upper, "threshold": g.threshold, "t2": g.t2, "t2_limit": g.t2_limit}


def check_report(result: DriftResult, checked: Transform, opts: DriftOptions, dataset: Dataset,
                 wall_s: float) -> CheckReport:
    return {
        "status": result.status.value,
        "axes": list(result.axes),
        "reasons": list(result.reasons),
        "change": {"rpy_deg": result.change[:3].tolist(), "xyz_cm": result.change[3:].tolist()},
        "sigma": {"rpy_deg": result.sigma[:3].tolist(), "xyz_cm": result.sigma[3:].tolist()},
        "groups": {g.group.value: _group_yaml(g) for g in result.judgement.groups},
        "places": result.places,
        "thresholds": {"rotation_deg": opts.threshold_rot_deg, "translation_cm": opts.threshold_trans_cm},
        "confidence": {"ok": opts.ok_confidence, "drifted": opts.drift_confidence},
        "checked": transform_to_yaml(checked),
        "found": transform_to_yaml(result.found),
        "dataset": str(dataset.root),
        "pairs": len(dataset),
        "wall_time_s": round(wall_s, 2),
    }


def with_rig_tolerance(opts: DriftOptions, dataset: Dataset) -> DriftOptions:
    """``opts`` with the rig file's field tolerance (if it has one) for the pairs' own verdict, as rigd calibrate."""
    return opts if dataset.rig.tolerance is None else replace(opts, trust=dataset.rig.tolerance)


def run_check(dataset_dir: Path, checked: Transform, opts: DriftOptions,
              progress: Progress | None = None) -> CheckOutcome:
    started = time.monotonic()
    dataset = open_dataset(dataset_dir, WORKING_WIDTH_PX)
    opts = with_rig_tolerance(opts, dataset)
    params = CalibParams()
    # Threads, not processes: the edges' FFTs and OpenCV release the GIL, and a spawned process would first spend
    # about a second importing; the same features either way.
    with ThreadPoolExecutor(max(1, min(cores(), len(dataset)))) as threads:
        feats = dataset_features(dataset, params, progress, threads)
    if progress:
        progress(Stage.AROUND, 0, 1)
    try:
        result = check_drift(feats, checked, params, opts, dataset.rig.prior)
    except CalibError as exc:
        raise RigdError(f"{dataset.root}: {exc}") from exc
    report = check_report(result, checked, opts, dataset, time.monotonic() - started)
    return CheckOutcome(result, checked, report)
