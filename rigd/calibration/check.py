"""``rigd check``: is an existing calibration still right for a dataset's pairs? (calib.check, docs/check.md)"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from calib.check import DriftOptions, DriftResult, check_drift
from calib.errors import CalibError
from calib.geometry import Transform
from calib.pipeline import CalibParams
from rigd.calibration.service import Progress, dataset_features
from rigd.dataset import open_dataset
from rigd.dataset.records import transform_from_yaml, transform_to_yaml
from rigd.dataset.store import read_yaml_mapping
from rigd.dataset.working import WORKING_WIDTH_PX
from rigd.errors import RigdError
from rigd.store import Database, VersionStore


@dataclass(frozen=True)
class CheckOutcome:
    result: DriftResult
    checked: Transform
    report: dict[str, Any]


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


def run_check(dataset_dir: Path, checked: Transform, opts: DriftOptions,
              progress: Progress | None = None) -> CheckOutcome:
    started = time.monotonic()
    dataset = open_dataset(dataset_dir, WORKING_WIDTH_PX)
    params = CalibParams()
    feats = dataset_features(dataset, params, progress)
    if progress:
        progress("searching around the checked extrinsics", 0.6)
    try:
        result = check_drift(feats, checked, params, opts, dataset.rig.prior)
    except CalibError as exc:
        raise RigdError(f"{dataset.root}: {exc}") from exc
    report: dict[str, Any] = {
        "status": result.status.value,
        "axes": list(result.axes),
        "reasons": list(result.reasons),
        "change": {"rpy_deg": result.change[:3].tolist(), "xyz_cm": result.change[3:].tolist()},
        "sigma": {"rpy_deg": result.sigma[:3].tolist(), "xyz_cm": result.sigma[3:].tolist()},
        "thresholds": {"rotation_deg": opts.threshold_rot_deg, "translation_cm": opts.threshold_trans_cm},
        "checked": transform_to_yaml(checked),
        "found": transform_to_yaml(result.found),
        "dataset": str(dataset.root),
        "pairs": len(dataset),
        "wall_time_s": round(time.monotonic() - started, 2),
    }
    return CheckOutcome(result, checked, report)
