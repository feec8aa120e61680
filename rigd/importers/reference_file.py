"""A published calibration in the convention its authors wrote it, as the dataset's reference.

People publish a camera-LiDAR calibration as the camera's pose in the LiDAR frame or the LiDAR's in the camera
frame, as roll/pitch/yaw in radians or degrees before or after x y z, as x y z and a quaternion, or as a 4x4
matrix. Nothing in the numbers tells these apart, so the convention is named (``FRAME:LAYOUT``, e.g.
``camera-in-lidar:rpy-rad-xyz`` for the ACFR cam_lidar_calibration's CSV) and never guessed:

- FRAME ``camera-in-lidar``: the file's pose maps camera points into the LiDAR frame, ``p_lidar = R p_camera + t``;
  ``lidar-in-camera``: ``p_camera = R p_lidar + t``, rigd's ``T_camera_lidar``. The camera frame is the one the
  dataset's camera model uses (OpenCV's optical frame for a pinhole or fisheye).
- LAYOUT ``rpy-rad-xyz`` / ``rpy-deg-xyz`` / ``xyz-rpy-rad`` / ``xyz-rpy-deg`` (six numbers a row, ``R = Rz(yaw)
  Ry(pitch) Rx(roll)``, metres), ``xyz-quat-xyzw`` (seven), ``matrix`` (a 4x4, sixteen numbers in four rows).

The file is text, numbers split by commas or blanks; ``#`` starts a comment; a first line of names (a CSV header)
must name the layout's columns in its order. A file of several six-number rows (one calibration per row, as
the ACFR tool writes them) gives the mean of the rows whose every value lies within two standard deviations of
its column's mean (the rule the ACFR authors read their rows with), and as the reference's one-sigma the kept
rows' standard deviation: the spread of one calibration, not of their mean, since the rows reuse the same
frames and are not independent. That sigma is written per axis of the LiDAR's pose in the reference's own
LiDAR frame (rotation about the LiDAR's x, y, z; its origin's shift along them), so it stays well defined
whatever the camera frame's angles (a forward optical frame sits at the gimbal lock of rigd's rpy).
"""

from __future__ import annotations

import re
from enum import Enum
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from calib.errors import CalibError
from calib.geometry import Transform, quaternion_xyzw_to_matrix
from rigd.dataset.reference import Reference
from rigd.errors import DatasetError

F64 = NDArray[np.float64]
CLIP_SIGMAS = 2.0  # the ACFR authors' rule: a row is kept when every value lies within 2 std of its column's mean
MIN_ROWS_FOR_SIGMA = 3  # fewer rows give no spread worth calling a sigma


class PoseFrame(Enum):
    CAMERA_IN_LIDAR = "camera-in-lidar"  # p_lidar = R p_camera + t (ACFR, tf's camera frame under the LiDAR's)
    LIDAR_IN_CAMERA = "lidar-in-camera"  # p_camera = R p_lidar + t (rigd's T_camera_lidar, KITTI's Tr_velo_to_cam)


class Layout(Enum):
    RPY_RAD_XYZ = "rpy-rad-xyz"
    RPY_DEG_XYZ = "rpy-deg-xyz"
    XYZ_RPY_RAD = "xyz-rpy-rad"
    XYZ_RPY_DEG = "xyz-rpy-deg"
    XYZ_QUAT_XYZW = "xyz-quat-xyzw"
    MATRIX = "matrix"

    @property
    def columns(self) -> tuple[str, ...]:
        """The names a header line may give the columns, in order."""
        rpy, xyz = ("roll", "pitch", "yaw"), ("x", "y", "z")
        return {Layout.RPY_RAD_XYZ: rpy + xyz, Layout.RPY_DEG_XYZ: rpy + xyz, Layout.XYZ_RPY_RAD: xyz + rpy,
                Layout.XYZ_RPY_DEG: xyz + rpy, Layout.XYZ_QUAT_XYZW: xyz + ("qx", "qy", "qz", "qw"),
                Layout.MATRIX: ()}[self]

    @property
    def angle_period(self) -> tuple[slice, float] | None:
        """Where a row's roll, pitch, yaw are and their period (rad or deg); None for a quaternion or matrix."""
        if self in (Layout.XYZ_QUAT_XYZW, Layout.MATRIX):
            return None
        where = slice(0, 3) if self.columns[0] == "roll" else slice(3, 6)
        return where, 360.0 if self in (Layout.RPY_DEG_XYZ, Layout.XYZ_RPY_DEG) else 2.0 * np.pi


class Convention(NamedTuple):
    frame: PoseFrame
    layout: Layout

    @property
    def name(self) -> str:
        return f"{self.frame.value}:{self.layout.value}"


CONVENTIONS = tuple(f"{f.value}:{layout.value}" for f in PoseFrame for layout in Layout)


def parse_convention(text: str) -> Convention:
    """``FRAME:LAYOUT`` (one of :data:`CONVENTIONS`); DatasetError listing them otherwise."""
    frame, _, layout = text.partition(":")
    try:
        return Convention(PoseFrame(frame), Layout(layout))
    except ValueError:
        raise DatasetError(f"reference convention {text!r} is not one of {', '.join(CONVENTIONS)}") from None


