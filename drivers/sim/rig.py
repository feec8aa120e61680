"""The simulated rig: a Ladybug5-like panorama camera and a VLP-16 on one frame, captured at many places.

Every pair is a new location: the scene is generated from (kind, seed, pair index) and the rig stands at
a random free spot with a random heading. The camera is mounted upright (its z axis up, up to a few
degrees of roll/pitch from an imperfectly levelled tripod); the LiDAR hangs below it, tilted, as given by
the ground truth ``T_camera_lidar``: ``T_world_lidar = T_world_camera @ T_camera_lidar``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.rig import LADYBUG5_SIZE_PX, default_ladybug5_rig
from drivers.sim.camera import ROTATION_PANORAMA_OPTICAL, jpeg_round_trip, render_panorama, render_pinhole
from drivers.sim.errors import SimError
from drivers.sim.indoor import indoor_scene
from drivers.sim.lidar import LidarConfig, Sweep, scan
from drivers.sim.outdoor import outdoor_scene
from drivers.sim.pose import Pose
from drivers.sim.scene import Scene, SceneKind
from drivers.sim.stitched import StitchConfig

# Kang & Doh 2020, Table 2, indoor dataset, GMM: roll, pitch, yaw (deg) and t (m).
PAPER_T_CAMERA_LIDAR = Pose.from_rpy_xyz((-0.18, 15.47, -55.14), (0.0934, 0.0597, -0.1659))

RIG_HALF_WIDTH_M = 0.35  # footprint of the tripod and sensor head
SENSOR_CLEARANCE_M = 0.8  # nearest surface allowed around either sensor when the rig is placed
MAX_TILT_DEG = 3.0
_PLACEMENT_TRIES = 500
F64 = NDArray[np.float64]
_STREAMS = {"scene": 0, "pose": 1, "camera": 2, "lidar": 3, "vegetation": 4}


@dataclass(frozen=True)
class PinholeSpec:
    """A pinhole camera in place of the panorama, looking along the panorama's forward axis (x): ``K`` (3,3)
    px, image ``width`` x ``height`` px, no distortion. Its frame is the OpenCV optical frame."""

    K: F64
    width: int
    height: int


@dataclass(frozen=True)
class HeadSensorSpec:
    """One sensor of a simulated multi-camera head: its pinhole ``K`` (3,3) px and size (no distortion), and
    ``T_head_sensor``, its optical frame in the head (= the panorama camera's) frame."""

    name: str
    K: F64
    width: int
    height: int
    T_head_sensor: Pose


def head_sensor_height(width: int) -> int:
    """The height px of a simulated head sensor ``width`` px wide: the Ladybug5's 2448:2048 aspect."""
    return max(1, round(width * LADYBUG5_SIZE_PX[1] / LADYBUG5_SIZE_PX[0]))


def ladybug_like_head(width: int = 512, height: int | None = None,
                      hfov_deg: float = 80.0) -> tuple[HeadSensorSpec, ...]:
    """The five side sensors of a Ladybug5 as pinholes, at the poses of rigd's nominal head
    (drivers.ladybug5.rig.default_ladybug5_rig: optical axes level at azimuths 0, -72, ... -288 deg, 6.1 cm out
    along them, lying on their side as the real sensors do: image columns down, rows along the horizontal). Images
    ``width`` x ``height`` px (default height: the Ladybug5's 2448:2048 aspect), ``hfov_deg`` of field across the
    rows, i.e. the head's horizontal (neighbours overlap by 8 deg), no distortion."""
    rows = head_sensor_height(width) if height is None else height
    f = (rows / 2) / np.tan(np.radians(hfov_deg / 2))
    K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (rows - 1) / 2], [0.0, 0.0, 1.0]])
    side = default_ladybug5_rig((width, rows)).cameras[:5]
    return tuple(HeadSensorSpec(c.name, K, width, rows, Pose(c.R_head_camera, c.t_head_camera_m)) for c in side)


