"""The Ladybug5 head calibration (drivers.ladybug5.head) as the head dataset format's camera section
(docs/dataset.md, "A multi-camera head"): what capture writes into a head dataset's rig.yaml."""

from __future__ import annotations

import numpy as np

from calib.geometry import Transform
from drivers.ladybug5.head import HeadCalibration
from rigd.dataset.records import CameraConfig, CameraKind, HeadConfig, SensorConfig


def head_config(head: HeadCalibration, masks: dict[str, str] | None = None) -> HeadConfig:
    """The dataset's ``camera: {model: head, sensors}`` of a head: each sensor its raw image size (px), the fitted
    OpenCV ``K`` (3,3) / ``D`` (5,) and ``T_head_camera`` (m); ``masks`` optionally names a mask file per sensor."""
    sensors = []
    for s in head.sensors:
        matrix = np.eye(4)
        matrix[:3, :3], matrix[:3, 3] = s.R_head_camera, s.t_head_camera_m
        camera = CameraConfig(CameraKind.PINHOLE, s.width, s.height, s.lens.K, s.lens.D, (masks or {}).get(s.name))
        sensors.append(SensorConfig(s.name, camera, Transform.from_matrix(matrix)))
    return HeadConfig(tuple(sensors))
