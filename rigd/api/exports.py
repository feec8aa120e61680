"""Extrinsics versions in other tools' formats (``?format=yaml|json|ros-tf|kalibr|opencv``)."""

from __future__ import annotations

import json
from enum import Enum
from typing import Any

import cv2
import numpy as np
import yaml

from rigd.dataset.records import transform_to_yaml
from rigd.store import ExtrinsicsVersion

YAML = "application/yaml"


class ExportFormat(Enum):
    YAML = "yaml"
    JSON = "json"
    ROS_TF = "ros-tf"
    KALIBR = "kalibr"
    OPENCV = "opencv"


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


def ros_tf(version: ExtrinsicsVersion, camera_frame: str, lidar_frame: str) -> str:
    """A geometry_msgs/TransformStamped (the LiDAR frame's pose in the camera frame) and the command that
    publishes it as a static transform."""
    x, y, z = version.T_camera_lidar.translation_m.tolist()
    qx, qy, qz, qw = version.T_camera_lidar.quaternion_xyzw.tolist()
    command = (f"ros2 run tf2_ros static_transform_publisher --x {x!r} --y {y!r} --z {z!r} --qx {qx!r} --qy {qy!r} "
               f"--qz {qz!r} --qw {qw!r} --frame-id {camera_frame} --child-frame-id {lidar_frame}")
    message = {
        "header": {"frame_id": camera_frame},
        "child_frame_id": lidar_frame,
        "transform": {"translation": {"x": x, "y": y, "z": z}, "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}},
    }
    return f"# rigd extrinsics version {version.number}\n# {command}\n" + yaml.safe_dump(message, sort_keys=False)


def kalibr(version: ExtrinsicsVersion) -> str:
    """Kalibr camchain style: T_cam_lidar maps LiDAR points into cam0, as Kalibr's T_cam_imu does for an IMU."""
    body = {"cam0": {"T_cam_lidar": version.T_camera_lidar.matrix.tolist()}}
    return f"# rigd extrinsics version {version.number}\n" + yaml.safe_dump(body, sort_keys=False)


def opencv(version: ExtrinsicsVersion) -> str:
    """cv::FileStorage YAML (written by OpenCV itself): R (3x3), t (3x1, m), T (4x4), rpy_deg."""
    fs = cv2.FileStorage("extrinsics.yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    T = version.T_camera_lidar
    fs.write("extrinsics_version", version.number)
    fs.write("R", T.rotation)
    fs.write("t", T.translation_m.reshape(3, 1))
    fs.write("T", T.matrix)
    fs.write("rpy_deg", np.asarray(T.rpy_deg).reshape(1, 3))
    return fs.releaseAndGetString()


def render(version: ExtrinsicsVersion, fmt: ExportFormat, camera_frame: str, lidar_frame: str) -> tuple[str, str]:
    """(body, media type) of ``version`` in ``fmt``."""
    if fmt is ExportFormat.JSON:
        return json.dumps(document(version), indent=2) + "\n", "application/json"
    if fmt is ExportFormat.YAML:
        return yaml.safe_dump(document(version), sort_keys=False), YAML
    if fmt is ExportFormat.ROS_TF:
        return ros_tf(version, camera_frame, lidar_frame), YAML
    if fmt is ExportFormat.KALIBR:
        return kalibr(version), YAML
    return opencv(version), YAML
