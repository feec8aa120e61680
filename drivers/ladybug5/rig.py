"""The rig camera file: each of the six Ladybug cameras as an OpenCV pinhole plus its pose in the head.

YAML layout (docs/ladybug5.md)::

    model: <free text>
    cameras:
      - name: cam0
        width: 2448                      # px, the image as decoded (raw sensor orientation)
        height: 2048
        K: [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
        D: [k1, k2, p1, p2, k3]          # OpenCV distortion
        T_head_camera:                   # maps camera (OpenCV optical) points into the head frame
          matrix: 4x4                    # readers take matrix, or rpy_deg + xyz_m
          quaternion_xyzw: [...]
          rpy_deg: [...]
          xyz_m: [...]

The head frame is the panorama frame: x forward, y left, z up, origin at the head centre.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from drivers.geometry import matrix_to_quaternion_xyzw, matrix_to_rpy_deg, rpy_deg_to_matrix
from drivers.ladybug5.errors import RigFileError

F64 = NDArray[np.float64]
_MIN_DEPTH_M = 1e-9


def _max_undistorted_radius(d: F64) -> float:
    """Largest normalised radius up to which the radial distortion polynomial is still increasing.

    Past that radius it folds back, and far-off-axis rays would land inside the image; they are invalid.
    """
    k1, k2, _, _, k3 = d
    r = np.linspace(0.0, 10.0, 4001)  # tan(84 deg) ~ 9.5: beyond any Ladybug lens
    r2 = r * r
    slope = 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2 + 7.0 * k3 * r2 * r2 * r2  # d(r * radial)/dr
    folds = np.nonzero(slope <= 0.0)[0]
    return float(r[folds[0] - 1]) if folds.size else float(r[-1])


@dataclass(frozen=True)
class RigCamera:
    """One camera: ``K`` (3,3) px, ``D`` (5,) OpenCV, size in px, pose ``T_head_camera`` (R (3,3), t (3,) m)."""

    name: str
    width: int
    height: int
    K: F64
    D: F64
    R_head_camera: F64
    t_head_camera_m: F64

    @property
    def max_undistorted_radius(self) -> float:
        return _max_undistorted_radius(self.D)

    def project(self, points_cam: F64) -> tuple[F64, NDArray[np.bool_]]:
        """Camera-frame points (N,3) m -> raw-image ``uv`` (N,2) px and ``valid`` (N,) (in front, unfolded,
        inside the image). Same model as ``cv2.projectPoints`` with ``D = (k1, k2, p1, p2, k3)``."""
        p = np.asarray(points_cam, dtype=np.float64)
        z = p[:, 2]
        front = z > _MIN_DEPTH_M
        zs = np.where(front, z, 1.0)
        x, y = p[:, 0] / zs, p[:, 1] / zs
        r2 = x * x + y * y
        k1, k2, p1, p2, k3 = self.D
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        u = self.K[0, 0] * xd + self.K[0, 1] * yd + self.K[0, 2]
        v = self.K[1, 1] * yd + self.K[1, 2]
        inside = (u >= 0.0) & (u <= self.width - 1.0) & (v >= 0.0) & (v <= self.height - 1.0)
        valid = front & (r2 < self.max_undistorted_radius**2) & inside
        return np.stack([u, v], axis=1), valid


@dataclass(frozen=True)
class RigCameras:
    """The six cameras of a head, in the order the SDK numbers them (0-4 around, 5 up)."""

    model: str
    cameras: tuple[RigCamera, ...]


def transform_yaml(rotation: F64, translation_m: F64) -> dict[str, Any]:
    """A pose in the project's four YAML forms: matrix (4x4), quaternion_xyzw, rpy_deg, xyz_m (m)."""
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = rotation, translation_m
    return {
        "matrix": matrix.round(12).tolist(),
        "quaternion_xyzw": matrix_to_quaternion_xyzw(rotation).round(12).tolist(),
        "rpy_deg": matrix_to_rpy_deg(rotation).round(9).tolist(),
        "xyz_m": np.asarray(translation_m).round(12).tolist(),
    }


def rig_to_yaml(rig: RigCameras) -> dict[str, Any]:
    return {
        "model": rig.model,
        "cameras": [
            {
                "name": c.name,
                "width": c.width,
                "height": c.height,
                "K": c.K.tolist(),
                "D": c.D.tolist(),
                "T_head_camera": transform_yaml(c.R_head_camera, c.t_head_camera_m),
            }
            for c in rig.cameras
        ],
    }


