"""Typed records of a dataset's ``rig.yaml``."""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import Enum
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from calib.assess import TrustOptions
from calib.camera import CameraModel, Equirectangular, Fisheye, Mounted, Pinhole
from calib.errors import CalibError
from calib.geometry import Transform, rpy_deg_to_matrix
from calib.pipeline import CalibParams
from calib.prior import Prior
from calib.search import SearchOptions
from rigd.dataset.lasers import VLP16, VerticalOffsets
from rigd.errors import DatasetError
from rigd.report import PriorYaml, TransformYaml


class CameraKind(Enum):
    EQUIRECTANGULAR = "equirectangular"
    PINHOLE = "pinhole"
    FISHEYE = "fisheye"  # OpenCV's fisheye (equidistant) model, D = k1..k4
    HEAD = "head"  # several pinhole sensors at fixed poses in one head (a Ladybug's side cameras)


@dataclass(frozen=True)
class CameraConfig:
    """Camera intrinsics: a panorama size, or a pinhole ``K`` (3,3) px and OpenCV ``D``; ``mask``: a file of the
    dataset, non-zero where the image shows the scene (the rig's own body and a rectified image's black surround
    are zero)."""

    kind: CameraKind
    width: int
    height: int
    K: NDArray[np.float64] | None = None
    D: NDArray[np.float64] | None = None
    mask: str | None = None
    # How well the principal point is known, px (1 sigma, each axis; a calibration tool reports it): one camera
    # cannot tell its error from a tilt of the LiDAR, so it enters the rotation's sigma (docs/trust.md).
    principal_point_sigma_px: float | None = None

    def model(self) -> CameraModel:
        if self.kind is CameraKind.EQUIRECTANGULAR:
            return Equirectangular(self.width, self.height)
        assert self.K is not None
        if self.kind is CameraKind.FISHEYE:
            return Fisheye(self.K, self.D if self.D is not None else np.zeros(4), self.width, self.height)
        return Pinhole(self.K, self.D if self.D is not None else np.zeros(5), self.width, self.height)

    def models(self) -> tuple[CameraModel, ...]:
        """The camera of each view (one: the camera itself)."""
        return (self.model(),)

    @property
    def view_names(self) -> tuple[str, ...]:
        return (SINGLE_VIEW,)

    @property
    def masks(self) -> tuple[str | None, ...]:
        return (self.mask,)

    def to_yaml(self) -> dict[str, Any]:
        out: dict[str, Any] = {"model": self.kind.value, "width": self.width, "height": self.height}
        if self.K is not None:
            out["K"] = np.asarray(self.K).tolist()
            out["D"] = np.asarray(self.D if self.D is not None else []).tolist()
        if self.mask is not None:
            out["mask"] = self.mask
        if self.principal_point_sigma_px is not None:
            out["principal_point_sigma_px"] = self.principal_point_sigma_px
        return out

    def intrinsics_sigma_rad(self) -> tuple[float, float]:
        """The principal point's sigma as rotations about the camera's x and y axes (rad): sigma / fy, sigma / fx;
        zero when it is not declared or the camera has no K."""
        if not self.principal_point_sigma_px or self.K is None:
            return (0.0, 0.0)
        sigma = self.principal_point_sigma_px
        return (sigma / float(self.K[1, 1]), sigma / float(self.K[0, 0]))

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> CameraConfig:
        try:
            kind = CameraKind(str(data["model"]))
            width, height = _pixels(data["width"], "width", where), _pixels(data["height"], "height", where)
            k = np.asarray(data["K"], dtype=np.float64) if "K" in data else None
            d = np.asarray(data.get("D", []), dtype=np.float64) if k is not None else None
            mask = None if data.get("mask") is None else _inside(str(data["mask"]), "mask", where)
            pp_sigma = None if data.get("principal_point_sigma_px") is None \
                else float(data["principal_point_sigma_px"])
        except (KeyError, TypeError, ValueError) as exc:
            raise DatasetError(f"{where}: bad camera section ({exc!r})") from exc
        if pp_sigma is not None and not (np.isfinite(pp_sigma) and 0.0 <= pp_sigma <= 100.0):
            raise DatasetError(f"{where}: principal_point_sigma_px must be 0 .. 100 px, got {pp_sigma:g}")
        if kind in (CameraKind.PINHOLE, CameraKind.FISHEYE) and k is None:
            raise DatasetError(f"{where}: a {kind.value} camera needs K")
        if kind is CameraKind.HEAD:
            raise DatasetError(f"{where}: a head's sensors are listed under camera.sensors")
        config = cls(kind, width, height, k, d, mask, pp_sigma)
        try:
            config.model()
        except CalibError as exc:
            raise DatasetError(f"{where}: {exc}") from exc
        return config