def read_rows(path: Path, layout: Layout) -> F64:
    """The file's rows of numbers (R, C) float64; its header, if any, checked against ``layout``'s columns."""
    if not path.is_file():
        raise DatasetError(f"{path}: reference file is missing")
    try:
        lines = [line.split("#")[0].strip() for line in path.read_text().splitlines()]
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path}: not a readable text file ({exc})") from exc
    lines = [line for line in lines if line]
    if lines and not re.match(r"^[-+.\d]", lines[0]):
        names = tuple(n.strip().lower() for n in re.split(r"[,\s]+", lines.pop(0)) if n.strip())
        if names != layout.columns:
            raise DatasetError(f"{path}: the header names the columns {', '.join(names)}; the convention's layout "
                               f"{layout.value} has {', '.join(layout.columns) or 'no header'}")
    try:
        rows = [[float(v) for v in re.split(r"[,\s]+", line) if v] for line in lines]
    except ValueError as exc:
        raise DatasetError(f"{path}: a line is not numbers ({exc})") from exc
    width = 4 if layout is Layout.MATRIX else len(layout.columns)
    bad = next((i for i, row in enumerate(rows) if len(row) != width), None)
    if not rows or bad is not None:
        raise DatasetError(f"{path}: the {layout.value} layout needs rows of {width} numbers"
                           + (f"; data row {bad + 1} has {len(rows[bad])}" if bad is not None else "; none found"))
    values = np.asarray(rows, dtype=np.float64)
    if not np.all(np.isfinite(values)):
        raise DatasetError(f"{path}: holds a non-finite number")
    return values


def _pose(row: F64, layout: Layout) -> Transform:
    """One row (or the 4x4) as the transform it writes, in the file's frame."""
    if layout is Layout.MATRIX:
        return Transform.from_matrix(row.reshape(4, 4))
    if layout is Layout.XYZ_QUAT_XYZW:
        quaternion = row[3:] / np.linalg.norm(row[3:])
        return Transform(quaternion_xyzw_to_matrix(quaternion), row[:3])
    rpy, xyz = (row[:3], row[3:]) if layout in (Layout.RPY_RAD_XYZ, Layout.RPY_DEG_XYZ) else (row[3:], row[:3])
    degrees = layout in (Layout.RPY_DEG_XYZ, Layout.XYZ_RPY_DEG)
    return Transform.from_rpy_xyz(rpy if degrees else np.degrees(rpy), xyz)


def _camera_lidar(row: F64, convention: Convention) -> Transform:
    pose = _pose(row, convention.layout)
    return pose.inverse() if convention.frame is PoseFrame.CAMERA_IN_LIDAR else pose


def kept_rows(rows: F64) -> NDArray[np.bool_]:
    """(R,) the rows whose every value lies within :data:`CLIP_SIGMAS` standard deviations of its column's mean."""
    mean, std = rows.mean(axis=0), rows.std(axis=0)
    return np.asarray(np.all(np.abs(rows - mean) <= CLIP_SIGMAS * std, axis=1))


def _spread(kept: list[Transform], reference: Transform) -> F64 | None:
    """(6,) the rows' std as [x, y, z (m), roll, pitch, yaw (deg)] of the LiDAR in the reference's LiDAR frame."""
    in_frame = [reference.inverse().compose(T) for T in kept]
    forms = np.array([np.concatenate([T.translation_m, T.rpy_deg]) for T in in_frame])
    sigma = forms.std(axis=0)
    return sigma if len(kept) >= MIN_ROWS_FOR_SIGMA and np.all(sigma > 0) else None


def read_reference(path: Path, convention: Convention) -> Reference:
    """The reference ``T_camera_lidar`` the file gives in ``convention``, with the rows' spread as its sigma when
    it holds several calibrations (module docstring)."""
    path = Path(path)
    layout = convention.layout
    rows = read_rows(path, layout)
    if layout is Layout.MATRIX and len(rows) != 4:
        raise DatasetError(f"{path}: a matrix reference is one 4x4 (four rows of four numbers), this file has "
                           f"{len(rows)} rows")
    if layout.angle_period is None and len(rows) > 1 and layout is not Layout.MATRIX:
        raise DatasetError(f"{path}: a {layout.value} reference holds one pose, this file {len(rows)}")
    if layout is Layout.MATRIX:
        rows = rows.reshape(1, 16)
    if layout.angle_period is not None:  # each angle taken within half a turn of the first row's, then averaged
        angles, period = layout.angle_period
        rows[:, angles] = rows[0, angles] + (rows[:, angles] - rows[0, angles] + period / 2) % period - period / 2
    keep = kept_rows(rows)
    try:
        T = _camera_lidar(rows[keep].mean(axis=0), convention)
        kept = [_camera_lidar(row, convention) for row in rows[keep]]
    except CalibError as exc:
        raise DatasetError(f"{path}: not a rigid pose in {convention.name} ({exc})") from exc
    sigma = _spread(kept, T)
    source = (f"{path.name} ({convention.name}"
              + (f"; mean of {int(keep.sum())} of {len(rows)} rows within {CLIP_SIGMAS:g} std of their column's "
                 "mean, sigma their std)" if len(rows) > 1 else ")"))
    return Reference(T, sigma, T.inverse() if sigma is not None else Transform.identity(), source)