@dataclass(frozen=True)
class SimConfig:
    """Sensor settings of the simulated rig: panorama size, noise figures, ground truth extrinsics."""

    width: int = 1024
    height: int = 512
    T_camera_lidar: Pose = field(default_factory=lambda: PAPER_T_CAMERA_LIDAR)
    lidar: LidarConfig = field(default_factory=LidarConfig)
    image_noise_grey: float = 1.5
    supersample: int = 2
    color: bool = False
    stitch: StitchConfig | None = None  # None: one projection centre; else the stitched sensors' effects
    jpeg_quality: int | None = None  # None: the image as rendered; else JPEG-compressed at this quality
    trees: bool = False  # outdoor scenes get rows of street trees (drivers.sim.vegetation)
    pinhole: PinholeSpec | None = None  # None: the panorama; else this pinhole camera (width/height unused)
    head: tuple[HeadSensorSpec, ...] | None = None  # else: these sensors of a head (width/height unused)

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0 or self.supersample <= 0:
            raise SimError(f"panorama size and supersampling must be positive, got {self.width}x{self.height}"
                           f" x{self.supersample}")
        if self.image_noise_grey < 0:
            raise SimError(f"image noise must be >= 0 grey levels, got {self.image_noise_grey}")
        if (self.pinhole is not None or self.head is not None) and self.stitch is not None:
            raise SimError("stitched sensors are the panorama's; a pinhole camera or a head has none")
        if self.pinhole is not None and self.head is not None:
            raise SimError("one camera: a pinhole or a head, not both")

    @property
    def T_image_lidar(self) -> Pose:
        """Ground truth in the frame of the image's camera: the panorama's (a head's frame is the panorama's), or
        the pinhole's optical frame."""
        if self.pinhole is None:
            return self.T_camera_lidar
        return Pose(ROTATION_PANORAMA_OPTICAL.T, np.zeros(3)).compose(self.T_camera_lidar)


@dataclass(frozen=True)
class SimCapture:
    """One simulated pair with its ground truth: ``image`` (H,W) or (H,W,3) uint8 (a head's first sensor's),
    the sweep, meta.yaml content, the scene and the sensor poses in the world; ``images``: every sensor's image
    of a head (empty for one camera)."""

    image: NDArray[np.uint8]
    sweep: Sweep
    meta: dict[str, Any]
    scene: Scene
    pose_world_camera: Pose
    pose_world_lidar: Pose
    images: tuple[NDArray[np.uint8], ...] = ()


def scene_kind(kind: SceneKind | str) -> SceneKind:
    """Parse a scene kind, naming the choices when it is not one."""
    if isinstance(kind, SceneKind):
        return kind
    try:
        return SceneKind(kind)
    except ValueError as exc:
        choices = ", ".join(k.value for k in SceneKind)
        raise SimError(f"unknown scene kind {kind!r}; choose one of {choices}") from exc


def rng_for(kind: SceneKind, seed: int, index: int, stream: str) -> np.random.Generator:
    """Independent random streams per (kind, seed, pair index, purpose): changing the LiDAR noise figure
    does not move the scene, and pair ``i`` is the same whatever the number of pairs."""
    if seed < 0 or index < 0:
        raise SimError(f"seed and pair index must be >= 0, got seed={seed} index={index}")
    kind_code = list(SceneKind).index(kind)
    return np.random.default_rng([seed, index, kind_code, _STREAMS[stream]])


def make_scene(kind: SceneKind | str, seed: int, index: int, trees: bool = False) -> Scene:
    """The scene of pair ``index`` of dataset ``seed``; ``trees``: with street trees (outdoor scenes only)."""
    k = scene_kind(kind)
    rng = rng_for(k, seed, index, "scene")
    if k is SceneKind.INDOOR:
        if trees:
            raise SimError("street trees are for outdoor scenes; indoor scenes have none")
        return indoor_scene(rng)
    return outdoor_scene(rng, rng_for(k, seed, index, "vegetation") if trees else None)


def place_rig(scene: Scene, rng: np.random.Generator, T_camera_lidar: Pose) -> Pose:
    """A random free pose of the camera (``T_world_camera``) where tripod and both sensors have room."""
    x0, x1, y0, y1 = scene.free_area
    for _ in range(_PLACEMENT_TRIES):
        x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
        z = scene.floor_z_m + rng.uniform(*scene.rig_height_m)
        roll, pitch = np.clip(rng.normal(0.0, 1.0, size=2), -MAX_TILT_DEG, MAX_TILT_DEG)
        pose = Pose.from_rpy_xyz((roll, pitch, rng.uniform(-180.0, 180.0)), (x, y, z))
        lidar = pose.compose(T_camera_lidar).translation_m
        if _has_room(scene, pose.translation_m, lidar):
            return pose
    raise SimError(f"no free place for the rig in this {scene.kind.value} scene after {_PLACEMENT_TRIES} tries")


def _has_room(scene: Scene, camera: NDArray[np.float64], lidar: NDArray[np.float64]) -> bool:
    """True when no box (other than the ground) is near the sensors or in the tripod's column."""
    above_floor = scene.box_max[:, 2] > scene.floor_z_m + 1e-6
    for sensor in (camera, lidar):
        gap = np.maximum(np.maximum(scene.box_min - sensor, sensor - scene.box_max), 0.0)
        if np.any(above_floor & (np.linalg.norm(gap, axis=1) < SENSOR_CLEARANCE_M)):
            return False
    lo = np.array([camera[0] - RIG_HALF_WIDTH_M, camera[1] - RIG_HALF_WIDTH_M, scene.floor_z_m])
    hi = np.array([camera[0] + RIG_HALF_WIDTH_M, camera[1] + RIG_HALF_WIDTH_M, camera[2]])
    column = np.all((scene.box_min < hi) & (scene.box_max > lo), axis=1)
    return not np.any(above_floor & column)


