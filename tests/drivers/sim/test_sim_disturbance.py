"""A rig that never stands quite still: vibration and creep on top of the trajectory, in the rig file, and in
the VLP-16 stream (a still rig's turns reuse their ray casting, a disturbed one's do not)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from drivers.sim import Pose
from drivers.sim.disturbance import Disturbance, axis_angle_matrix
from drivers.sim.errors import SimError
from drivers.sim.motion import MotionRigSpec, Trajectory, load_spec, save_spec
from drivers.sim.stream import LidarEmitter

PLACE = Pose.from_rpy_xyz((1.0, -2.0, 170.0), (1.0, 2.0, 1.5))


def angle_deg(a: Pose, b: Pose) -> float:
    return math.degrees(math.acos(np.clip((np.trace(a.rotation.T @ b.rotation) - 1) / 2, -1.0, 1.0)))


def test_vibration_swings_the_rig_by_its_amplitude_at_its_frequency() -> None:
    trajectory = Trajectory((PLACE,), still_s=10.0, move_s=1.0, disturbance=Disturbance(vibration_deg=0.1,
                                                                                        vibration_hz=2.0, seed=3))
    times = np.arange(0.0, 2.0, 0.005)
    angles = np.array([angle_deg(PLACE, trajectory.pose_at(t)) for t in times])
    assert angles.max() == pytest.approx(0.1, abs=1e-3)  # either way, about one fixed axis
    assert angle_deg(trajectory.pose_at(0.3), trajectory.pose_at(0.8)) == pytest.approx(0.0, abs=1e-5)  # 2 Hz
    np.testing.assert_allclose(trajectory.pose_at(1.0).translation_m, PLACE.translation_m, atol=1e-12)
    np.testing.assert_array_equal(trajectory.planned_pose_at(1.0).matrix, PLACE.matrix)


def test_creep_moves_the_rig_at_its_speed_horizontally_and_turns_it() -> None:
    trajectory = Trajectory((PLACE,), still_s=10.0, move_s=1.0,
                            disturbance=Disturbance(creep_m_s=0.005, creep_deg_s=0.1, seed=4))
    moved = trajectory.pose_at(2.0).translation_m - trajectory.pose_at(0.0).translation_m
    assert np.linalg.norm(moved) == pytest.approx(0.01, abs=1e-12) and moved[2] == 0.0  # 1 cm in 2 s, level
    assert angle_deg(trajectory.pose_at(0.0), trajectory.pose_at(2.0)) == pytest.approx(0.2, abs=1e-5)


def test_axis_angle_matrix_is_a_rotation() -> None:
    rotation = axis_angle_matrix(np.array([0.0, 0.0, 1.0]), math.radians(90.0))
    np.testing.assert_allclose(rotation @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)


def test_the_rig_file_carries_the_disturbance(tmp_path: Path) -> None:
    spec = MotionRigSpec(stops=2, disturbance=Disturbance(vibration_deg=0.1, creep_m_s=0.002, seed=9))
    save_spec(tmp_path / "rig.yaml", spec)
    assert load_spec(tmp_path / "rig.yaml").disturbance == spec.disturbance
    save_spec(tmp_path / "still.yaml", MotionRigSpec(stops=2))
    assert "disturbance" not in (tmp_path / "still.yaml").read_text()  # none: the file stays as it was
    (tmp_path / "bad.yaml").write_text("disturbance: {vibration_deg: -1}\n")
    with pytest.raises(SimError, match="disturbance"):
        load_spec(tmp_path / "bad.yaml")
    (tmp_path / "typo.yaml").write_text("disturbance: {vibration: 0.1}\n")
    with pytest.raises(SimError, match="unknown disturbance key"):
        load_spec(tmp_path / "typo.yaml")


def test_a_still_rig_reuses_its_ray_casting_a_creeping_one_does_not() -> None:
    still = LidarEmitter(MotionRigSpec(stops=1, width=64, height=32).started(1000.0), "127.0.0.1", 9)
    first = still.turn_datagrams(3)
    cached = still._returns
    again = still.turn_datagrams(4)
    assert still._returns is cached  # the same surfaces ...
    assert first[1][2] != again[1][2]  # ... and new noise
    creeping = LidarEmitter(MotionRigSpec(stops=1, width=64, height=32,
                                          disturbance=Disturbance(creep_m_s=0.005)).started(1000.0), "127.0.0.1", 9)
    creeping.turn_datagrams(3)
    cached = creeping._returns
    creeping.turn_datagrams(4)
    assert creeping._returns is not cached