def _rotation_from_yaml(data: dict[str, Any], where: str) -> tuple[F64, F64]:
    if "matrix" in data:
        m = np.asarray(data["matrix"], dtype=np.float64)
        if m.shape != (4, 4):
            raise RigFileError(f"{where}: T_head_camera.matrix must be 4x4, got shape {m.shape}")
        rotation, translation = m[:3, :3], m[:3, 3]
    else:
        rotation = rpy_deg_to_matrix(np.asarray(data["rpy_deg"], dtype=np.float64))
        translation = np.asarray(data["xyz_m"], dtype=np.float64)
    if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) or np.linalg.det(rotation) < 0:
        raise RigFileError(f"{where}: T_head_camera rotation is not a rotation matrix")
    return rotation, translation.reshape(3)


def _camera_from_yaml(data: Any, where: str) -> RigCamera:
    try:
        k = np.asarray(data["K"], dtype=np.float64)
        d = np.zeros(5)
        d_in = np.asarray(data.get("D", []), dtype=np.float64).reshape(-1)
        if k.shape != (3, 3) or d_in.size not in (0, 4, 5):
            raise RigFileError(f"{where}: K must be 3x3 and D have 0, 4 or 5 numbers")
        d[: d_in.size] = d_in
        rotation, translation = _rotation_from_yaml(data["T_head_camera"], where)
        camera = RigCamera(str(data["name"]), int(data["width"]), int(data["height"]), k, d, rotation, translation)
    except (KeyError, TypeError, ValueError) as exc:
        raise RigFileError(f"{where}: bad camera entry ({exc!r})") from exc
    if camera.width <= 0 or camera.height <= 0:
        raise RigFileError(f"{where}: image size must be positive")
    return camera


def _head_sensors(data: dict[str, Any], where: str) -> list[Any] | None:
    """The sensors of a head calibration file (``rigd camera export-head``: ``camera: {model: head, sensors}``,
    the head dataset format's form), or None when ``data`` is not one."""
    camera = data.get("camera")
    if not isinstance(camera, dict) or camera.get("model") != "head":
        return None
    sensors = camera.get("sensors")
    if not isinstance(sensors, list) or not sensors:
        raise RigFileError(f"{where}: camera.sensors must be a non-empty list")
    for i, sensor in enumerate(sensors):
        if isinstance(sensor, dict) and sensor.get("model", "pinhole") != "pinhole":
            raise RigFileError(f"{where}: camera.sensors[{i}] is a {sensor.get('model')} sensor; the Ladybug5 "
                               "stitcher takes pinhole sensors")
    return sensors


def rig_from_yaml(data: Any, where: str) -> RigCameras:
    """A rig camera file (``cameras: [...]``) or a head calibration file (``camera: {model: head, sensors}``)."""
    sensors = _head_sensors(data, where) if isinstance(data, dict) else None
    if sensors is not None:
        head = data.get("head")
        model = str(head.get("description", "")) if isinstance(head, dict) else "head calibration file"
        return RigCameras(model, tuple(_camera_from_yaml(c, f"{where}: camera.sensors[{i}]")
                                       for i, c in enumerate(sensors)))
    if not isinstance(data, dict) or not isinstance(data.get("cameras"), list) or not data["cameras"]:
        raise RigFileError(f"{where}: expected a mapping with a non-empty 'cameras' list (or a head calibration "
                           "file's camera.sensors)")
    cameras = tuple(_camera_from_yaml(c, f"{where}: cameras[{i}]") for i, c in enumerate(data["cameras"]))
    return RigCameras(str(data.get("model", "")), cameras)


def load_rig(path: Path) -> RigCameras:
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise RigFileError(f"cannot read rig camera file {path}: {exc}") from exc
    except yaml.YAMLError as exc:
        raise RigFileError(f"rig camera file {path} is not valid YAML: {exc}") from exc
    return rig_from_yaml(data, str(path))


def save_rig(rig: RigCameras, path: Path) -> None:
    Path(path).write_text(yaml.safe_dump(rig_to_yaml(rig), sort_keys=False, width=120, default_flow_style=None))