class SimRig:
    """The simulated Ladybug5 + VLP-16 rig with ground truth ``config.T_camera_lidar``."""

    def __init__(self, config: SimConfig | None = None) -> None:
        self.config = config or SimConfig()

    @property
    def T_camera_lidar(self) -> Pose:
        return self.config.T_camera_lidar

    def capture(self, kind: SceneKind | str, seed: int, index: int) -> SimCapture:
        """Pair ``index`` of the dataset ``seed``: a new scene, a rig pose in it, an image and a sweep."""
        k = scene_kind(kind)
        cfg = self.config
        scene = make_scene(k, seed, index, cfg.trees)
        pose_cam = place_rig(scene, rng_for(k, seed, index, "pose"), cfg.T_camera_lidar)
        pose_lidar = pose_cam.compose(cfg.T_camera_lidar)
        camera_rng = rng_for(k, seed, index, "camera")
        images = tuple(self._render_sensor(scene, pose_cam, s, camera_rng) for s in cfg.head) if cfg.head else ()
        image = images[0] if images else self._render(scene, pose_cam, camera_rng)
        sweep = scan(scene, pose_lidar, rng_for(k, seed, index, "lidar"), cfg.lidar)
        meta: dict[str, Any] = {
            "source": "simulated",
            "scene": k.value,
            "seed": int(seed),
            "index": int(index),
            "T_world_camera": pose_cam.to_yaml(),
            "T_world_lidar": pose_lidar.to_yaml(),
            "sun_dir_world": [float(v) for v in scene.lighting.sun_dir_world],
            "range_noise_m": float(cfg.lidar.range_noise_m),
            "image_noise_grey": float(cfg.image_noise_grey),
        }
        if cfg.stitch is not None:
            meta["stitched_sensors"] = dataclasses.asdict(cfg.stitch)
        if cfg.jpeg_quality is not None:
            meta["jpeg_quality"] = int(cfg.jpeg_quality)
        if cfg.lidar.footprint is not None:
            meta["beam_footprint"] = dataclasses.asdict(cfg.lidar.footprint)
        if cfg.trees:
            meta["trees"] = True
        if cfg.lidar.elevations_deg is not None:
            meta["lidar_elevations_deg"] = [float(e) for e in cfg.lidar.elevations_deg]
        if cfg.lidar.detect_range_m is not None:
            meta["lidar_detection"] = {"detect_range_m": float(cfg.lidar.detect_range_m),
                                       "energy_noise": float(cfg.lidar.energy_noise)}
        if cfg.head:
            meta["head_sensors"] = [s.name for s in cfg.head]
        return SimCapture(image, sweep, meta, scene, pose_cam, pose_lidar, images)

    def _render_sensor(self, scene: Scene, pose_head: Pose, sensor: HeadSensorSpec,
                       rng: np.random.Generator) -> NDArray[np.uint8]:
        """One sensor's image of a head standing at ``pose_head``."""
        cfg = self.config
        pose = pose_head.compose(sensor.T_head_sensor)
        image = render_pinhole(scene, pose.translation_m, pose.rotation, sensor.K, sensor.width, sensor.height, rng,
                               noise_grey=cfg.image_noise_grey, supersample=cfg.supersample, color=cfg.color)
        return image if cfg.jpeg_quality is None else jpeg_round_trip(image, cfg.jpeg_quality)

    def _render(self, scene: Scene, pose_cam: Pose, rng: np.random.Generator) -> NDArray[np.uint8]:
        """The panorama, or the pinhole image along the panorama's forward axis, from ``pose_cam``."""
        cfg = self.config
        if cfg.pinhole is None:
            return render_panorama(scene, pose_cam, cfg.width, cfg.height, rng, cfg.image_noise_grey,
                                   cfg.supersample, cfg.color, cfg.stitch, cfg.jpeg_quality)
        p = cfg.pinhole
        image = render_pinhole(scene, pose_cam.translation_m, pose_cam.rotation @ ROTATION_PANORAMA_OPTICAL, p.K,
                               p.width, p.height, rng, noise_grey=cfg.image_noise_grey, supersample=cfg.supersample,
                               color=cfg.color)
        return image if cfg.jpeg_quality is None else jpeg_round_trip(image, cfg.jpeg_quality)


def simulate_pair(kind: SceneKind | str, seed: int, index: int, width: int = 1024, height: int = 512,
                  range_noise_m: float = 0.02) -> tuple[NDArray[np.uint8], Sweep, dict[str, Any]]:
    """``(image, sweep, meta)`` of pair ``index`` with the default rig (paper's ground truth)."""
    config = SimConfig(width=width, height=height, lidar=LidarConfig(range_noise_m=range_noise_m))
    cap = SimRig(config).capture(kind, seed, index)
    return cap.image, cap.sweep, cap.meta
