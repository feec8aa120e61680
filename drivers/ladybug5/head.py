"""The head calibration: each sensor's intrinsics, pose in the head and lens rectification, as the SDK holds them.

After ``ladybugLoadConfig`` the SDK knows the camera's factory calibration: per sensor a *rectified* pinhole
(``ladybugGetCameraUnitFocalLength``, ``...ImageCenter``, at the rectified size set with
``ladybugSetOffScreenImageSize``), its pose (``ladybugGetCameraUnitExtrinsics``: Euler ZYX angles in rad and a
translation in m, mapping the sensor's frame into the Ladybug frame) and the lens distortion, only as the
mapping ``ladybugRectifyPixel`` / ``ladybugUnrectifyPixel`` between raw and rectified pixels. rigd samples that
mapping into :class:`RectificationMaps` and fits an OpenCV pinhole + ``(k1, k2, p1, p2, k3)`` model of the raw
image to it, which the stitcher and the head dataset format use; the fit's residual says how well it holds.

Conventions: the rectified size is the raw (border-cropped) size, so the rectified focal length is in raw
pixels; a sensor's frame is the OpenCV optical frame of its image (x along columns, y along rows, z forward,
as FLIR's examples back-project rectified pixels); the Ladybug frame is taken as the head frame (x along
camera 0, z towards camera 5, docs/ladybug5.md). This module is pure NumPy: reading the SDK is sdk_head.py.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from drivers.geometry import matrix_to_rpy_deg, rpy_deg_to_matrix
from drivers.ladybug5.errors import HeadCalibrationError
from drivers.ladybug5.rig import (
    LADYBUG5_FOCAL_PX,
    LADYBUG5_RECTIFIED_FOCAL_PX,
    LADYBUG5_SIZE_PX,
    RigCamera,
    RigCameras,
    default_ladybug5_rig,
)

F64 = NDArray[np.float64]
FIT_WARN_PX = 0.5  # a distortion fit worse than this (rms, px) is reported as poor
_FIT_ITERATIONS = 50


class HeadSource(Enum):
    """Where a head calibration came from."""

    FACTORY = "factory"  # the camera's own calibration, read through the SDK (head, .cal file or .pgr stream)
    NOMINAL = "nominal"  # rigd's nominal Ladybug5 head: not a calibration of any camera
    FILE = "file"  # a rig camera file that does not say it is a factory calibration


@dataclass(frozen=True)
class RectificationMaps:
    """The SDK's raw <-> rectified pixel mapping sampled on a grid of columns ``grid_x`` (Wg,) and rows
    ``grid_y`` (Hg,), px. ``raw_to_rect`` (Hg, Wg, 2): rectified (x, y) of the raw pixel (grid_x[j],
    grid_y[i]); ``rect_to_raw`` (Hg, Wg, 2): raw (x, y) of that rectified pixel. NaN where the SDK maps the point
    outside (no such pixel)."""

    grid_x: F64
    grid_y: F64
    raw_to_rect: F64
    rect_to_raw: F64

    def dense_rect_to_raw(self, width: int, height: int) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """(height, width) float32 ``map_x, map_y`` for ``cv2.remap(raw, map_x, map_y, ...)`` -> the rectified
        image, by bilinear interpolation of the grid; -1 where the SDK has no raw pixel."""
        xs, ys = np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64)
        maps = []
        for k in (0, 1):
            rows = np.array([np.interp(xs, self.grid_x, line) for line in self.rect_to_raw[..., k]])
            full = np.array([np.interp(ys, self.grid_y, column) for column in rows.T]).T
            maps.append(np.where(np.isfinite(full), full, -1.0).astype(np.float32))
        return maps[0], maps[1]


@dataclass(frozen=True)
class LensFit:
    """An OpenCV model of the raw image fitted to the SDK's rectification: ``K`` (3,3) px, ``D`` (5,)
    ``(k1, k2, p1, p2, k3)``; residual ``rms_px`` / ``max_px`` over ``points`` grid points; ``folds`` True when
    the polynomial folds back inside the sampled field of view (the model is then not usable there)."""

    K: F64
    D: F64
    rms_px: float
    max_px: float
    points: int
    folds: bool

    @property
    def poor(self) -> bool:
        return self.folds or self.rms_px > FIT_WARN_PX


@dataclass(frozen=True)
class SensorCalibration:
    """One sensor: raw (border-cropped) image ``width`` x ``height`` px; the SDK's rectified ``focal_px`` and
    ``centre_px`` (x, y) at that size; ``extrinsics`` as ladybugGetCameraUnitExtrinsics returns them
    (rx, ry, rz rad, tx, ty, tz m); the fitted ``lens``; the sampled ``maps`` (None for a nominal head)."""

    name: str
    width: int
    height: int
    focal_px: float
    centre_px: tuple[float, float]
    extrinsics: tuple[float, float, float, float, float, float]
    lens: LensFit
    maps: RectificationMaps | None = None

    @property
    def R_head_camera(self) -> F64:
        return euler_zyx_matrix(*self.extrinsics[:3])

    @property
    def t_head_camera_m(self) -> F64:
        return np.array(self.extrinsics[3:], dtype=np.float64)

    def rig_camera(self) -> RigCamera:
        return RigCamera(self.name, self.width, self.height, self.lens.K, self.lens.D, self.R_head_camera,
                         self.t_head_camera_m)


@dataclass(frozen=True)
class HeadCalibration:
    """The six sensors in the SDK's order (0-4 around, 5 up), where they came from (``source``, and
    ``description`` for people), and the head's serial number when known."""

    sensors: tuple[SensorCalibration, ...]
    source: HeadSource
    description: str
    serial: int | None = None

    def to_rig(self) -> RigCameras:
        """The rig camera file's form, for the stitcher."""
        return RigCameras(f"Ladybug5 head, {self.source.value}: {self.description}",
                          tuple(s.rig_camera() for s in self.sensors))

    @property
    def sizes(self) -> tuple[tuple[int, int], ...]:
        """(width, height) px of each sensor's raw image."""
        return tuple((s.width, s.height) for s in self.sensors)

    def summary(self) -> str:
        """One line for people: which head this is (factory, or NOMINAL), of which camera, the worst lens fit."""
        what = {HeadSource.FACTORY: "factory head", HeadSource.NOMINAL: "NOMINAL head (not a calibration)",
                HeadSource.FILE: "head from a rig camera file (origin unknown)"}[self.source]
        serial = f" of camera {self.serial}" if self.serial else ""
        fitted = [s.lens for s in self.sensors if s.lens.points]
        fit = f"; distortion fit rms <= {max(f.rms_px for f in fitted):.3f} px" if fitted else ""
        return f"{what}{serial}: {self.description}{fit}"

    def poor_sensors(self) -> list[str]:
        """Sensors whose fitted OpenCV model does not hold the SDK's rectification (rms over FIT_WARN_PX px, or
        a polynomial that folds back inside the field of view), each with its residual."""
        return [f"{s.name} (rms {s.lens.rms_px:.2f} px, max {s.lens.max_px:.2f} px{', folds' if s.lens.folds else ''})"
                for s in self.sensors if s.lens.poor]

    @classmethod
    def from_rig(cls, rig: RigCameras, source: HeadSource, description: str) -> HeadCalibration:
        """A head from a rig camera file (no rectification maps; the file's model is taken as exact)."""
        sensors = tuple(_sensor_from_rig(c) for c in rig.cameras)
        return cls(sensors, source, description)

    @classmethod
    def nominal(cls, size_px: tuple[int, int]) -> HeadCalibration:
        """rigd's nominal Ladybug5 head at a sensor size (width, height) px: NOT a factory calibration. Its
        rectified pinhole is the SDK's of a real unit (``LADYBUG5_RECTIFIED_FOCAL_PX`` at 2448 px, scaled with the
        width; centred), its raw lens the nominal one."""
        head = cls.from_rig(default_ladybug5_rig(size_px), HeadSource.NOMINAL,
                            "rigd's nominal Ladybug5 head (not a factory calibration)")
        focal_px = LADYBUG5_RECTIFIED_FOCAL_PX * size_px[0] / LADYBUG5_SIZE_PX[0]
        return replace(head, sensors=tuple(replace(s, focal_px=focal_px) for s in head.sensors))