# Nominal head (docs/ladybug5.md, "Default head"). Geometry as two public factory calibrations of real Ladybug5
# heads give it (an SDK calibration of an LD5-U3-51S5C-44, serial 15402620, and an Optech camera file of another
# unit): camera i looks out level at azimuth -72 deg * i (clockwise from above: camera 1 is on the right), its
# centre 6.08-6.16 cm out along its axis; the top camera's 7.47-7.60 cm up. The sensors lie on their side:
# a side camera's image columns (x, the long 2448 px side) run down (-z), its rows (y) along the horizontal; the
# top camera's columns run backwards (-x), its rows right (-y). The lens is not in those files (the SDK gives it
# only as a mapping): 4.4 mm on the Sony ICX655's 3.45 um pixels is f = 1275 px in the raw image, while the SDK's
# rectified pinhole at 2448x2048 has f = 443-464 px. The barrel distortion is our choice, not a factory
# calibration: it widens each camera so the head covers ~90 % of the sphere as FLIR's datasheet says (a
# distortion-free 1275 px pinhole would leave a gap between the side and top cameras), and it is monotonic at
# every radius so the model never folds.
LADYBUG5_SIZE_PX = (2448, 2048)
LADYBUG5P_SIZE_PX = (2464, 2048)  # the Ladybug5+ (LADYBUG_RESOLUTION_2464x2048 in the SDK's header)
LADYBUG5_FOCAL_PX = 4.4e-3 / 3.45e-6  # the raw image's, px at 2448x2048
LADYBUG5_RECTIFIED_FOCAL_PX = 452.0  # the SDK's rectified pinhole's, px at 2448x2048 (one unit's mean, 443-457)
LADYBUG5_DISTORTION = (-0.2, 0.03, 0.0, 0.0, 0.0)
LADYBUG5_CAMERA_RADIUS_M = 0.0613  # side camera centres from the head's axis (one unit's mean, 6.12-6.16 cm)
LADYBUG5_TOP_HEIGHT_M = 0.076  # the top camera's centre above the side cameras' plane
LADYBUG5_SIDE_YAW_STEP_DEG = -72.0  # camera i's optical axis at azimuth i times this
# The top camera's optical frame in the head: columns along -x, rows along -y, optical axis up.
_TOP_ROTATION = np.array([[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]])


def _side_rotation(yaw_rad: float) -> F64:
    """(3,3) a side camera's optical frame in the head: optical axis level at azimuth ``yaw_rad``, image columns
    down (-z), rows along the horizontal (z x columns: the camera's left)."""
    forward = np.array([np.cos(yaw_rad), np.sin(yaw_rad), 0.0])
    columns = np.array([0.0, 0.0, -1.0])  # the long image axis points down
    rows = np.cross(forward, columns)  # y = z x x keeps the optical frame right-handed
    return np.stack([columns, rows, forward], axis=1) + 0.0  # + 0.0: no -0.0 in the rig file


def default_ladybug5_rig(size_px: tuple[int, int] = LADYBUG5_SIZE_PX) -> RigCameras:
    """A Ladybug5 head of sensors ``size_px`` (width, height) px (Ladybug5+: ``LADYBUG5P_SIZE_PX``) with the
    nominal geometry above: cameras 0-4 at azimuths 0, -72, ... -288 deg (camera 0 looks along +x), camera 5 up."""
    width, height = size_px
    k = np.array([[LADYBUG5_FOCAL_PX, 0.0, (width - 1) / 2.0], [0.0, LADYBUG5_FOCAL_PX, (height - 1) / 2.0], [0, 0, 1]])
    d = np.array(LADYBUG5_DISTORTION)
    cameras = []
    for i in range(5):
        rotation = _side_rotation(np.radians(i * LADYBUG5_SIDE_YAW_STEP_DEG))
        cameras.append(RigCamera(f"cam{i}", width, height, k, d, rotation, LADYBUG5_CAMERA_RADIUS_M * rotation[:, 2]))
    cameras.append(RigCamera("cam5", width, height, k, d, _TOP_ROTATION.copy(),
                             np.array([0.0, 0.0, LADYBUG5_TOP_HEIGHT_M])))
    return RigCameras("Ladybug5 nominal head (rigd; the geometry of real units, not a factory calibration)",
                      tuple(cameras))


def scaled_ladybug5_rig(width_px: int) -> RigCameras:
    """rigd's nominal head with each sensor ``width_px`` wide (height and focal length scaled with it, so every
    sensor keeps the nominal field of view): the simulated Ladybug's head (small images render fast)."""
    if width_px < 8:
        raise RigFileError(f"a scaled Ladybug5 head needs sensors at least 8 px wide, got {width_px}")
    scale = width_px / LADYBUG5_SIZE_PX[0]
    height = round(LADYBUG5_SIZE_PX[1] * scale)
    nominal = default_ladybug5_rig((width_px, height))
    cameras = []
    for camera in nominal.cameras:
        k = camera.K.copy()
        k[0, 0] = k[1, 1] = LADYBUG5_FOCAL_PX * scale
        cameras.append(RigCamera(camera.name, width_px, height, k, camera.D, camera.R_head_camera,
                                 camera.t_head_camera_m))
    return RigCameras(f"Ladybug5 nominal head scaled to {width_px}x{height} px sensors (rigd; nominal values)",
                      tuple(cameras))
