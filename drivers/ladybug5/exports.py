"""Per-camera images as people have them: rigd's own ``cam0.png`` .. ``cam5.png`` in sensor orientation, or images
exported by FLIR's tools, named with the camera's number (``..._Cam0.jpg``, ``camera_0.png``, ...), turned upright
or not, raw or rectified (``...Rectified...``).

Orientation: a Ladybug5 sensor lies on its side (docs/ladybug5.md: up is towards column 0 of a side camera's raw
image, 2448 wide x 2048 high); an upright export is that image turned 90 degrees clockwise (2048 x 2448), as the
public stream viewers turn it for display. An image whose width and height are the head's swapped is turned back.
Rectified exports are the SDK's rectified pinholes: no distortion, the head file's rectified focal length and
centre (``focal_px``, ``centre_px``) scaled to the exported size; a head without them (a nominal head, or one
read from the 3D map) gets the rectified focal length of public factory calibrations (LADYBUG5_RECTIFIED_FOCAL_PX)
and is then NOMINAL.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import CorruptFrameError
from drivers.ladybug5.head import HeadCalibration, HeadSource, LensFit, SensorCalibration
from drivers.ladybug5.rig import LADYBUG5_RECTIFIED_FOCAL_PX, LADYBUG5_SIZE_PX

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
# the camera's number after "cam" or "camera" (case, separators and leading zeros free), not part of a longer number
_CAMERA = re.compile(r"(?i)(?:^|[^a-z])cam(?:era)?[ _.-]?0*([0-5])(?![0-9])")
_RECTIFIED = re.compile(r"(?i)rectif")
NUM_CAMERAS = 6


class ImageKind(Enum):
    RAW = "raw"  # the sensor's own (distorted) image
    RECTIFIED = "rectified"  # the SDK's rectified pinhole image


class Orientation(Enum):
    SENSOR = "sensor"  # as the sensor reads out (rigd's, and the SDK's raw buffers)
    UPRIGHT = "upright"  # turned 90 degrees clockwise


@dataclass(frozen=True)
class CameraFiles:
    """One frame's six image files in camera order, and what their names say."""

    paths: tuple[Path, ...]
    kind: ImageKind
    flir_names: bool  # named otherwise than rigd's cam0..cam5

    def describe(self) -> str:
        names = f"names like {self.paths[0].name}" if self.flir_names else "rigd's names (cam0..cam5)"
        return f"{self.kind.value} images, {names}"


def camera_number(name: str) -> int | None:
    match = _CAMERA.search(Path(name).stem)
    return int(match.group(1)) if match else None


def find_camera_files(where: Path) -> CameraFiles:
    """The six images of a frame: the files in directory ``where``, or (a frame of a flat export folder) the files
    of ``where``'s folder whose names start with ``where``'s name. Errors name the missing or doubled cameras."""
    if where.is_dir():
        candidates = sorted(where.iterdir())
    else:
        candidates = sorted(where.parent.glob(f"{where.name}*"))
    by_camera: dict[int, list[Path]] = {}
    for path in candidates:
        number = camera_number(path.name) if path.suffix.lower() in IMAGE_SUFFIXES else None
        if number is not None:
            by_camera.setdefault(number, []).append(path)
    missing = [c for c in range(NUM_CAMERAS) if c not in by_camera]
    doubled = {c: paths for c, paths in by_camera.items() if len(paths) > 1}
    if missing or doubled:
        said = [f"no cam{c} image" for c in missing]
        said += [f"camera {c} in {len(p)} files ({', '.join(x.name for x in p)})" for c, p in doubled.items()]
        raise CorruptFrameError(f"{where}: {'; '.join(said)} (six images named with cam0..cam5 or "
                                f"Camera0..Camera5, {'/'.join(IMAGE_SUFFIXES)})")
    paths = tuple(by_camera[c][0] for c in range(NUM_CAMERAS))
    kinds = {ImageKind.RECTIFIED if _RECTIFIED.search(p.name) else ImageKind.RAW for p in paths}
    if len(kinds) > 1:
        raise CorruptFrameError(f"{where}: raw and rectified images mixed in one frame "
                                f"({', '.join(p.name for p in paths)})")
    flir = any(p.stem.lower() != f"cam{c}" for c, p in enumerate(paths))
    return CameraFiles(paths, kinds.pop(), flir)


def to_sensor_orientation(image: NDArray[Any], size_px: tuple[int, int], kind: ImageKind) -> tuple[NDArray[Any],
                                                                                                 Orientation]:
    """``image`` turned back to the sensor's orientation when it is upright. ``size_px`` (width, height) is the
    head's sensor: a raw image is upright when it has that size the other way round (any other size is left for the
    caller's size check); a rectified one (any size) when its aspect is the other way round."""
    height, width = image.shape[:2]
    if kind is ImageKind.RAW:
        upright = (width, height) == (size_px[1], size_px[0]) and size_px[0] != size_px[1]
    else:
        upright = (width > height) != (size_px[0] > size_px[1])
    if not upright:
        return image, Orientation.SENSOR
    return np.ascontiguousarray(np.rot90(image, 1)), Orientation.UPRIGHT


def _rectified_sensor(sensor: SensorCalibration, size_px: tuple[int, int]) -> tuple[SensorCalibration, bool]:
    """The sensor's rectified pinhole at ``size_px`` and whether its focal length is the head's own."""
    own = math.isfinite(sensor.focal_px) and all(math.isfinite(c) for c in sensor.centre_px)
    focal = sensor.focal_px if own else LADYBUG5_RECTIFIED_FOCAL_PX * sensor.width / LADYBUG5_SIZE_PX[0]
    centre = sensor.centre_px if own else ((sensor.width - 1) / 2.0, (sensor.height - 1) / 2.0)
    sx, sy = size_px[0] / sensor.width, size_px[1] / sensor.height
    k = np.array([[focal * sx, 0.0, (centre[0] + 0.5) * sx - 0.5], [0.0, focal * sy, (centre[1] + 0.5) * sy - 0.5],
                  [0.0, 0.0, 1.0]])
    lens = LensFit(k, np.zeros(5), 0.0, 0.0, 0, False)
    return replace(sensor, width=size_px[0], height=size_px[1], focal_px=float(k[0, 0]),
                   centre_px=(float(k[0, 2]), float(k[1, 2])), lens=lens, maps=None), own


def rectified_head(head: HeadCalibration, size_px: tuple[int, int]) -> HeadCalibration:
    """The head of rectified images of ``size_px`` (width, height): each sensor's rectified pinhole, its pose."""
    pairs = [_rectified_sensor(s, size_px) for s in head.sensors]
    own = all(o for _, o in pairs)
    source = head.source if own else HeadSource.NOMINAL
    focal = "" if own else (f" with the rectified focal length of public factory calibrations "
                            f"({LADYBUG5_RECTIFIED_FOCAL_PX:.0f} px at 2448 px; the head has none)")
    return HeadCalibration(tuple(s for s, _ in pairs), source,
                           f"rectified images {size_px[0]}x{size_px[1]} of {head.description}{focal}", head.serial)
