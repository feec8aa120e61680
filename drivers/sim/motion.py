"""The simulated rig on a scripted trajectory: stand still at a place, drive to the next, stand still, ...

This is the field workflow of the paper (every pair taken with the rig standing still) played by the
simulator, so the capture daemon can run end to end without hardware. All places are in one scene; time
``t`` is seconds since the rig started (its ``start_host_s`` on the host clock).

Timeline: place 0 for ``still_s``, a drive of ``move_s`` to place 1, ``still_s`` there, ... ; the rig
stays at the last place for good. A drive eases in and out (``s = (1 - cos(pi tau)) / 2``, tau the
fraction of the drive) as a carried or driven rig does, so speed is zero at both ends; positions and
roll/pitch/yaw are interpolated (yaw the short way round). The path is a straight line between places
and may cross furniture: the sensors then see the inside of a box for a moment, which only makes the
motion more obvious. A :class:`drivers.sim.disturbance.Disturbance` (vibration, creep) may move the rig a
little all the time, stops included: a rig that never stands quite still.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from drivers.sim.disturbance import Disturbance
from drivers.sim.errors import SimError
from drivers.sim.pose import Pose
from drivers.sim.rig import PAPER_T_CAMERA_LIDAR, make_scene, place_rig, rng_for, scene_kind
from drivers.sim.scene import Scene

PLACE_SPACING_M = (1.0, 6.0)  # consecutive places this far apart: distinct places, plausible drives
_SPACING_TRIES = 200


@dataclass(frozen=True)
class Trajectory:
    """Stops at ``places`` (T_world_camera poses), ``still_s`` at each, drives of ``move_s`` between, the
    whole moved by ``disturbance`` (none by default)."""

    places: tuple[Pose, ...]
    still_s: float
    move_s: float
    disturbance: Disturbance = Disturbance()

    def __post_init__(self) -> None:
        if not self.places:
            raise SimError("a trajectory needs at least one place")
        if not (self.still_s > 0 and self.move_s > 0):
            raise SimError(f"still and move durations must be positive, got {self.still_s}, {self.move_s}")

    @property
    def leg_s(self) -> float:
        return self.still_s + self.move_s

    def stop_interval(self, i: int) -> tuple[float, float]:
        """[start, end) s of the stop at place ``i``; the last stop never ends (end = inf)."""
        start = i * self.leg_s
        return start, (math.inf if i == len(self.places) - 1 else start + self.still_s)

    def stop_index(self, t: float) -> int | None:
        """The place the rig stands still at at time ``t`` s, or None while it drives."""
        if t < 0:
            return 0
        leg = min(int(t // self.leg_s), len(self.places) - 1)
        start, end = self.stop_interval(leg)
        return leg if start <= t < end else None

    def pose_at(self, t: float) -> Pose:
        """T_world_camera at time ``t`` s (the first place before 0, the last one after the end), disturbed."""
        return self.disturbance.apply(self.planned_pose_at(t), t)

    def planned_pose_at(self, t: float) -> Pose:
        """T_world_camera at time ``t`` s as planned, without the disturbance."""
        if t <= 0:
            return self.places[0]
        leg = int(t // self.leg_s)
        if leg >= len(self.places) - 1:
            return self.places[-1]
        tau = (t - leg * self.leg_s - self.still_s) / self.move_s
        if tau <= 0:
            return self.places[leg]
        return interpolate(self.places[leg], self.places[leg + 1], 0.5 * (1.0 - math.cos(math.pi * tau)))


def interpolate(a: Pose, b: Pose, s: float) -> Pose:
    """The pose a fraction ``s`` (0..1) of the way from ``a`` to ``b``: position and roll/pitch/yaw
    linearly, yaw the short way round (the rig's roll and pitch are a few degrees, far from gimbal lock)."""
    rpy_a, rpy_b = a.rpy_deg, b.rpy_deg
    delta = rpy_b - rpy_a
    delta[2] = (delta[2] + 180.0) % 360.0 - 180.0
    return Pose.from_rpy_xyz(rpy_a + s * delta, a.translation_m + s * (b.translation_m - a.translation_m))


def plan_places(scene: Scene, seed: int, count: int, first: int = 0,
                T_camera_lidar: Pose = PAPER_T_CAMERA_LIDAR) -> tuple[Pose, ...]:
    """Places ``first`` .. ``first + count - 1`` of the rig in ``scene`` (T_world_camera).

    Place ``i`` is drawn from its own random stream (so a resumed run can start at place ``first``),
    redrawn until it is :data:`PLACE_SPACING_M` from the previous one (the closest to that band if no draw
    is after a bounded number of tries).
    """
    places: list[Pose] = []
    for i in range(first, first + count):
        rng = rng_for(scene.kind, seed, i, "pose")
        best, best_gap = None, math.inf
        for _ in range(_SPACING_TRIES if places else 1):
            pose = place_rig(scene, rng, T_camera_lidar)
            if not places:
                best = pose
                break
            distance = float(np.linalg.norm(pose.translation_m - places[-1].translation_m))
            gap = max(PLACE_SPACING_M[0] - distance, distance - PLACE_SPACING_M[1], 0.0)
            if gap < best_gap:
                best, best_gap = pose, gap
            if gap == 0.0:
                break
        assert best is not None
        places.append(best)
    return tuple(places)


@dataclass(frozen=True)
class MotionRigSpec:
    """Everything that defines a simulated rig with motion; two processes with the same spec (including
    ``start_host_s``) simulate the same rig at the same instants (one emits the LiDAR, one the camera).

    ``scene``/``seed``: scene kind and dataset seed (the scene is ``make_scene(scene, seed, 0)``);
    ``stops`` places from place ``first_place``; ``still_s``/``move_s`` s; panorama ``width`` x ``height``
    px rendered every ``frame_period_s`` s at most (the simulator renders slower than a Ladybug5 streams:
    a 1024x512 panorama takes 1-2 s); noise figures as in :class:`drivers.sim.SimConfig`;
    ``start_host_s``: UNIX time of trajectory time 0, None until the rig is started; ``disturbance``: vibration
    and creep on top of the trajectory (drivers.sim.disturbance). ``sensor_width``: None renders the panorama
    directly; a width in px makes the camera a Ladybug5-like head of six sensors that wide
    (drivers.ladybug5.rig.scaled_ladybug5_rig): each frame then holds the six raw sensor images and the
    panorama stitched from them.
    """

    scene: str = "indoor"
    seed: int = 0
    stops: int = 8
    first_place: int = 0
    still_s: float = 6.0
    move_s: float = 2.0
    width: int = 1024
    height: int = 512
    frame_period_s: float = 0.25
    range_noise_m: float = 0.02
    image_noise_grey: float = 1.5
    T_camera_lidar: Pose = field(default_factory=lambda: PAPER_T_CAMERA_LIDAR)
    start_host_s: float | None = None
    disturbance: Disturbance = Disturbance()
    sensor_width: int | None = None

    def __post_init__(self) -> None:
        scene_kind(self.scene)
        if self.stops < 1 or self.first_place < 0 or self.seed < 0:
            raise SimError(f"sim rig: stops must be >= 1 and seed, first_place >= 0, got {self.stops}, "
                           f"{self.seed}, {self.first_place}")
        if self.width <= 0 or self.height <= 0 or not self.frame_period_s > 0:
            raise SimError(f"sim rig: bad camera size or frame period {self.width}x{self.height}, "
                           f"{self.frame_period_s} s")
        if self.range_noise_m < 0 or self.image_noise_grey < 0:
            raise SimError("sim rig: noise figures must be >= 0")
        if self.sensor_width is not None and self.sensor_width < 8:
            raise SimError(f"sim rig: sensor_width must be at least 8 px (or absent), got {self.sensor_width}")

    def started(self, start_host_s: float) -> MotionRigSpec:
        return replace(self, start_host_s=float(start_host_s))

    def build(self) -> tuple[Scene, Trajectory]:
        scene = make_scene(self.scene, self.seed, 0)
        places = plan_places(scene, self.seed, self.stops, self.first_place, self.T_camera_lidar)
        return scene, Trajectory(places, self.still_s, self.move_s, self.disturbance)

    def to_yaml(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "scene": self.scene, "seed": self.seed, "stops": self.stops, "first_place": self.first_place,
            "still_s": self.still_s, "move_s": self.move_s, "width": self.width, "height": self.height,
            "frame_period_s": self.frame_period_s, "range_noise_m": self.range_noise_m,
            "image_noise_grey": self.image_noise_grey, "T_camera_lidar": self.T_camera_lidar.to_yaml(),
        }
        if self.start_host_s is not None:
            out["start_host_s"] = self.start_host_s
        if self.disturbance.active:
            out["disturbance"] = self.disturbance.to_yaml()
        if self.sensor_width is not None:
            out["sensor_width"] = self.sensor_width
        return out

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> MotionRigSpec:
        if not isinstance(data, dict):
            raise SimError(f"{where}: a sim rig file must be a YAML mapping")
        unknown = set(data) - set(cls.__dataclass_fields__)
        if unknown:
            raise SimError(f"{where}: unknown sim rig key(s) {sorted(unknown)}")
        values = dict(data)
        try:
            if "T_camera_lidar" in values:
                t = values["T_camera_lidar"]
                values["T_camera_lidar"] = Pose.from_rpy_xyz(np.asarray(t["rpy_deg"], float),
                                                             np.asarray(t["xyz_m"], float))
            if "disturbance" in values:
                values["disturbance"] = Disturbance.from_yaml(values["disturbance"], where)
            for key, kind in (("seed", int), ("stops", int), ("first_place", int), ("width", int), ("height", int),
                              ("sensor_width", int)):
                if values.get(key) is not None:
                    values[key] = kind(values[key])
            return cls(**values)
        except (KeyError, TypeError, ValueError) as exc:
            raise SimError(f"{where}: bad sim rig file ({exc!r})") from exc


def save_spec(path: Path, spec: MotionRigSpec) -> None:
    """Write ``spec`` as YAML (through a temporary file, so a reader never sees half of it)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        tmp.write_text(yaml.safe_dump(spec.to_yaml(), sort_keys=False))
        tmp.replace(path)
    except OSError as exc:
        raise SimError(f"{path}: cannot write the sim rig file ({exc})") from exc


def load_spec(path: Path) -> MotionRigSpec:
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as exc:
        raise SimError(f"{path}: cannot read the sim rig file ({exc})") from exc
    return MotionRigSpec.from_yaml(data, str(path))
