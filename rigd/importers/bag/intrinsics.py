"""sensor_msgs/CameraInfo as the dataset's camera: ``plumb_bob`` (and ``rational_polynomial`` without its
extra terms) -> pinhole ``K``, ``D = [k1, k2, p1, p2, k3]``; ``equidistant`` -> fisheye ``D = [k1..k4]``
(OpenCV's cv2.fisheye model, the one rigd's fisheye camera is). ROS 1 spells the fields K, D; ROS 2 k, d."""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.dataset.records import CameraConfig, CameraKind
from rigd.errors import DatasetError
from rigd.importers.bag.errors import BagError

PINHOLE_MODELS = ("plumb_bob", "rational_polynomial")
FISHEYE_MODELS = ("equidistant", "fisheye")


def _field(message: Any, name: str) -> Any:
    return getattr(message, name.lower()) if hasattr(message, name.lower()) else getattr(message, name.upper())


def camera_from_info(message: Any, *, where: str) -> CameraConfig:
    """The camera a CameraInfo describes, at the size it gives (``width`` x ``height`` px)."""
    model = str(message.distortion_model)
    K = np.asarray(_field(message, "k"), dtype=np.float64).reshape(3, 3)
    D = np.asarray(_field(message, "d"), dtype=np.float64).ravel()
    width, height = int(message.width), int(message.height)
    if not (K[0, 0] > 0 and K[1, 1] > 0 and width > 0 and height > 0):
        raise BagError(f"{where}: CameraInfo without a camera matrix or size (K {K.ravel().tolist()}, "
                       f"{width}x{height}): the camera is not calibrated; give --rig")
    if model in PINHOLE_MODELS:
        kind, D = CameraKind.PINHOLE, D[:5]
    elif model in FISHEYE_MODELS:
        kind, D = CameraKind.FISHEYE, D[:4]
        if len(D) != 4:
            raise BagError(f"{where}: an equidistant CameraInfo needs 4 distortion terms, got {len(D)}")
    else:
        raise BagError(f"{where}: unknown distortion model {model!r}; rigd reads "
                       f"{', '.join(PINHOLE_MODELS + FISHEYE_MODELS)} (or give --rig)")
    config = CameraConfig(kind, width, height, K, D)
    try:
        CameraConfig.from_yaml(config.to_yaml(), where)
    except DatasetError as exc:
        raise BagError(str(exc)) from exc
    return config
