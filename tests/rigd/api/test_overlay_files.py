"""Which overlay file a request names: one camera's per pair, a multi-camera head's per pair and sensor."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from rigd.api.routes.extrinsics import overlay_path
from rigd.store.errors import NotFoundError


def _fake(tmp_path: Path, names: list[str]) -> tuple[SimpleNamespace, SimpleNamespace]:
    folder = tmp_path / "job" / "calibration" / "overlays"
    folder.mkdir(parents=True)
    for name in names:
        (folder / name).write_bytes(b"png")
    service = SimpleNamespace(jobs=SimpleNamespace(job_dir=lambda job_id: tmp_path / "job"))
    version = SimpleNamespace(number=3, job_id=7, parameters={"pair_numbers": [4, 9]})
    return service, version


def test_a_head_has_overlays_per_sensor_and_one_cloud_per_pair(tmp_path: Path) -> None:
    service, version = _fake(tmp_path, ["0001_cam0_after.png", "0001_cam1_after.png", "0001_cloud.png"])
    assert overlay_path(service, version, 9, "after", "cam1").name == "0001_cam1_after.png"  # type: ignore[arg-type]
    assert overlay_path(service, version, 9, "after").name == "0001_cam0_after.png"  # type: ignore[arg-type]
    assert overlay_path(service, version, 9, "cloud", "cam1").name == "0001_cloud.png"  # type: ignore[arg-type]
    with pytest.raises(NotFoundError, match="0001_cam4_after.png"):
        overlay_path(service, version, 9, "after", "cam4")  # type: ignore[arg-type]


def test_one_camera_keeps_its_file_names(tmp_path: Path) -> None:
    service, version = _fake(tmp_path, ["0000_before.png"])
    assert overlay_path(service, version, 4, "before").name == "0000_before.png"  # type: ignore[arg-type]
    with pytest.raises(NotFoundError, match="no overlay of pair 5"):
        overlay_path(service, version, 5, "before")  # type: ignore[arg-type]