SINGLE_VIEW = "image"  # the view name of a single-camera dataset (pairs/NNNN/image.png)
_NAME = re.compile(r"^[A-Za-z0-9_-]{1,32}$")


@dataclass(frozen=True)
class SensorConfig:
    """One sensor of a multi-camera head: ``name`` (its images are pairs/NNNN/images/NAME.png), its pinhole
    ``camera`` (with its mask) and its factory pose ``T_head_camera`` (``p_head = R p_camera + t``, the camera
    in the OpenCV optical frame)."""

    name: str
    camera: CameraConfig
    T_head_camera: Transform

    def model(self) -> Mounted:
        to_camera = self.T_head_camera.inverse()
        return Mounted(self.name, cast(Pinhole | Fisheye, self.camera.model()), to_camera.rotation,
                       to_camera.translation_m)

    def to_yaml(self) -> dict[str, Any]:
        return {"name": self.name, **self.camera.to_yaml(),
                "T_head_camera": {"rpy_deg": self.T_head_camera.rpy_deg.tolist(),
                                  "xyz_m": self.T_head_camera.translation_m.tolist()}}

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> SensorConfig:
        if not isinstance(data, dict):
            raise DatasetError(f"{where}: each of camera.sensors must be a mapping, got {data!r}")
        name = str(data.get("name", ""))
        if not _NAME.match(name):
            raise DatasetError(f"{where}: sensor name {name!r} must be 1-32 letters, digits, '_' or '-'")
        here = f"{where}: sensor {name}"
        camera = CameraConfig.from_yaml(data, here)
        if camera.kind not in (CameraKind.PINHOLE, CameraKind.FISHEYE):
            raise DatasetError(f"{here}: a head's sensors are pinhole or fisheye cameras, got {camera.kind.value}")
        if "T_head_camera" not in data:
            raise DatasetError(f"{here}: needs T_head_camera (its pose in the head)")
        return cls(name, camera, transform_from_yaml(data["T_head_camera"], here))


@dataclass(frozen=True)
class HeadConfig:
    """A multi-camera head: its ``sensors`` (at least one, names unique). The extrinsics are then
    ``T_head_lidar`` (reported as T_camera_lidar: the head frame is the camera frame, docs/conventions.md)."""

    sensors: tuple[SensorConfig, ...]
    kind: CameraKind = CameraKind.HEAD

    @property
    def width(self) -> int:
        return max(s.camera.width for s in self.sensors)

    @property
    def height(self) -> int:
        return max(s.camera.height for s in self.sensors)

    def models(self) -> tuple[CameraModel, ...]:
        return tuple(s.model() for s in self.sensors)

    @property
    def view_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.sensors)

    @property
    def masks(self) -> tuple[str | None, ...]:
        return tuple(s.camera.mask for s in self.sensors)

    def to_yaml(self) -> dict[str, Any]:
        return {"model": CameraKind.HEAD.value, "sensors": [s.to_yaml() for s in self.sensors]}

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> HeadConfig:
        sensors = data.get("sensors") if isinstance(data, dict) else None
        if not isinstance(sensors, list) or not sensors:
            raise DatasetError(f"{where}: a head camera needs a non-empty list camera.sensors")
        parsed = tuple(SensorConfig.from_yaml(s, where) for s in sensors)
        names = [s.name for s in parsed]
        if len(set(names)) != len(names):
            raise DatasetError(f"{where}: sensor names must be unique, got {names}")
        return cls(parsed)