def euler_zyx_matrix(rx: float, ry: float, rz: float) -> F64:
    """(3,3) ``Rz(rz) @ Ry(ry) @ Rx(rx)`` (angles in rad): the SDK's extrinsics rotation (Craig's ZYX Euler)."""
    return rpy_deg_to_matrix(np.degrees([rx, ry, rz]))


def _sensor_from_rig(camera: RigCamera) -> SensorCalibration:
    rx, ry, rz = (float(v) for v in np.radians(matrix_to_rpy_deg(camera.R_head_camera)))
    tx, ty, tz = (float(v) for v in camera.t_head_camera_m)
    lens = LensFit(camera.K, camera.D, 0.0, 0.0, 0, False)
    return SensorCalibration(camera.name, camera.width, camera.height, float(camera.K[0, 0]),
                             (float(camera.K[0, 2]), float(camera.K[1, 2])), (rx, ry, rz, tx, ty, tz), lens)


def sensor_from_sdk(name: str, size_px: tuple[int, int], focal_px: float, centre_px: tuple[float, float],
                    extrinsics: tuple[float, ...], maps: RectificationMaps) -> SensorCalibration:
    """A sensor from what the SDK reported, with the OpenCV model fitted to its sampled rectification."""
    if len(extrinsics) != 6 or not np.all(np.isfinite(extrinsics)):
        raise HeadCalibrationError(f"{name}: the SDK's extrinsics are not six finite numbers: {extrinsics}")
    if not (np.isfinite(focal_px) and focal_px > 0):
        raise HeadCalibrationError(f"{name}: the SDK's rectified focal length is {focal_px} px")
    gx, gy = np.meshgrid(maps.grid_x, maps.grid_y)
    raw_xy = np.stack([gx, gy], axis=-1).reshape(-1, 2)
    rect = maps.raw_to_rect.reshape(-1, 2)
    keep = np.all(np.isfinite(rect), axis=1)
    if keep.sum() < 20:
        raise HeadCalibrationError(f"{name}: ladybugRectifyPixel mapped only {keep.sum()} of {len(keep)} raw pixels")
    normalised = (rect[keep] - np.asarray(centre_px)) / focal_px
    lens = fit_lens(raw_xy[keep], normalised, focal_px, centre_px)
    e = tuple(float(v) for v in extrinsics)
    return SensorCalibration(name, size_px[0], size_px[1], float(focal_px),
                             (float(centre_px[0]), float(centre_px[1])), (e[0], e[1], e[2], e[3], e[4], e[5]), lens,
                             maps)


