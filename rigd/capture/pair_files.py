"""What a captured pair's camera side is on disk: a panorama dataset's ``image.png``, or, when the camera gives its
raw sensor images, the head dataset format (docs/dataset.md): ``images/camN.png`` per sensor, rig.yaml's camera
the head calibration they go with (rigd.ladybug_head), and the panorama they were stitched from beside them as
``panorama.png`` (for people; calibration reads the sensors)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from rigd.capture.sources import CameraFrame
from rigd.dataset import CameraConfig, CameraKind
from rigd.dataset.records import HeadConfig
from rigd.ladybug_head import head_config

PANORAMA_FILE = "panorama.png"
_POSE_ATOL = 1e-9  # rig.yaml's poses round-trip through rpy_deg and xyz_m


def rig_camera(frame: CameraFrame) -> CameraConfig | HeadConfig:
    """rig.yaml's camera for pairs of ``frame``'s kind: the head of its sensor images, else its panorama size."""
    if frame.sensors is not None:
        return head_config(frame.sensors.head)
    height, width = frame.panorama.image.shape[:2]
    return CameraConfig(CameraKind.EQUIRECTANGULAR, width, height)


def pair_images(frame: CameraFrame) -> tuple[NDArray[Any] | dict[str, NDArray[Any]], dict[str, NDArray[Any]]]:
    """(the pair's image or its images by sensor name, extra images by file name) for rigd.dataset.write_pair."""
    if frame.sensors is None:
        return frame.panorama.image, {}
    names = [s.name for s in frame.sensors.head.sensors]
    return dict(zip(names, frame.sensors.images, strict=True)), {PANORAMA_FILE: frame.panorama.image}


def pair_bytes(frame: CameraFrame) -> int:
    """The uncompressed size of the pair's images, bytes."""
    sensors = 0 if frame.sensors is None else sum(im.nbytes for im in frame.sensors.images)
    return int(frame.panorama.image.nbytes + sensors)


def camera_difference(written: CameraConfig | HeadConfig, capturing: CameraConfig | HeadConfig) -> str | None:
    """Why pairs of ``capturing`` cannot join a dataset whose rig.yaml has ``written``, or None when they can:
    another kind, size, sensor set or head calibration."""
    if written.kind is not capturing.kind:
        return f"its camera is {written.kind.value}, the camera gives {capturing.kind.value} images"
    if not isinstance(written, HeadConfig) or not isinstance(capturing, HeadConfig):
        if (written.width, written.height) != (capturing.width, capturing.height):
            return f"says {written.width}x{written.height} but the camera gives {capturing.width}x{capturing.height}"
        return None
    had, gives = _sensor_sizes(written), _sensor_sizes(capturing)
    if had != gives:
        return f"has sensors {', '.join(had)}, the camera gives {', '.join(gives)}"
    for old, new in zip(written.sensors, capturing.sensors, strict=True):
        if not _same_sensor(old.camera, new.camera) or not np.allclose(
                old.T_head_camera.matrix, new.T_head_camera.matrix, atol=_POSE_ATOL):
            return f"sensor {old.name}'s calibration differs from the head the camera's frames go with"
    return None


def _sensor_sizes(head: HeadConfig) -> list[str]:
    return [f"{s.name} {s.camera.width}x{s.camera.height}" for s in head.sensors]


def _same_sensor(a: CameraConfig, b: CameraConfig) -> bool:
    arrays = [(a.K, b.K), (a.D, b.D)]
    return all(x is None and y is None or x is not None and y is not None and x.shape == y.shape
               and bool(np.allclose(x, y, atol=_POSE_ATOL)) for x, y in arrays)