def camera_from_yaml(data: Any, where: str) -> CameraConfig | HeadConfig:
    """rig.yaml's ``camera`` section: one camera, or a head of sensors (``model: head``)."""
    if isinstance(data, dict) and data.get("model") == CameraKind.HEAD.value:
        return HeadConfig.from_yaml(data, where)
    return CameraConfig.from_yaml(data, where)


def transform_to_yaml(transform: Transform) -> TransformYaml:
    """The project's YAML form of a transform: matrix, quaternion_xyzw, rpy_deg, xyz_m."""
    return {
        "matrix": transform.matrix.tolist(),
        "quaternion_xyzw": transform.quaternion_xyzw.tolist(),
        "rpy_deg": transform.rpy_deg.tolist(),
        "xyz_m": transform.translation_m.tolist(),
    }


MAX_PIXELS = 65535  # a side of any image rigd reads (OpenCV's own limit on a whole image is 2^30 pixels)


def _pixels(value: Any, name: str, where: str) -> int:
    """A camera's width or height: a whole number of pixels (``true`` is no number, though Python reads it as 1)."""
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_PIXELS:
        raise DatasetError(f"{where}: camera {name} must be a whole number of pixels, 1 .. {MAX_PIXELS}, got {value!r}")
    return value


def _inside(path: str, name: str, where: str) -> str:
    """A file of the dataset named in rig.yaml: relative, and inside the dataset's folder."""
    if path.startswith("/") or ".." in path.split("/"):
        raise DatasetError(f"{where}: {name} {path!r} must be a file inside the dataset, named relative to it")
    return path


def transform_from_yaml(data: Any, where: str) -> Transform:
    """Read a transform given as ``matrix`` (4x4) or ``rpy_deg`` + ``xyz_m``."""
    if not isinstance(data, dict) or not ("matrix" in data or {"rpy_deg", "xyz_m"} <= set(data)):
        found = (f"it has {', '.join(map(str, data))}" if data else "it is empty") if isinstance(data, dict) \
            else f"got {type(data).__name__}"
        raise DatasetError(f"{where}: no transform: T_camera_lidar needs matrix (4x4) or rpy_deg and xyz_m ({found})")
    try:
        if "matrix" in data:
            return Transform.from_matrix(np.asarray(data["matrix"], dtype=np.float64))
        return Transform.from_rpy_xyz(np.asarray(data["rpy_deg"], float), np.asarray(data["xyz_m"], float))
    except (KeyError, TypeError, ValueError, CalibError) as exc:
        raise DatasetError(f"{where}: bad transform ({exc!r})") from exc


def _three(value: Any, name: str, where: str) -> NDArray[np.float64]:
    """One number or three, as (3,) float64."""
    try:
        arr = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"{where}: prior {name} must be one number or three, got {value!r}") from exc
    return arr


# Camera and LiDAR share one rig: the calibration takes a start farther apart than this for a wrong guess
# (calib.pipeline), and a lever arm given beyond it is one in the wrong unit (cm typed as metres) or another rig's.
MAX_LEVER_ARM_M = CalibParams.max_translation_m


def lever_arm_problem(xyz_m: Any) -> str | None:
    """Why a prior's lever arm (m) cannot be a rig's, naming the unit; None when it can."""
    xyz = np.asarray(xyz_m, dtype=np.float64)
    length = float(np.linalg.norm(xyz))
    if length <= MAX_LEVER_ARM_M:
        return None
    as_cm = ", ".join(f"{v / 100.0:g}" for v in xyz.tolist())
    return (f"the lever arm xyz_m {[round(v, 4) for v in xyz.tolist()]} puts the LiDAR {length:.2f} m from the "
            f"camera, more than the {MAX_LEVER_ARM_M:g} m any rig has: it is in metres (if these are cm, it is "
            f"[{as_cm}] m)")