def sensor_from_rays(name: str, size_px: tuple[int, int], extrinsics: tuple[float, ...], raw_xy: F64,
                     points_head: F64) -> SensorCalibration:
    """A sensor whose lens is fitted to raw pixels ``raw_xy`` (N,2) px and points ``points_head`` (N,3) m of the
    Ladybug frame on their rays (ladybugGet3dMap's sphere): no rectified pinhole (``focal_px``, ``centre_px`` NaN,
    no maps). Points behind the camera or not finite are left out."""
    if len(extrinsics) != 6 or not np.all(np.isfinite(extrinsics)):
        raise HeadCalibrationError(f"{name}: the SDK's extrinsics are not six finite numbers: {extrinsics}")
    e = tuple(float(v) for v in extrinsics)
    rays = (points_head - np.array(e[3:])) @ euler_zyx_matrix(*e[:3])  # R^T (p - t): the sensor's frame
    keep = np.all(np.isfinite(rays), axis=1) & (rays[:, 2] > 1e-9)
    if keep.sum() < 20:
        raise HeadCalibrationError(f"{name}: ladybugGet3dMap placed only {keep.sum()} of {len(keep)} raw pixels in "
                                   "front of the sensor")
    focal = LADYBUG5_FOCAL_PX * size_px[0] / LADYBUG5_SIZE_PX[0]  # the start; the fit finds the lens's own
    centre = ((size_px[0] - 1) / 2.0, (size_px[1] - 1) / 2.0)
    lens = fit_lens(raw_xy[keep], rays[keep, :2] / rays[keep, 2:], focal, centre)
    return SensorCalibration(name, size_px[0], size_px[1], float("nan"), (float("nan"), float("nan")),
                             (e[0], e[1], e[2], e[3], e[4], e[5]), lens)


