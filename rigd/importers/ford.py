"""``rigd import ford``: the Ford Campus sample (Ladybug3 + HDL-64E, Pandey et al.) as a rigd dataset.

Source layout (docs/dataset.md, "Importing"): ``camN/imageSSSS.jpg`` (N = 0..4), ``masks/camN.png``,
``scans/scanSSSS.pcd`` (x y z intensity, laser by laser in firing order) and ``head.yaml`` (each camera's
pinhole K and its pose in the head ``X_hc``, the reference pose of the LiDAR in the head ``X_hl`` with its
covariance, and a starting guess). Poses there are ``[x, y, z, roll, pitch, heading]``, frame b in frame a:
``p_a = R p_b + t`` with ``R = Rz(heading) Ry(pitch) Rx(roll)``, the same convention as rigd's rpy_deg.

Written: a head dataset (the five cameras as sensors with their masks), or with ``camera`` one sensor as a
pinhole dataset, or with ``panorama_width`` the five stitched into one equirectangular panorama by rigd's own
stitching (drivers.ladybug5.stitch, from the head calibration; what a stitched Ladybug stream gives); the
clouds with their rings (:mod:`rigd.importers.scan_order`); ``reference.yaml`` with the published pose as
T_camera_lidar (the head's, or the one camera's) and its one-sigma per axis of the head form
(:mod:`rigd.dataset.reference`).
"""

from __future__ import annotations

import re
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from calib.geometry import Transform
from drivers.ladybug5.rig import RigCamera, RigCameras
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher
from rigd.dataset.pcd import Cloud, read_pcd
from rigd.dataset.records import CameraConfig, CameraKind, HeadConfig, RigConfig, SensorConfig
from rigd.dataset.reference import Reference
from rigd.dataset.store import read_image, read_mask, read_yaml_mapping, write_pair, write_rig, write_yaml
from rigd.errors import DatasetError
from rigd.importers.scan_order import rings_from_scan_order

SCAN_NAME = re.compile(r"^scan(\d{4})\.pcd$")
LIDAR_MODEL = "HDL-64E"
# The release states no accuracy for the Ladybug SDK's rectified K. Against the LiDAR the stored images sit about
# 2.5 px off in cx, alike in every camera (docs/results.md): a single camera carries 1 px at 1 sigma.
PRINCIPAL_POINT_SIGMA_PX = 1.0


@dataclass(frozen=True)
class FordHead:
    """``head.yaml`` read: the sensors (their K, size and pose), the reference ``T_head_lidar`` with its
    one-sigma per axis (x, y, z m; roll, pitch, heading deg) and the release's starting guess."""

    sensors: tuple[SensorConfig, ...]
    reference: Transform
    reference_sigma: NDArray[np.float64]
    guess: Transform


def _pose(values: Any, degrees: bool, where: str) -> Transform:
    try:
        x = np.asarray(values, dtype=np.float64).reshape(6)
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"{where}: a pose needs [x, y, z, roll, pitch, heading], got {values!r}") from exc
    rpy = x[3:] if degrees else np.degrees(x[3:])
    return Transform.from_rpy_xyz(rpy, x[:3])


def read_head(path: Path) -> FordHead:
    """``head.yaml`` of the Ford sample; DatasetError naming the file and key when it is not as documented."""
    data = read_yaml_mapping(path)
    where = str(path)
    try:
        width, height = (int(v) for v in data["image_size"])
        sensors = []
        for name, cam in data["cameras"].items():
            k = np.array([[cam["focal_length"] * cam["scale_x"], 0.0, cam["cx"]],
                          [0.0, cam["focal_length"] * cam["scale_y"], cam["cy"]], [0.0, 0.0, 1.0]])
            sensors.append(SensorConfig(str(name), CameraConfig(CameraKind.PINHOLE, width, height, k, np.zeros(0),
                                                                f"masks/{name}.png", PRINCIPAL_POINT_SIGMA_PX),
                                        _pose(cam["X_hc"], True, f"{where}: cameras.{name}.X_hc")))
        ref = data["head_lidar_reference"]
        covariance = np.asarray(ref["covariance"], dtype=np.float64).reshape(6, 6)
        reference = _pose(ref["pose"], False, f"{where}: head_lidar_reference.pose")
        guess = _pose(data["initial_guess_head_lidar"], True, f"{where}: initial_guess_head_lidar")
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise DatasetError(f"{where}: not the Ford sample's head file ({exc!r})") from exc
    sigma = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    sigma[3:] = np.degrees(sigma[3:])
    return FordHead(tuple(sensors), reference, sigma, guess)


def scan_numbers(src: Path) -> list[int]:
    """The scans the source holds (scans/scanSSSS.pcd), in order."""
    folder = src / "scans"
    if not folder.is_dir():
        raise DatasetError(f"{folder}: no scans folder (the Ford sample has scans/scanSSSS.pcd)")
    found = sorted(int(m.group(1)) for p in folder.iterdir() if (m := SCAN_NAME.match(p.name)))
    if not found:
        raise DatasetError(f"{folder}: holds no scanSSSS.pcd")
    return found


