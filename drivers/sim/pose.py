"""Rigid poses for the simulator (drivers may not import calib, so this is a small local copy).

Same conventions as docs/conventions.md: ``p_to = rotation @ p_from + translation_m``; roll/pitch/yaw in
degrees with ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.geometry import matrix_to_rpy_deg, rpy_deg_to_matrix

F64 = NDArray[np.float64]


def rotate(vectors: F64, rotation: F64) -> F64:
    """``rotation @ v`` for each row of ``vectors`` (N,3).

    einsum, not ``@``: a BLAS matmul of an (N,3) array by a 3x3 is many times slower (and erratic) when
    OpenBLAS's threads compete for busy cores, and gains nothing for such a small inner dimension.
    """
    rotated: F64 = np.einsum("ij,kj->ik", np.asarray(vectors, dtype=np.float64), np.asarray(rotation, dtype=np.float64))
    return rotated


@dataclass(frozen=True)
class Pose:
    """``p_to = rotation @ p_from + translation_m``; ``rotation`` (3,3) float64, ``translation_m`` (3,) m."""

    rotation: F64
    translation_m: F64

    @classmethod
    def from_rpy_xyz(cls, rpy_deg: tuple[float, float, float] | F64, xyz_m: tuple[float, float, float] | F64) -> Pose:
        return cls(rpy_deg_to_matrix(rpy_deg), np.asarray(xyz_m, dtype=np.float64).reshape(3))

    @property
    def matrix(self) -> F64:
        """4x4 homogeneous matrix."""
        m = np.eye(4)
        m[:3, :3] = self.rotation
        m[:3, 3] = self.translation_m
        return m

    @property
    def rpy_deg(self) -> F64:
        return matrix_to_rpy_deg(self.rotation)

    def inverse(self) -> Pose:
        return Pose(self.rotation.T, -self.rotation.T @ self.translation_m)

    def compose(self, other: Pose) -> Pose:
        """``self @ other``: first ``other``, then ``self``."""
        return Pose(self.rotation @ other.rotation, self.rotation @ other.translation_m + self.translation_m)

    def apply(self, points_from: F64) -> F64:
        """Map points (N,3) float64 m into the target frame."""
        return rotate(points_from, self.rotation) + self.translation_m

    def to_yaml(self) -> dict[str, list[float]]:
        """Plain-Python form for meta.yaml: ``rpy_deg`` and ``xyz_m``."""
        return {"rpy_deg": [float(a) for a in self.rpy_deg], "xyz_m": [float(a) for a in self.translation_m]}