def _model(params: F64, xy: F64) -> tuple[F64, F64]:
    """Projected raw pixels (N,2) and the Jacobian (2N, 9) w.r.t. (fx, fy, cx, cy, k1, k2, p1, p2, k3)."""
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = params
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    zero, one = np.zeros_like(x), np.ones_like(x)
    ju = [xd, zero, one, zero, fx * x * r2, fx * x * r2 * r2, fx * 2.0 * x * y, fx * (r2 + 2.0 * x * x),
          fx * x * r2 ** 3]
    jv = [zero, yd, zero, one, fy * y * r2, fy * y * r2 * r2, fy * (r2 + 2.0 * y * y), fy * 2.0 * x * y,
          fy * y * r2 ** 3]
    jacobian = np.concatenate([np.stack(ju, axis=1), np.stack(jv, axis=1)])
    return np.stack([fx * xd + cx, fy * yd + cy], axis=1), jacobian


def fit_lens(raw_xy: F64, normalised_xy: F64, focal_px: float, centre_px: tuple[float, float]) -> LensFit:
    """Least-squares OpenCV model ``raw = K distort(normalised)`` over (N,2) point pairs (Gauss-Newton from
    ``fx = fy = focal_px``, the centre, no distortion). ``focal_px`` is the SDK's rectified focal length, about a
    third of a Ladybug5's raw one (~450 against ~1275 px); the model is linear in ``fx, fy, cx, cy`` for a given
    distortion, so the fit converges from there in a few steps (tests/drivers/ladybug5: the fake SDK so set)."""
    params = np.array([focal_px, focal_px, centre_px[0], centre_px[1], 0, 0, 0, 0, 0], dtype=np.float64)
    for _ in range(_FIT_ITERATIONS):
        predicted, jacobian = _model(params, normalised_xy)
        residual = np.concatenate([raw_xy[:, 0] - predicted[:, 0], raw_xy[:, 1] - predicted[:, 1]])
        step = np.linalg.lstsq(jacobian, residual, rcond=None)[0]
        params = params + step
        if np.max(np.abs(step)) < 1e-10 * max(1.0, focal_px):
            break
    predicted, _ = _model(params, normalised_xy)
    error = np.linalg.norm(predicted - raw_xy, axis=1)
    k = np.array([[params[0], 0.0, params[2]], [0.0, params[1], params[3]], [0.0, 0.0, 1.0]])
    d = params[4:].copy()  # (k1, k2, p1, p2, k3): OpenCV's order
    probe = RigCamera("fit", 1, 1, k, d, np.eye(3), np.zeros(3))
    folds = bool(np.sqrt(np.max(np.sum(normalised_xy**2, axis=1))) > probe.max_undistorted_radius)
    return LensFit(k, d, float(np.sqrt(np.mean(error**2))), float(error.max()), len(raw_xy), folds)
