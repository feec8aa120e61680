"""Typed records of a dataset's ``rig.yaml``."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.camera import CameraModel, Equirectangular, Pinhole
from calib.errors import CalibError
from calib.geometry import Transform
from rigd.errors import DatasetError


class CameraKind(Enum):
    EQUIRECTANGULAR = "equirectangular"
    PINHOLE = "pinhole"


@dataclass(frozen=True)
class CameraConfig:
    """Camera intrinsics: a panorama size, or a pinhole ``K`` (3,3) px and OpenCV ``D``."""

    kind: CameraKind
    width: int
    height: int
    K: NDArray[np.float64] | None = None
    D: NDArray[np.float64] | None = None

    def model(self) -> CameraModel:
        if self.kind is CameraKind.EQUIRECTANGULAR:
            return Equirectangular(self.width, self.height)
        assert self.K is not None
        return Pinhole(self.K, self.D if self.D is not None else np.zeros(5), self.width, self.height)

    def to_yaml(self) -> dict[str, Any]:
        out: dict[str, Any] = {"model": self.kind.value, "width": self.width, "height": self.height}
        if self.K is not None:
            out["K"] = np.asarray(self.K).tolist()
            out["D"] = np.asarray(self.D if self.D is not None else []).tolist()
        return out

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> CameraConfig:
        try:
            kind = CameraKind(str(data["model"]))
            width, height = int(data["width"]), int(data["height"])
            k = np.asarray(data["K"], dtype=np.float64) if "K" in data else None
            d = np.asarray(data.get("D", []), dtype=np.float64) if k is not None else None
        except (KeyError, TypeError, ValueError) as exc:
            raise DatasetError(f"{where}: bad camera section ({exc!r})") from exc
        if kind is CameraKind.PINHOLE and k is None:
            raise DatasetError(f"{where}: a pinhole camera needs K")
        config = cls(kind, width, height, k, d)
        try:
            config.model()
        except CalibError as exc:
            raise DatasetError(f"{where}: {exc}") from exc
        return config


def transform_to_yaml(transform: Transform) -> dict[str, Any]:
    """The project's YAML form of a transform: matrix, quaternion_xyzw, rpy_deg, xyz_m."""
    return {
        "matrix": transform.matrix.tolist(),
        "quaternion_xyzw": transform.quaternion_xyzw.tolist(),
        "rpy_deg": transform.rpy_deg.tolist(),
        "xyz_m": transform.translation_m.tolist(),
    }


def transform_from_yaml(data: Any, where: str) -> Transform:
    """Read a transform given as ``matrix`` (4x4) or ``rpy_deg`` + ``xyz_m``."""
    try:
        if "matrix" in data:
            return Transform.from_matrix(np.asarray(data["matrix"], dtype=np.float64))
        return Transform.from_rpy_xyz(np.asarray(data["rpy_deg"], float), np.asarray(data["xyz_m"], float))
    except (KeyError, TypeError, ValueError, CalibError) as exc:
        raise DatasetError(f"{where}: bad transform ({exc!r})") from exc


@dataclass(frozen=True)
class RigConfig:
    """``rig.yaml``: the camera, the LiDAR model and an optional initial guess of T_camera_lidar."""

    camera: CameraConfig
    lidar_model: str = "VLP-16"
    initial_guess: Transform | None = None

    def to_yaml(self) -> dict[str, Any]:
        out: dict[str, Any] = {"camera": self.camera.to_yaml(), "lidar": {"model": self.lidar_model}}
        if self.initial_guess is not None:
            out["initial_guess"] = {
                "rpy_deg": self.initial_guess.rpy_deg.tolist(),
                "xyz_m": self.initial_guess.translation_m.tolist(),
            }
        return out

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> RigConfig:
        if not isinstance(data, dict) or "camera" not in data:
            raise DatasetError(f"{where}: rig file needs a 'camera' section")
        camera = CameraConfig.from_yaml(data["camera"], where)
        lidar = data.get("lidar") or {}
        if not isinstance(lidar, dict):
            raise DatasetError(f"{where}: 'lidar' must be a mapping with a 'model' key, got {lidar!r}")
        guess = data.get("initial_guess")
        initial = transform_from_yaml(guess, where) if guess else None
        return cls(camera, str(lidar.get("model", "VLP-16")), initial)
