"""A ROS ``camera_info`` YAML file as the dataset's camera.

Two spellings are read: the message's own fields (``rostopic echo`` / ``ros2 topic echo`` of a
sensor_msgs/CameraInfo: ``width``, ``height``, ``distortion_model``, ``K``/``k``, ``D``/``d``, as the ACFR
cam_lidar_calibration's ``camera_info.yaml``) and camera_calibration_parsers' file (``image_width``,
``image_height``, ``camera_matrix: {data}``, ``distortion_coefficients: {data}``, ``distortion_model``, what
``camera_calibration`` writes). The models map as :func:`rigd.importers.bag.intrinsics.camera_from_info` maps a
bag's message: ``plumb_bob`` -> pinhole, ``equidistant`` (and ``fisheye``) -> OpenCV's fisheye. A
``rational_polynomial`` camera is a pinhole only when its terms k4..k6 are zero: rigd's pinhole has no
denominator, so one with them is refused by name.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from rigd.dataset.records import CameraConfig
from rigd.dataset.store import read_yaml_mapping
from rigd.errors import DatasetError
from rigd.importers.bag.errors import BagError
from rigd.importers.bag.intrinsics import FISHEYE_MODELS, PINHOLE_MODELS, camera_from_info

RATIONAL = "rational_polynomial"


def _first(data: dict[str, Any], path: Path, *keys: str) -> Any:
    """The value of the first of ``keys`` the file has; a ``{data: [...]}`` matrix gives its data."""
    for key in keys:
        if key in data:
            value = data[key]
            return value["data"] if isinstance(value, dict) and "data" in value else value
    raise DatasetError(f"{path}: camera_info has no {' / '.join(keys)}")


def read_camera_info(path: Path) -> CameraConfig:
    """The camera ``path`` describes (its size, K and D), as rig.yaml's camera; DatasetError naming the file and
    the key or model when it is not a camera rigd models."""
    path = Path(path)
    data = read_yaml_mapping(path)
    try:
        message = SimpleNamespace(
            width=int(_first(data, path, "width", "image_width")),
            height=int(_first(data, path, "height", "image_height")),
            distortion_model=str(_first(data, path, "distortion_model")),
            k=np.asarray(_first(data, path, "K", "k", "camera_matrix"), dtype=np.float64).reshape(3, 3),
            d=np.asarray(_first(data, path, "D", "d", "distortion_coefficients"), dtype=np.float64).reshape(-1))
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"{path}: camera_info: width/height must be integers, K 9 numbers, D numbers "
                           f"({exc})") from exc
    model = message.distortion_model
    if model not in PINHOLE_MODELS + FISHEYE_MODELS:
        raise DatasetError(f"{path}: distortion model {model!r} is not supported; rigd reads "
                           f"{', '.join(PINHOLE_MODELS + FISHEYE_MODELS)}")
    if model == RATIONAL and np.any(message.d[5:] != 0.0):
        raise DatasetError(f"{path}: distortion model {RATIONAL} with k4..k6 {message.d[5:8].tolist()} is not "
                           "supported (rigd's pinhole is plumb_bob: k1 k2 p1 p2 k3); recalibrate as plumb_bob")
    if not (message.k[0, 0] > 0 and message.k[1, 1] > 0 and message.width > 0 and message.height > 0):
        raise DatasetError(f"{path}: camera_info without a camera matrix or size (K {message.k.ravel().tolist()}, "
                           f"{message.width}x{message.height}): the camera is not calibrated")
    try:
        return camera_from_info(message, where=str(path))
    except BagError as exc:  # too few distortion terms, a K rigd's camera refuses
        raise DatasetError(str(exc)) from exc
