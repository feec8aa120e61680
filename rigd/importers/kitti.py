"""``rigd import kitti``: one camera of a KITTI raw drive as a rigd pinhole dataset.

Source layout (KITTI raw, "synced+rectified"): the drive folder ``DATE_drive_NNNN_sync`` holds
``image_0X/data/NNNNNNNNNN.png`` (X = 0..3, rectified) and ``velodyne_points/data/NNNNNNNNNN.bin`` (float32
x y z reflectance per point, the HDL-64E's points in firing order); ``calib_cam_to_cam.txt`` and
``calib_velo_to_cam.txt`` lie beside the images or in the date folder above. Rectified camera X sees LiDAR
points through ``P_rect_0X R_rect_00 T_cam0_velo``: with ``P_rect_0X = K [I | t]`` its pose is the rectifying
rotation of camera 0 followed by camera X's offset ``t = K^-1 P[:, 3]`` in the rectified frame.

Written: rig.yaml (K of the rectified camera, no distortion), the frames' pairs with their rings recovered from
the firing order, and reference.yaml with KITTI's own calibration (published without an uncertainty).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from calib.geometry import Transform
from rigd.dataset.pcd import Cloud
from rigd.dataset.records import CameraConfig, CameraKind, RigConfig
from rigd.dataset.reference import Reference
from rigd.dataset.store import read_image, write_pair, write_rig, write_yaml
from rigd.errors import DatasetError
from rigd.importers.scan_order import rings_from_scan_order

LIDAR_MODEL = "HDL-64E"
FRAME_NAME = re.compile(r"^(\d{10})\.(png|bin)$")


def read_calib_txt(path: Path) -> dict[str, NDArray[np.float64]]:
    """A KITTI calibration file: ``KEY: numbers`` per line (lines without numbers, e.g. calib_time, skipped)."""
    if not path.is_file():
        raise DatasetError(f"{path}: calibration file is missing")
    out: dict[str, NDArray[np.float64]] = {}
    for line in path.read_text(errors="replace").splitlines():
        key, sep, values = line.partition(":")
        if not sep:
            continue
        try:
            out[key.strip()] = np.array([float(v) for v in values.split()], dtype=np.float64)
        except ValueError:
            continue  # calib_time: 09-Jan-2012 13:57:47
    return out


def _find_calib(drive: Path, name: str) -> Path:
    for folder in (drive, drive.parent):
        if (folder / name).is_file():
            return folder / name
    raise DatasetError(f"{drive}: no {name} beside the drive or in its date folder")


def _get(calib: dict[str, NDArray[np.float64]], key: str, size: int, where: Path) -> NDArray[np.float64]:
    value = calib.get(key)
    if value is None or value.size != size:
        raise DatasetError(f"{where}: needs {key} with {size} numbers")
    return value


def kitti_camera(drive: Path, camera: int) -> tuple[CameraConfig, Transform]:
    """The rectified camera ``camera`` (0..3): its pinhole and ``T_camera_lidar`` from KITTI's calibration."""
    c2c_path, v2c_path = _find_calib(drive, "calib_cam_to_cam.txt"), _find_calib(drive, "calib_velo_to_cam.txt")
    c2c, v2c = read_calib_txt(c2c_path), read_calib_txt(v2c_path)
    P = _get(c2c, f"P_rect_0{camera}", 12, c2c_path).reshape(3, 4)
    R_rect = _get(c2c, "R_rect_00", 9, c2c_path).reshape(3, 3)
    width, height = (int(round(v)) for v in _get(c2c, f"S_rect_0{camera}", 2, c2c_path))
    T_cam0_velo = Transform(_get(v2c, "R", 9, v2c_path).reshape(3, 3), _get(v2c, "T", 3, v2c_path))
    K = P[:, :3].copy()
    baseline = np.asarray(np.linalg.solve(K, P[:, 3]), dtype=np.float64)  # P = K [I | t]
    T = Transform(R_rect, baseline).compose(T_cam0_velo)  # R_rect is a rotation: rectify, then shift
    return CameraConfig(CameraKind.PINHOLE, width, height, K, np.zeros(0)), T


