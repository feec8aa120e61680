"""Extrinsics versions in other tools' formats (``?format=yaml|json|ros-tf|ros2-launch|urdf|kalibr|opencv``); the
transform formats themselves are rigd.exports', which ``rigd export`` uses too."""

from __future__ import annotations

import json
from typing import Any

import yaml

from rigd.dataset.records import transform_to_yaml
from rigd.exports import ExportFormat, render_transform
from rigd.store import ExtrinsicsVersion

__all__ = ["ExportFormat", "document", "download_name", "render"]

YAML = "application/yaml"
MEDIA_TYPES = {ExportFormat.JSON: "application/json", ExportFormat.ROS2_LAUNCH: "text/x-python",
               ExportFormat.URDF: "application/xml"}
# A download's file name ends as its format is read: a launch file is Python, a URDF joint .urdf; the rest YAML.
EXTENSIONS = {ExportFormat.JSON: "json", ExportFormat.ROS2_LAUNCH: "launch.py", ExportFormat.URDF: "urdf"}


def download_name(number: int, fmt: ExportFormat) -> str:
    """The file name a download of extrinsics version ``number`` in ``fmt`` is offered under."""
    return f"extrinsics-v{number}-{fmt.value}.{EXTENSIONS.get(fmt, 'yaml')}"


def document(version: ExtrinsicsVersion) -> dict[str, Any]:
    """rigd's own export: the transform in all four forms plus where it came from."""
    return {
        "extrinsics_version": version.number,
        "status": version.status.value,
        "created_at": version.created_at,
        "convention": "p_camera = R p_lidar + t (T_camera_lidar; rpy_deg: R = Rz(yaw) Ry(pitch) Rx(roll))",
        "T_camera_lidar": transform_to_yaml(version.T_camera_lidar),
        "method": version.method,
        "dataset_id": version.dataset_id,
        "dataset_hash": version.dataset_hash,
        "code_version": version.code_version,
    }


def render(version: ExtrinsicsVersion, fmt: ExportFormat, camera_frame: str, lidar_frame: str) -> tuple[str, str]:
    """(body, media type) of ``version`` in ``fmt``."""
    media_type = MEDIA_TYPES.get(fmt, YAML)
    if fmt is ExportFormat.JSON:
        return json.dumps(document(version), indent=2) + "\n", media_type
    if fmt is ExportFormat.YAML:
        return yaml.safe_dump(document(version), sort_keys=False), media_type
    body = render_transform(version.T_camera_lidar, fmt, label=f"extrinsics version {version.number}",
                            camera_frame=camera_frame, lidar_frame=lidar_frame, version=version.number)
    return body, media_type
