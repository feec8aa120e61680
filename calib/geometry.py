"""SO(3)/SE(3) helpers and the project's rotation conventions (docs/conventions.md).

Conventions fixed for the whole project:
- ``T_camera_lidar`` maps LiDAR points into the camera frame, ``p_cam = R @ p_lidar + t`` (paper eq. 3).
- Roll/pitch/yaw in degrees with ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
- Quaternions are named by component order: ``quaternion_xyzw``.
- The optimiser parameterises rotation by ``omega`` in so(3), ``R = exp(omega^)`` (paper eq. 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib.errors import GeometryError

F64 = NDArray[np.float64]

_SMALL_ANGLE = 1e-8


def skew(v: F64) -> F64:
    """The skew-symmetric matrix ``v^`` with ``v^ @ x == cross(v, x)``; ``v`` (3,)."""
    x, y, z = (float(c) for c in v)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def cross_rows(a: F64, b: F64) -> F64:
    """Row-wise cross product of (N,3) arrays: np.cross's arithmetic, without its general axis handling,
    which costs more than the products on the few hundred rows of one pair."""
    out = np.empty((len(a), 3))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def so3_exp(omega: F64) -> F64:
    """Rotation matrix ``exp(omega^)`` (paper eq. 4), Rodrigues' formula; ``omega`` (3,) rad."""
    omega = np.asarray(omega, dtype=np.float64)
    angle = float(np.linalg.norm(omega))
    k = skew(omega)
    if angle < _SMALL_ANGLE:
        return np.eye(3) + k + 0.5 * k @ k
    return np.eye(3) + (math.sin(angle) / angle) * k + ((1.0 - math.cos(angle)) / angle**2) * k @ k


def so3_log(rotation: F64) -> F64:
    """Rotation vector ``omega`` (3,) rad with ``so3_exp(omega) == rotation``; angle in [0, pi]."""
    r = check_rotation(rotation)
    vee = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    sin_angle = float(np.linalg.norm(vee)) / 2.0
    cos_angle = (float(np.trace(r)) - 1.0) / 2.0
    # atan2 keeps the angle accurate near 0 and pi, where arccos and arcsin lose half the digits.
    angle = math.atan2(sin_angle, cos_angle)
    if angle < 1e-6:
        return 0.5 * vee
    if np.pi - angle > 1e-3:
        return (angle / (2.0 * sin_angle)) * vee
    # Near pi the antisymmetric part vanishes: the symmetric part is cos I + (1 - cos) a a^T.
    outer = (r + r.T) / 2.0 - cos_angle * np.eye(3)
    col = int(np.argmax(np.diag(outer)))
    axis = outer[:, col] / np.linalg.norm(outer[:, col])
    if np.dot(axis, vee) < 0:
        axis = -axis
    return angle * axis


def left_jacobian(omega: F64) -> F64:
    """Left Jacobian ``J`` of SO(3) at ``omega`` (paper eq. 31), (3,3)."""
    omega = np.asarray(omega, dtype=np.float64)
    angle = float(np.linalg.norm(omega))
    if angle < 1e-6:
        return np.eye(3) + 0.5 * skew(omega)
    a = omega / angle
    s = math.sin(angle) / angle
    return s * np.eye(3) + (1.0 - s) * np.outer(a, a) + ((1.0 - math.cos(angle)) / angle) * skew(a)


def check_rotation(rotation: F64, tol: float = 1e-6) -> F64:
    """Return ``rotation`` as (3,3) float64 or raise :class:`GeometryError` if not in SO(3)."""
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise GeometryError(f"rotation must be a finite 3x3 matrix, got shape {r.shape}")
    if np.abs(r @ r.T - np.eye(3)).max() > tol or np.linalg.det(r) < 0:
        raise GeometryError("rotation matrix is not orthonormal with det +1")
    return r


