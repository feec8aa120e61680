"""The simulated rig: box scenes, a ray caster, a Ladybug5-like panorama camera and a VLP-16 (docs/simulator.md).

Everything here is numpy arrays; writing datasets is rigd's job (rigd/simulate.py).
"""

from drivers.sim.camera import ROTATION_PANORAMA_OPTICAL, render_panorama, render_pinhole, render_rays
from drivers.sim.errors import SimError
from drivers.sim.lidar import LASER_ELEVATIONS_DEG, RINGS64_ELEVATIONS_DEG, Footprint, LidarConfig, Sweep, scan
from drivers.sim.pose import Pose
from drivers.sim.raycast import Hits, cast
from drivers.sim.rig import (
    PAPER_T_CAMERA_LIDAR,
    HeadSensorSpec,
    PinholeSpec,
    SimCapture,
    SimConfig,
    SimRig,
    head_sensor_height,
    ladybug_like_head,
    make_scene,
    scene_kind,
    simulate_pair,
)
from drivers.sim.scene import Face, Lighting, Scene, SceneBuilder, SceneKind
from drivers.sim.stitched import StitchConfig

__all__ = [
    "LASER_ELEVATIONS_DEG",
    "PAPER_T_CAMERA_LIDAR",
    "RINGS64_ELEVATIONS_DEG",
    "ROTATION_PANORAMA_OPTICAL",
    "Face",
    "Footprint",
    "HeadSensorSpec",
    "Hits",
    "LidarConfig",
    "Lighting",
    "PinholeSpec",
    "Pose",
    "Scene",
    "SceneBuilder",
    "SceneKind",
    "SimCapture",
    "SimConfig",
    "head_sensor_height",
    "ladybug_like_head",
    "SimError",
    "SimRig",
    "StitchConfig",
    "Sweep",
    "cast",
    "make_scene",
    "render_panorama",
    "render_pinhole",
    "render_rays",
    "scan",
    "scene_kind",
    "simulate_pair",
]