def prior_from_yaml(data: Any, where: str) -> Prior:
    """``prior: {xyz_m: [x, y, z], sigma_cm: 1.0, rpy_deg: [r, p, y], sigma_deg: 2.0, fix_translation: false}``
    (every key optional; a sigma is one number or one per axis)."""
    if not isinstance(data, dict):
        raise DatasetError(f"{where}: 'prior' must be a mapping (xyz_m, sigma_cm, rpy_deg, sigma_deg), got {data!r}")
    unknown = set(data) - {"xyz_m", "sigma_cm", "rpy_deg", "sigma_deg", "fix_translation"}
    if unknown:
        raise DatasetError(f"{where}: unknown prior keys {sorted(unknown)}")
    fix = bool(data.get("fix_translation", False))
    xyz = _three(data["xyz_m"], "xyz_m", where) if "xyz_m" in data else None
    if xyz is not None and (problem := lever_arm_problem(xyz)) is not None:
        raise DatasetError(f"{where}: prior: {problem}")
    sigma_t = _three(data["sigma_cm"], "sigma_cm", where) / 100.0 if "sigma_cm" in data else None
    if xyz is not None and sigma_t is None and not fix:
        raise DatasetError(f"{where}: prior xyz_m needs sigma_cm (or fix_translation: true)")
    rotation = rpy_deg_to_matrix(_three(data["rpy_deg"], "rpy_deg", where)) if "rpy_deg" in data else None
    sigma_r = np.radians(_three(data["sigma_deg"], "sigma_deg", where)) if "sigma_deg" in data else None
    try:
        return Prior(xyz, sigma_t, rotation, sigma_r, fix)
    except CalibError as exc:
        raise DatasetError(f"{where}: {exc}") from exc


def prior_to_yaml(prior: Prior) -> PriorYaml:
    """The ``prior`` section of rig.yaml (inverse of :func:`prior_from_yaml`)."""
    out: PriorYaml = {}
    if prior.xyz_m is not None:
        out["xyz_m"] = prior.xyz_m.tolist()
    if prior.sigma_xyz_m is not None:
        out["sigma_cm"] = (prior.sigma_xyz_m * 100.0).tolist()
    if prior.rotation is not None and prior.sigma_rot_rad is not None:
        out["rpy_deg"] = Transform(prior.rotation, np.zeros(3)).rpy_deg.tolist()
        out["sigma_deg"] = np.degrees(prior.sigma_rot_rad).tolist()
    if prior.fix_translation:
        out["fix_translation"] = True
    return out


# The field tolerance's bounds, the service's too (rigd/api/models.py): below them no sensor of the rig resolves a
# difference (a working pixel is 0.18 deg, a VLP-16 step 0.1-0.4 deg, its range accurate to 3 cm) and the verdict's
# arithmetic, which divides by them, breaks down (a tolerance of 1e-300 killed the calibration with a LinAlgError).
TOLERANCE_ROT_DEG = (0.001, 10.0)
TOLERANCE_TRANS_CM = (0.01, 100.0)
TOLERANCE_WHY = "finer than the rig's sensors resolve, or so coarse that any result would pass"


def tolerance_from_yaml(data: Any, where: str, bounded: bool = False) -> TrustOptions:
    """``tolerance: {rotation_deg: 0.2, translation_cm: 2.0}``: the field tolerance of the verdict; positive, and
    ``bounded`` (rig.yaml's) within ``TOLERANCE_ROT_DEG`` / ``TOLERANCE_TRANS_CM``. The worker's request tolerance
    is not bounded here: the service's request models bound it with the same numbers."""
    if not isinstance(data, dict) or set(data) - {"rotation_deg", "translation_cm", "rpy_deg", "xyz_cm"}:
        raise DatasetError(f"{where}: 'tolerance' must be a mapping with rotation_deg and/or translation_cm (and "
                           "each axis's own: rpy_deg, xyz_cm)")
    try:
        rot = float(data.get("rotation_deg", TrustOptions.tolerance_rot_deg))
        trans = float(data.get("translation_cm", TrustOptions.tolerance_trans_cm))
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"{where}: tolerance values must be numbers ({exc})") from exc
    if bounded:
        for key, value, (low, high), unit in (("rotation_deg", rot, TOLERANCE_ROT_DEG, "deg"),
                                              ("translation_cm", trans, TOLERANCE_TRANS_CM, "cm")):
            if not low <= value <= high:  # NaN too
                raise DatasetError(f"{where}: tolerance {key} must be within {low:g} .. {high:g} {unit}, got "
                                   f"{value:g}: {TOLERANCE_WHY}")
    elif not (np.isfinite(rot) and np.isfinite(trans) and rot > 0 and trans > 0):
        raise DatasetError(f"{where}: tolerance values must be positive, got {rot} deg, {trans} cm")
    axes = (*(_three(data["rpy_deg"], "tolerance rpy_deg", where) if "rpy_deg" in data else [rot] * 3),
            *(_three(data["xyz_cm"], "tolerance xyz_cm", where) if "xyz_cm" in data else [trans] * 3))
    if not all(np.isfinite(axes)) or min(axes) <= 0:
        raise DatasetError(f"{where}: each axis's tolerance must be positive, got {list(axes)}")
    per_axis = tuple(float(v) for v in axes) if {"rpy_deg", "xyz_cm"} & set(data) else ()
    return TrustOptions(tolerance_rot_deg=rot, tolerance_trans_cm=trans, tolerance_per_axis=per_axis)


