"""Rotation helpers shared by the drivers (the simulator, the Ladybug5 rig file); drivers does not import
calib, so these few functions are written here once and cross-checked against calib.geometry in tests.

Same conventions as docs/conventions.md: roll/pitch/yaw in degrees with ``R = Rz(yaw) @ Ry(pitch) @
Rx(roll)``, pitch in [-90, 90]; quaternions in ``xyzw`` order with ``w >= 0``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def rpy_deg_to_matrix(rpy_deg: F64 | tuple[float, float, float]) -> F64:
    """(3,3) rotation from roll, pitch, yaw in degrees."""
    roll, pitch, yaw = np.radians(np.asarray(rpy_deg, dtype=np.float64))
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    rotation: F64 = rz @ ry @ rx
    return rotation


def matrix_to_rpy_deg(rotation: F64) -> F64:
    """Roll, pitch, yaw in degrees (3,) of a (3,3) rotation; at gimbal lock roll is set to 0."""
    r = np.asarray(rotation, dtype=np.float64)
    pitch = np.arcsin(np.clip(-r[2, 0], -1.0, 1.0))
    if abs(r[2, 0]) > 1.0 - 1e-12:
        roll = 0.0
        yaw = np.arctan2(-r[0, 1], r[1, 1])
    else:
        roll = np.arctan2(r[2, 1], r[2, 2])
        yaw = np.arctan2(r[1, 0], r[0, 0])
    rpy: F64 = np.degrees(np.array([roll, pitch, yaw], dtype=np.float64))
    return rpy


def matrix_to_quaternion_xyzw(rotation: F64) -> F64:
    """Unit quaternion (x, y, z, w) with w >= 0 of a (3,3) rotation (largest-component method)."""
    r = np.asarray(rotation, dtype=np.float64)
    trace = np.trace(r)
    candidates = np.array([1 + 2 * r[0, 0] - trace, 1 + 2 * r[1, 1] - trace, 1 + 2 * r[2, 2] - trace, 1 + trace])
    k = int(np.argmax(candidates))
    q = np.empty(4)
    q[k] = np.sqrt(candidates[k]) / 2.0
    s = 1.0 / (4.0 * q[k])
    off = {
        0: (r[0, 1] + r[1, 0], r[0, 2] + r[2, 0], r[2, 1] - r[1, 2]),
        1: (r[0, 1] + r[1, 0], r[1, 2] + r[2, 1], r[0, 2] - r[2, 0]),
        2: (r[0, 2] + r[2, 0], r[1, 2] + r[2, 1], r[1, 0] - r[0, 1]),
        3: (r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]),
    }[k]
    others = [i for i in range(4) if i != k]
    q[others] = np.array(off) * s
    return q if q[3] >= 0 else -q
