"""Motion of a rig that should stand still: vibration and creep, on top of its trajectory (drivers.sim.motion).

A real rig is never perfectly still: a mast sways in the wind or with an engine, a tripod on soft ground
settles, a cart rolls slowly down a slope. :class:`Disturbance` models two such motions so that the capture's
stillness gate can be measured against them (benchmarks/stillness_gate.py, docs/capture.md):

- vibration: a rotation about a fixed axis through the camera centre, ``vibration_deg`` either way,
  sinusoidal at ``vibration_hz``;
- creep: a constant velocity, ``creep_m_s`` along a horizontal direction and ``creep_deg_s`` of yaw.

Both run all the time, drives included; the axis, the direction and the phase are drawn from ``seed``. At
trajectory time t (s) the rig's pose becomes ``T_world_camera(t)`` with the creep's translation added in the
world and the creep's yaw and the vibration applied in the camera frame (the LiDAR, rigidly mounted, swings
with its lever arm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivers.sim.errors import SimError
from drivers.sim.pose import Pose

F64 = NDArray[np.float64]


def axis_angle_matrix(axis: F64, angle_rad: float) -> F64:
    """(3,3) rotation by ``angle_rad`` about the unit vector ``axis`` (3,) (Rodrigues)."""
    x, y, z = axis
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    rotation: F64 = np.eye(3) + math.sin(angle_rad) * k + (1.0 - math.cos(angle_rad)) * (k @ k)
    return rotation


@dataclass(frozen=True)
class Disturbance:
    """Vibration (``vibration_deg`` amplitude, deg, at ``vibration_hz``) and creep (``creep_m_s`` m/s
    horizontally, ``creep_deg_s`` deg/s of yaw) of a rig, drawn from ``seed`` (module doc). All zero: none."""

    vibration_deg: float = 0.0
    vibration_hz: float = 2.0
    creep_m_s: float = 0.0
    creep_deg_s: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        values = (self.vibration_deg, self.vibration_hz, self.creep_m_s, self.creep_deg_s)
        if not all(math.isfinite(v) and v >= 0 for v in values) or self.vibration_hz <= 0 or self.seed < 0:
            raise SimError(f"sim rig disturbance: amplitudes and speeds must be finite and >= 0, the frequency "
                           f"> 0 and the seed >= 0, got {self}")

    @property
    def active(self) -> bool:
        return bool(self.vibration_deg or self.creep_m_s or self.creep_deg_s)

    def _draws(self) -> tuple[F64, float, F64]:
        """The vibration's unit axis (3,), its phase rad, and the creep's horizontal unit direction (3,)."""
        rng = np.random.default_rng([self.seed, 0x5EED])
        axis = rng.normal(size=3)
        heading = rng.uniform(0.0, 2.0 * math.pi)
        phase = float(rng.uniform(0.0, 2.0 * math.pi))
        return axis / np.linalg.norm(axis), phase, np.array([math.cos(heading), math.sin(heading), 0.0])

    def apply(self, pose: Pose, t: float) -> Pose:
        """``pose`` (T_world_camera at trajectory time ``t`` s) moved by the disturbance at ``t``."""
        if not self.active:
            return pose
        axis, phase, direction = self._draws()
        swing = math.radians(self.vibration_deg) * math.sin(2.0 * math.pi * self.vibration_hz * t + phase)
        turn = axis_angle_matrix(np.array([0.0, 0.0, 1.0]), math.radians(self.creep_deg_s) * t)
        rotation = pose.rotation @ turn @ axis_angle_matrix(axis, swing)
        return Pose(rotation, pose.translation_m + self.creep_m_s * t * direction)

    def to_yaml(self) -> dict[str, Any]:
        return {"vibration_deg": self.vibration_deg, "vibration_hz": self.vibration_hz, "creep_m_s": self.creep_m_s,
                "creep_deg_s": self.creep_deg_s, "seed": self.seed}

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> Disturbance:
        if not isinstance(data, dict):
            raise SimError(f"{where}: 'disturbance' must be a mapping of {sorted(cls.__dataclass_fields__)}")
        unknown = set(data) - set(cls.__dataclass_fields__)
        if unknown:
            raise SimError(f"{where}: unknown disturbance key(s) {sorted(unknown)}")
        try:
            numbers = {k: float(v) for k, v in data.items() if k != "seed"}
            seed = int(data.get("seed", 0))
        except (TypeError, ValueError) as exc:
            raise SimError(f"{where}: disturbance values must be numbers ({exc})") from exc
        return cls(seed=seed, **numbers)