SEARCH_KEYS = ("tilt_deg", "yaw_range_deg")


def search_from_yaml(data: Any, where: str) -> SearchOptions:
    """``search: {tilt_deg: 30, yaw_range_deg: 180}``: how far the global search for an initial guess looks
    (roll and pitch within +-tilt_deg, yaw within +-yaw_range_deg of the LiDAR's forward axis)."""
    if not isinstance(data, dict) or set(data) - set(SEARCH_KEYS):
        raise DatasetError(f"{where}: 'search' must be a mapping with tilt_deg and/or yaw_range_deg")
    try:
        values = {k: float(data[k]) for k in SEARCH_KEYS if k in data}
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"{where}: search values must be numbers ({exc})") from exc
    if not all(np.isfinite(v) and v >= 0 for v in values.values()) or values.get("yaw_range_deg", 180) > 180:
        raise DatasetError(f"{where}: search angles must be >= 0 (yaw_range_deg <= 180), got {values}")
    default = SearchOptions()
    return SearchOptions(tilt_deg=values.get("tilt_deg", default.tilt_deg),
                         yaw_range_deg=values.get("yaw_range_deg", default.yaw_range_deg))


@dataclass(frozen=True)
class RigConfig:
    """``rig.yaml``: the camera, the LiDAR model, an optional initial guess of T_camera_lidar, an optional
    prior from the rig's drawing, the field tolerance of the verdict and the global search's range."""

    camera: CameraConfig | HeadConfig
    lidar_model: str = "VLP-16"
    initial_guess: Transform | None = None
    prior: Prior | None = None
    tolerance: TrustOptions | None = None
    search: SearchOptions | None = None
    # deg: every cloud point is raised by this in elevation when a pair is loaded (the LiDAR's common elevation
    # offset, e.g. from rigd calibrate --fit-elevation-offset on a well-structured set; calib.elevation)
    lidar_elevation_offset_deg: float = 0.0
    # deg, how well that offset is known (1 sigma; 0: exact); None: not declared, the LiDAR model's own
    # (:data:`MODEL_ELEVATION_SIGMA_DEG`, :attr:`lidar_elevation_sigma_deg`)
    lidar_elevation_sigma_declared_deg: float | None = None
    # the VLP-16 manual's per-laser vertical offsets added to each cloud as it is loaded (rigd.dataset.lasers)
    lidar_vertical_offsets: VerticalOffsets = VerticalOffsets.AS_RECORDED

    @property
    def lidar_elevation_sigma_deg(self) -> float:
        """The sigma of the LiDAR's elevation offset the assessment takes, deg: the declared one, else the model's."""
        if self.lidar_elevation_sigma_declared_deg is not None:
            return self.lidar_elevation_sigma_declared_deg
        return MODEL_ELEVATION_SIGMA_DEG.get(self.lidar_model, 0.0)

    def to_yaml(self) -> dict[str, Any]:
        out: dict[str, Any] = {"camera": self.camera.to_yaml(), "lidar": {"model": self.lidar_model}}
        if self.lidar_elevation_offset_deg:
            out["lidar"]["elevation_offset_deg"] = self.lidar_elevation_offset_deg
        if self.lidar_elevation_sigma_declared_deg is not None:
            out["lidar"]["elevation_offset_sigma_deg"] = self.lidar_elevation_sigma_declared_deg
        if self.lidar_vertical_offsets is not VerticalOffsets.AS_RECORDED:
            out["lidar"]["vertical_offsets"] = self.lidar_vertical_offsets.value
        if self.initial_guess is not None:
            out["initial_guess"] = {
                "rpy_deg": self.initial_guess.rpy_deg.tolist(),
                "xyz_m": self.initial_guess.translation_m.tolist(),
            }
        if self.prior is not None:
            out["prior"] = prior_to_yaml(self.prior)
        if self.tolerance is not None:
            out["tolerance"] = {"rotation_deg": self.tolerance.tolerance_rot_deg,
                                "translation_cm": self.tolerance.tolerance_trans_cm}
            if self.tolerance.tolerance_per_axis:
                per_axis = list(self.tolerance.tolerance_per_axis)
                out["tolerance"] |= {"rpy_deg": per_axis[:3], "xyz_cm": per_axis[3:]}
        if self.search is not None:
            out["search"] = {"tilt_deg": self.search.tilt_deg, "yaw_range_deg": self.search.yaw_range_deg}
        return out

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> RigConfig:
        if not isinstance(data, dict) or "camera" not in data:
            raise DatasetError(f"{where}: rig file needs a 'camera' section")
        camera = camera_from_yaml(data["camera"], where)
        lidar = data.get("lidar") or {}
        if not isinstance(lidar, dict):
            raise DatasetError(f"{where}: 'lidar' must be a mapping with a 'model' key, got {lidar!r}")
        guess = data.get("initial_guess")
        initial = transform_from_yaml(guess, where) if guess else None
        prior = prior_from_yaml(data["prior"], where) if data.get("prior") is not None else None
        tolerance = (tolerance_from_yaml(data["tolerance"], where, bounded=True)
                     if data.get("tolerance") is not None else None)
        search = search_from_yaml(data["search"], where) if data.get("search") is not None else None
        model = str(lidar.get("model", VLP16))
        sigma = lidar.get("elevation_offset_sigma_deg")
        return cls(camera, model, initial, prior, tolerance, search,
                   _elevation_offset(lidar.get("elevation_offset_deg", 0.0), "elevation_offset_deg", where),
                   None if sigma is None else abs(_elevation_offset(sigma, "elevation_offset_sigma_deg", where)),
                   _vertical_offsets(lidar.get("vertical_offsets"), model, where))