def _rx(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_deg_to_matrix(rpy_deg: F64) -> F64:
    """``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` from ``rpy_deg`` = (roll, pitch, yaw) in degrees."""
    roll, pitch, yaw = np.radians(np.asarray(rpy_deg, dtype=np.float64))
    return _rz(yaw) @ _ry(pitch) @ _rx(roll)


def matrix_to_rpy_deg(rotation: F64) -> F64:
    """(roll, pitch, yaw) in degrees with pitch in [-90, 90]; inverse of :func:`rpy_deg_to_matrix`."""
    r = check_rotation(rotation)
    cos_pitch = math.hypot(r[0, 0], r[1, 0])
    # atan2 rather than arcsin(-r[2, 0]), which loses half the digits near the gimbal lock.
    pitch = math.atan2(-r[2, 0], cos_pitch)
    if cos_pitch < 1e-14:  # gimbal lock: only roll -/+ yaw is defined; put it all in yaw
        yaw = math.atan2(-r[0, 1], r[1, 1])
    else:
        yaw = math.atan2(r[1, 0], r[0, 0])
    # Roll from Rz(yaw)^T R = Ry(pitch) Rx(roll), whose roll entries stay O(1) near the lock (r[2, 1] and
    # r[2, 2] shrink with cos(pitch)): roll absorbs the rounding of yaw and R is rebuilt to machine precision.
    m = _rz(yaw).T @ r
    roll = math.atan2(-m[1, 2], m[1, 1])
    return np.array([math.degrees(roll), math.degrees(pitch), math.degrees(yaw)])


def matrix_to_quaternion_xyzw(rotation: F64) -> F64:
    """Unit quaternion (x, y, z, w) with w >= 0 for a rotation matrix."""
    r = check_rotation(rotation)
    trace = np.trace(r)
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0, 0.0, 0.0, (r[k, j] - r[j, k]) / s]
        q[i] = 0.25 * s
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
    quat = np.array(q)
    quat /= np.linalg.norm(quat)
    return -quat if quat[3] < 0 else quat


def quaternion_xyzw_to_matrix(quaternion_xyzw: F64) -> F64:
    """Rotation matrix of a (not necessarily unit) quaternion given as (x, y, z, w)."""
    q = np.asarray(quaternion_xyzw, dtype=np.float64)
    norm = float(np.linalg.norm(q))
    if q.shape != (4,) or not np.isfinite(norm) or norm < 1e-12:
        raise GeometryError(f"quaternion_xyzw must be 4 finite numbers, not all zero: {q}")
    x, y, z, w = q / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass(frozen=True)
class Transform:
    """A rigid transform ``p_to = rotation @ p_from + translation_m``.

    ``rotation`` (3,3) float64, ``translation_m`` (3,) float64 metres. Used for ``T_camera_lidar``.
    """

    rotation: F64
    translation_m: F64

    def __post_init__(self) -> None:
        object.__setattr__(self, "rotation", check_rotation(self.rotation))
        t = np.asarray(self.translation_m, dtype=np.float64).reshape(-1)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise GeometryError(f"translation must be 3 finite numbers, got {t}")
        object.__setattr__(self, "translation_m", t)

    @classmethod
    def identity(cls) -> Transform:
        return cls(np.eye(3), np.zeros(3))

    @classmethod
    def from_matrix(cls, matrix: F64) -> Transform:
        m = np.asarray(matrix, dtype=np.float64)
        if m.shape != (4, 4) or np.abs(m[3] - [0, 0, 0, 1]).max() > 1e-9:
            raise GeometryError("a 4x4 homogeneous matrix with last row [0 0 0 1] is required")
        return cls(m[:3, :3], m[:3, 3])

    @classmethod
    def from_rpy_xyz(cls, rpy_deg: F64, xyz_m: F64) -> Transform:
        return cls(rpy_deg_to_matrix(rpy_deg), np.asarray(xyz_m, dtype=np.float64))

    @classmethod
    def from_tau(cls, tau: F64) -> Transform:
        """From the optimiser's parameters ``tau = [omega, t]`` (6,) (paper section 3)."""
        tau = np.asarray(tau, dtype=np.float64)
        return cls(so3_exp(tau[:3]), tau[3:])

    @property
    def matrix(self) -> F64:
        m = np.eye(4)
        m[:3, :3] = self.rotation
        m[:3, 3] = self.translation_m
        return m

    @property
    def tau(self) -> F64:
        return np.concatenate([so3_log(self.rotation), self.translation_m])

    @property
    def rpy_deg(self) -> F64:
        return matrix_to_rpy_deg(self.rotation)

    @property
    def quaternion_xyzw(self) -> F64:
        return matrix_to_quaternion_xyzw(self.rotation)

    def apply(self, points_from: F64) -> F64:
        """Transform points (N,3) float64 into the target frame (N,3)."""
        return np.asarray(points_from, dtype=np.float64) @ self.rotation.T + self.translation_m

    def inverse(self) -> Transform:
        return Transform(self.rotation.T, -self.rotation.T @ self.translation_m)

    def compose(self, other: Transform) -> Transform:
        """``self @ other``: first ``other``, then ``self``."""
        rotation = self.rotation @ other.rotation
        return Transform(rotation, self.rotation @ other.translation_m + self.translation_m)


def rotation_angle_deg(a: F64, b: F64) -> float:
    """Angle in degrees of the relative rotation between rotation matrices ``a`` and ``b``."""
    return float(np.degrees(np.linalg.norm(so3_log(a.T @ b))))
