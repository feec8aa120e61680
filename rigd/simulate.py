"""Write a simulated dataset: arrays from drivers.sim, files through rigd.dataset."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from calib.geometry import Transform
from drivers.sim import (
    RINGS64_ELEVATIONS_DEG,
    Footprint,
    LidarConfig,
    PinholeSpec,
    Pose,
    SceneKind,
    SimConfig,
    SimRig,
    StitchConfig,
    ladybug_like_head,
    scene_kind,
)
from rigd.dataset import CameraConfig, CameraKind, Cloud, RigConfig, write_ground_truth, write_pair, write_rig
from rigd.dataset.records import HeadConfig, SensorConfig
from rigd.errors import DatasetError, RigdError

JPEG_QUALITY = 85  # a moderate Ladybug5 stream setting: blocking and ringing at edges
# --camera pinhole: a forward camera like the pinhole sample's (1920x1200, f 2150 px: 48 x 31 deg) below a
# level LiDAR, as on a car's roof: the LiDAR 0.35 m above the camera and 0.10 m behind it, turned a little.
PINHOLE = PinholeSpec(np.array([[2150.0, 0.0, 959.5], [0.0, 2150.0, 599.5], [0.0, 0.0, 1.0]]), 1920, 1200)
PINHOLE_T_CAMERA_LIDAR = Pose.from_rpy_xyz((0.6, -0.8, 1.2), (-0.10, 0.03, 0.35))  # panorama frame
DETECT_RANGE_M = 60.0  # with dropouts: a 10 % target's detection range (an assumption, drivers.sim.LidarConfig)


def write_simulated_dataset(out_dir: Path, kind: str, pairs: int, seed: int, width: int = 1024,
                            height: int = 512, range_noise_m: float = 0.02, progress: bool = True,
                            sensor_effects: bool = False, dropouts: bool = False, trees: bool = False,
                            pinhole: bool = False, rings64: bool = False, head: bool = False) -> Path:
    """Simulate ``pairs`` pairs (pair i = location i of dataset ``seed``) into the new dataset ``out_dir``.

    Writes rig.yaml (equirectangular ``width`` x ``height``, VLP-16), ground_truth.yaml (the simulator's
    T_camera_lidar) and pairs/NNNN. Refuses an existing non-empty directory. ``sensor_effects``: the
    stitched Ladybug5 sensors, JPEG images and the VLP-16's beam footprint (docs/simulator.md). ``dropouts``:
    energy-limited returns (dark ground at grazing incidence drops out; the same seed's other returns are
    unchanged). ``trees``: rows of street trees in outdoor scenes (the rest of each scene unchanged).
    ``pinhole``: a forward pinhole camera (:data:`PINHOLE`) below a level LiDAR instead of the panorama rig
    (``width`` and ``height`` are then unused; sensor effects are JPEG and the beam footprint). ``rings64``:
    a 64-ring street LiDAR (drivers.sim.RINGS64_ELEVATIONS_DEG) in place of the VLP-16. ``head``: the five
    side sensors of a Ladybug5 head as pinholes, ``width`` x ``height`` px each, lying on their side as a real
    head's (drivers.sim.ladybug_like_head, images/camK.png) instead of the panorama, the ground truth
    T_head_lidar (sensor effects are then JPEG and the beam footprint).
    """
    out = Path(out_dir)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise DatasetError(f"{out}: already exists and is not empty; refusing to overwrite it "
                           "(give a new or empty directory)")
    if pairs < 1:
        raise RigdError(f"--pairs must be at least 1, got {pairs}")
    sim_kind = scene_kind(kind)
    if trees and sim_kind is not SceneKind.OUTDOOR:
        raise RigdError("--trees needs --scene outdoor: street trees line a street")
    footprint = Footprint() if sensor_effects else None
    lidar = LidarConfig(range_noise_m=range_noise_m, footprint=footprint,
                        detect_range_m=DETECT_RANGE_M if dropouts else None,
                        elevations_deg=RINGS64_ELEVATIONS_DEG if rings64 else None)
    camera: CameraConfig | HeadConfig
    if pinhole and head:
        raise RigdError("--camera is a pinhole or a head, not both")
    if pinhole:
        config = SimConfig(T_camera_lidar=PINHOLE_T_CAMERA_LIDAR, lidar=lidar, pinhole=PINHOLE, trees=trees,
                           jpeg_quality=JPEG_QUALITY if sensor_effects else None)
        camera = CameraConfig(CameraKind.PINHOLE, PINHOLE.width, PINHOLE.height, PINHOLE.K, np.zeros(0))
    elif head:
        sensors = ladybug_like_head(width, height)
        config = SimConfig(lidar=lidar, head=sensors, trees=trees,
                           jpeg_quality=JPEG_QUALITY if sensor_effects else None)
        camera = HeadConfig(tuple(SensorConfig(s.name, CameraConfig(CameraKind.PINHOLE, s.width, s.height, s.K,
                                                                    np.zeros(0)),
                                               Transform.from_matrix(s.T_head_sensor.matrix)) for s in sensors))
    else:
        config = SimConfig(width=width, height=height, lidar=lidar, stitch=StitchConfig() if sensor_effects else None,
                           jpeg_quality=JPEG_QUALITY if sensor_effects else None, trees=trees)
        camera = CameraConfig(CameraKind.EQUIRECTANGULAR, width, height)
    rig = SimRig(config)
    # the simulated beams are where the table says: their elevation offset is known exactly (0)
    write_rig(out, RigConfig(camera, "64-ring" if rings64 else "VLP-16", lidar_elevation_sigma_declared_deg=0.0))
    write_ground_truth(out, Transform.from_matrix(config.T_image_lidar.matrix))
    for index in tqdm(range(pairs), desc=f"simulate {sim_kind.value}", unit="pair", file=sys.stderr,
                      disable=not progress):
        cap = rig.capture(sim_kind, seed, index)
        sweep = cap.sweep
        images = dict(zip(camera.view_names, cap.images, strict=True)) if cap.images else cap.image
        write_pair(out, index, images, Cloud(sweep.points_lidar, sweep.intensity, sweep.ring), cap.meta)
    return out