# deg: the sigma of a LiDAR model's common elevation error (every beam a little high or low), which one camera cannot
# tell from a tilt, taken when rig.yaml declares none. A VLP-16 has nominal beam angles only (no per-unit table): the
# floor of the real unit in docs/results.md fits best with every beam 0.02-0.11 deg up, and worse from 0.25 deg on.
# Simulated LiDARs declare 0: their beams are where their table says.
MODEL_ELEVATION_SIGMA_DEG = {VLP16: 0.15}


def _vertical_offsets(value: Any, model: str, where: str) -> VerticalOffsets:
    if value is None:
        return VerticalOffsets.AS_RECORDED
    try:
        offsets = VerticalOffsets(str(value))
    except ValueError as exc:
        names = ", ".join(v.value for v in VerticalOffsets)
        raise DatasetError(f"{where}: lidar vertical_offsets must be one of {names}, got {value!r}") from exc
    if offsets is VerticalOffsets.MANUAL and model != VLP16:
        raise DatasetError(f"{where}: lidar vertical_offsets: manual is the {VLP16} manual's table; the LiDAR is "
                           f"{model}")
    return offsets


MAX_ELEVATION_OFFSET_DEG = 2.0  # a LiDAR's elevation table is good to tenths of a degree


def _elevation_offset(value: Any, key: str, where: str) -> float:
    try:
        offset = float(value)
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"{where}: lidar {key} must be a number of degrees, got {value!r}") from exc
    if not np.isfinite(offset) or abs(offset) > MAX_ELEVATION_OFFSET_DEG:
        raise DatasetError(f"{where}: lidar {key} must be within +-{MAX_ELEVATION_OFFSET_DEG:g} deg, got {offset:g}")
    return offset