def _cloud(path: Path) -> Cloud:
    """A scan with its rings recovered from the firing order (its intensity kept)."""
    cloud = read_pcd(path)
    ring = cloud.ring if cloud.ring is not None else rings_from_scan_order(cloud.points_lidar)
    return Cloud(cloud.points_lidar, cloud.intensity, ring)


def _reference(T: Transform, head: FordHead, T_head_camera: Transform) -> Reference:
    return Reference(T, head.reference_sigma, T_head_camera,
                     "Pandey et al., Ford Campus data (IJRR 2011): MI calibration, head.yaml head_lidar_reference")


def _stitcher(src: Path, head: FordHead, width: int) -> Stitcher:
    """rigd's own stitching (drivers.ladybug5.stitch) of the five cameras, from the head calibration and the
    masks, onto a ``width`` x ``width / 2`` panorama of the head frame at the SDK's 20 m sphere."""
    cameras = tuple(RigCamera(s.name, s.camera.width, s.camera.height, np.asarray(s.camera.K), np.zeros(5),
                              s.T_head_camera.rotation, s.T_head_camera.translation_m) for s in head.sensors)
    masks = [read_mask(src / str(s.camera.mask), (s.camera.height, s.camera.width)) for s in head.sensors]
    return Stitcher(RigCameras("Ladybug3", cameras), PanoramaSpec(width, width // 2), masks)


def import_ford(src: Path, out: Path, camera: str | None = None, scans: list[int] | None = None,
                progress: Any = None, panorama_width: int | None = None) -> int:
    """Write the dataset ``out`` from the Ford sample at ``src``; returns the number of pairs. ``camera``: one
    sensor (cam0..cam4) as a pinhole dataset; ``panorama_width``: the five stitched into one equirectangular
    panorama of that width (the way a stitched Ladybug stream is calibrated); neither: the whole head.
    ``scans``: which scans (default all)."""
    src, out = Path(src), Path(out)
    head = read_head(src / "head.yaml")
    names = [s.name for s in head.sensors]
    if camera is not None and camera not in names:
        raise DatasetError(f"{src / 'head.yaml'}: no camera {camera!r} (the head has {', '.join(names)})")
    if camera is not None and panorama_width is not None:
        raise DatasetError("one camera or a stitched panorama, not both")
    available = scan_numbers(src)
    chosen = available if scans is None else scans
    missing = sorted(set(chosen) - set(available))
    if missing:
        raise DatasetError(f"{src / 'scans'}: no scan {missing[0]:04d} (it holds {available[0]}-{available[-1]})")
    if out.exists() and any(out.iterdir()):
        raise DatasetError(f"{out}: exists and is not empty; give a new folder")
    sensors = [s for s in head.sensors if camera is None or s.name == camera]
    stitcher = None if panorama_width is None else _stitcher(src, head, panorama_width)
    _write_rig(src, out, head, sensors, camera is not None, stitcher)
    for index, scan in enumerate(chosen):
        images = {s.name: src / s.name / f"image{scan:04d}.jpg" for s in sensors}
        arrays = {name: read_image(path) for name, path in images.items()}  # a missing or corrupt image fails here
        cloud = _cloud(src / "scans" / f"scan{scan:04d}.pcd")
        meta = {"source": "ford_campus", "scan": scan}
        if stitcher is not None:
            meta["stitched"] = {"sphere_radius_m": stitcher.spec.radius_m}
            write_pair(out, index, stitcher.stitch([arrays[s.name] for s in head.sensors]), cloud, meta)
        elif camera is None:
            write_pair(out, index, dict(images), cloud, meta)
        else:
            write_pair(out, index, arrays[camera], cloud, meta)
        if progress:
            progress(index + 1, len(chosen))
    return len(chosen)


def _write_rig(src: Path, out: Path, head: FordHead, sensors: list[SensorConfig], single: bool,
               stitcher: Stitcher | None) -> None:
    """rig.yaml, the masks, and reference.yaml (the head's pose, or the one camera's)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "masks").mkdir(exist_ok=True)
    if stitcher is not None:
        cv2.imwrite(str(out / "masks" / "panorama.png"), np.where(stitcher.coverage, 255, 0).astype(np.uint8))
        panorama = CameraConfig(CameraKind.EQUIRECTANGULAR, stitcher.spec.width, stitcher.spec.height,
                                mask="masks/panorama.png")
        write_rig(out, RigConfig(panorama, LIDAR_MODEL, head.guess))
        write_yaml(out / "reference.yaml", _reference(head.reference, head, Transform.identity()).to_yaml())
        return
    for s in sensors:
        assert s.camera.mask is not None
        if not (src / s.camera.mask).is_file():
            raise DatasetError(f"{src / s.camera.mask}: mask file is missing")
        shutil.copyfile(src / s.camera.mask, out / s.camera.mask)
    if single:
        sensor = sensors[0]
        to_camera = sensor.T_head_camera.inverse()
        rig = RigConfig(sensor.camera, LIDAR_MODEL, to_camera.compose(head.guess))
        reference = _reference(to_camera.compose(head.reference), head, sensor.T_head_camera)
    else:
        rig = RigConfig(HeadConfig(tuple(sensors)), LIDAR_MODEL, head.guess)
        reference = _reference(head.reference, head, Transform.identity())
    write_rig(out, rig)
    write_yaml(out / "reference.yaml", reference.to_yaml())