def frame_numbers(drive: Path, camera: int) -> list[int]:
    """The frames with both an image of ``camera`` and a LiDAR sweep, in order."""
    images = drive / f"image_0{camera}" / "data"
    sweeps = drive / "velodyne_points" / "data"
    for folder in (images, sweeps):
        if not folder.is_dir():
            raise DatasetError(f"{folder}: folder is missing (a KITTI raw drive holds image_0X/data and "
                               "velodyne_points/data)")
    have = {int(m.group(1)) for p in images.iterdir() if (m := FRAME_NAME.match(p.name)) and m.group(2) == "png"}
    swept = {int(m.group(1)) for p in sweeps.iterdir() if (m := FRAME_NAME.match(p.name)) and m.group(2) == "bin"}
    both = sorted(have & swept)
    if not both:
        raise DatasetError(f"{drive}: no frame has both an image of camera {camera} and a LiDAR sweep")
    return both


def read_velodyne_bin(path: Path) -> Cloud:
    """A KITTI sweep: float32 x y z reflectance per point, in firing order (rings recovered from it)."""
    if not path.is_file():
        raise DatasetError(f"{path}: LiDAR sweep is missing")
    raw = np.fromfile(path, dtype="<f4")
    if raw.size == 0 or raw.size % 4:
        raise DatasetError(f"{path}: {raw.size * 4} bytes is not a whole number of 16-byte points")
    data = raw.reshape(-1, 4).astype(np.float64)
    keep = np.all(np.isfinite(data), axis=1)
    points = data[keep, :3]
    reflectance = np.clip(data[keep, 3] * 255.0, 0.0, 255.0).astype(np.float32)  # KITTI stores 0..1
    return Cloud(points, reflectance, rings_from_scan_order(points))


def import_kitti(drive: Path, out: Path, camera: int = 2, frames: list[int] | None = None,
                 progress: object = None) -> int:
    """Write the pinhole dataset ``out`` from camera ``camera`` of the KITTI raw drive ``drive``; returns the
    number of pairs. ``frames``: which frames (default all)."""
    drive, out = Path(drive), Path(out)
    if camera not in (0, 1, 2, 3):
        raise DatasetError(f"KITTI has cameras 0-3, got {camera}")
    config, T = kitti_camera(drive, camera)
    available = frame_numbers(drive, camera)
    chosen = available if frames is None else frames
    missing = sorted(set(chosen) - set(available))
    if missing:
        raise DatasetError(f"{drive}: no frame {missing[0]} with an image and a sweep "
                           f"(the drive has {available[0]}-{available[-1]})")
    if out.exists() and any(out.iterdir()):
        raise DatasetError(f"{out}: exists and is not empty; give a new folder")
    write_rig(out, RigConfig(config, LIDAR_MODEL))
    reference = Reference(T, None, Transform.identity(), "KITTI raw calibration (calib_velo_to_cam, calib_cam_to_cam)")
    write_yaml(out / "reference.yaml", reference.to_yaml())
    for index, frame in enumerate(chosen):
        image_path = drive / f"image_0{camera}" / "data" / f"{frame:010d}.png"
        image = read_image(image_path)
        if image.shape[:2] != (config.height, config.width):
            raise DatasetError(f"{image_path}: image is {image.shape[1]}x{image.shape[0]}, S_rect_0{camera} says "
                               f"{config.width}x{config.height}")
        cloud = read_velodyne_bin(drive / "velodyne_points" / "data" / f"{frame:010d}.bin")
        write_pair(out, index, image, cloud, {"source": "kitti_raw", "drive": drive.name, "frame": frame})
        if callable(progress):
            progress(index + 1, len(chosen))
    return len(chosen)
