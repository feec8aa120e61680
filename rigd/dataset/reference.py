"""``reference.yaml``: a published calibration of a real dataset, with its own uncertainty.

Real data has no ground truth, only another method's estimate. ``T_camera_lidar`` is that estimate in the
dataset's camera frame (the head's for a head dataset). Its one-sigma is given per axis of the form the source
published it in, ``[x, y, z, roll, pitch, heading]`` of the LiDAR in frame ``sigma_frame`` (the head for the
Ford sample), with ``T_sigma_frame_camera`` mapping the dataset's camera frame into it (the identity for a
head dataset, a sensor's factory pose for one camera of the head). A result agrees with the reference when
every axis of that form lies within a few of the reference's sigmas (:func:`agreement`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.geometry import Transform, rotation_angle_deg
from calib.uncertainty import TO_DISPLAY, xi_of
from rigd.dataset.records import transform_from_yaml, transform_to_yaml
from rigd.errors import DatasetError
from rigd.report import ReferenceAgreement

AXES = ("x", "y", "z", "roll", "pitch", "heading")


@dataclass(frozen=True)
class Reference:
    """``T_camera_lidar``: the published pose in the dataset's frame; ``sigma`` (6,) its one-sigma per axis of
    the source's form (m, m, m, deg, deg, deg), None when the source published none (KITTI);
    ``T_sigma_frame_camera`` the dataset's camera in the frame of that form."""

    T_camera_lidar: Transform
    sigma: NDArray[np.float64] | None
    T_sigma_frame_camera: Transform
    source: str

    def source_form(self, T_camera_lidar: Transform) -> NDArray[np.float64]:
        """(6,) [x, y, z (m), roll, pitch, heading (deg)] of ``T_camera_lidar`` in the reference's frame."""
        T = self.T_sigma_frame_camera.compose(T_camera_lidar)
        return np.concatenate([T.translation_m, T.rpy_deg])

    def local_sigma(self) -> NDArray[np.float64] | None:
        """(6,) the reference's one-sigma in rigd's local coordinates around it (roll, pitch, yaw about the LiDAR's
        axes in deg, x, y, z in cm: docs/conventions.md), its published per-axis sigmas carried through the
        derivative of that change of coordinates (numerically, at the reference); None without sigmas."""
        if self.sigma is None:
            return None
        base = self.source_form(self.T_camera_lidar)
        tau0 = self.T_camera_lidar.tau
        to_camera = self.T_sigma_frame_camera.inverse()
        steps = np.array([1e-4] * 3 + [1e-3] * 3)
        jac = np.zeros((6, 6))
        for k in range(6):
            cols = []
            for sign in (1.0, -1.0):
                form = base.copy()
                form[k] += sign * steps[k]
                T = to_camera.compose(Transform.from_rpy_xyz(form[3:], form[:3]))
                cols.append(xi_of(tau0, T.tau) * TO_DISPLAY)
            jac[:, k] = (cols[0] - cols[1]) / (2.0 * steps[k])
        return np.asarray(np.sqrt(np.diag(jac @ np.diag(self.sigma**2) @ jac.T)), dtype=np.float64)

    def to_yaml(self) -> dict[str, Any]:
        sigma = None if self.sigma is None else {
            "xyz_cm": (self.sigma[:3] * 100.0).tolist(), "roll_pitch_heading_deg": self.sigma[3:].tolist(),
            "frame": {"T_frame_camera": transform_to_yaml(self.T_sigma_frame_camera)}}
        return {"T_camera_lidar": transform_to_yaml(self.T_camera_lidar), "source": self.source, "sigma": sigma}


def reference_from_yaml(data: dict[str, Any], where: str) -> Reference:
    """``reference.yaml`` as read (a mapping); DatasetError naming ``where`` when a key is missing or bad."""
    T = transform_from_yaml(data.get("T_camera_lidar"), where)
    if data.get("sigma") is None:
        return Reference(T, None, Transform.identity(), str(data.get("source", "")))
    try:
        sigma = data["sigma"]
        values = np.concatenate([np.asarray(sigma["xyz_cm"], float).reshape(3) / 100.0,
                                 np.asarray(sigma["roll_pitch_heading_deg"], float).reshape(3)])
        frame = transform_from_yaml(sigma["frame"]["T_frame_camera"], where)
    except (KeyError, TypeError, ValueError) as exc:
        raise DatasetError(f"{where}: needs sigma: {{xyz_cm, roll_pitch_heading_deg, frame: {{T_frame_camera}}}} "
                           f"({exc!r})") from exc
    if not (np.all(np.isfinite(values)) and np.all(values > 0)):
        raise DatasetError(f"{where}: the reference's sigmas must be positive, got {values.tolist()}")
    return Reference(T, values, frame, str(data.get("source", "")))


@dataclass(frozen=True)
class Agreement:
    """A result against the reference: ``z`` (6,) difference per axis of the source's form in the reference's
    sigmas (NaN when it has none); ``rotation_deg``, ``translation_cm`` the whole difference."""

    z: NDArray[np.float64]
    rotation_deg: float
    translation_cm: float

    def within(self, z_max: float = 2.5, rotation_deg: float = 0.6, translation_cm: float = 10.0) -> bool:
        """Every axis within ``z_max`` sigmas (when the reference has sigmas) and the whole difference within
        ``rotation_deg`` and ``translation_cm``."""
        sigmas_agree = bool(np.all(np.isnan(self.z)) or np.all(np.abs(self.z) <= z_max))
        return sigmas_agree and self.rotation_deg <= rotation_deg and self.translation_cm <= translation_cm

    def to_yaml(self) -> ReferenceAgreement:
        z = [None if np.isnan(v) else float(v) for v in self.z]
        return {"z_per_axis": dict(zip(AXES, z, strict=True)), "rotation_deg": self.rotation_deg,
                "translation_cm": self.translation_cm, "within_2_5_sigma_0_6_deg_10_cm": self.within()}


def agreement(reference: Reference, T_camera_lidar: Transform) -> Agreement:
    """How ``T_camera_lidar`` compares with the reference (the heading difference wrapped to +-180 deg)."""
    diff = reference.source_form(T_camera_lidar) - reference.source_form(reference.T_camera_lidar)
    diff[3:] = (diff[3:] + 180.0) % 360.0 - 180.0
    rot = rotation_angle_deg(reference.T_camera_lidar.rotation, T_camera_lidar.rotation)
    trans = float(np.linalg.norm(T_camera_lidar.translation_m - reference.T_camera_lidar.translation_m) * 100.0)
    return Agreement(diff / reference.sigma if reference.sigma is not None else np.full(6, np.nan), rot, trans)
