"""Extrinsics in other tools' formats, for the service (``/extrinsics?format=``) and ``rigd export``.

Every format is of ``T_camera_lidar`` (``p_camera = R p_lidar + t``): the LiDAR frame's pose in the camera frame,
so the camera frame is the parent of a transform tree and the LiDAR frame its child. ``label`` says where the
transform came from (an extrinsics version, a file) in a comment of the text formats.

Frame names reach generated code (a Python launch file) and XML (URDF): every writer here takes only ROS names
(:func:`frame_problem`), whoever gives them (the CLI, the service, a bag's headers), and escapes the label, which
may hold any text of a file's path.
"""

from __future__ import annotations

import re
from enum import Enum
from xml.sax.saxutils import quoteattr

import cv2
import numpy as np
import yaml

from calib.geometry import Transform
from rigd.errors import RigdError

# A ROS name's tokens (letters, digits, '_', not starting with a digit) joined by single '/': what tf2 and
# every ROS tool take as a frame id, and no text that can end a Python string, an XML attribute or a comment.
ROS_NAME_PATTERN = r"^[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$"
MAX_NAME_LENGTH = 128
_ROS_NAME = re.compile(ROS_NAME_PATTERN)


class ExportError(RigdError):
    """A transform cannot be written as asked (a frame name that is no ROS name); the message names it."""


def frame_problem(name: str) -> str | None:
    """Why ``name`` cannot be a frame id of the exports, or None when it can."""
    if len(name) > MAX_NAME_LENGTH:
        return f"is {len(name)} characters long, more than {MAX_NAME_LENGTH}"
    if name.startswith("/"):
        return "starts with '/' (tf2 frame ids do not; drop it)"
    if not _ROS_NAME.fullmatch(name):
        return ("is not a ROS name: letters, digits and '_', not starting with a digit, in parts joined by single "
                "'/'")
    return None


def check_frames(**frames: str) -> None:
    """ExportError naming the first of ``frames`` (by role: ``camera_frame=...``) that is no ROS name."""
    for role, name in frames.items():
        problem = frame_problem(name)
        if problem is not None:
            raise ExportError(f"the {role.replace('_', ' ')} {name!r} {problem}")


def _plain(text: str) -> str:
    """``text`` on one line of printable characters (others spelt as Python escapes), for a comment."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class ExportFormat(Enum):
    YAML = "yaml"
    JSON = "json"
    ROS_TF = "ros-tf"
    ROS2_LAUNCH = "ros2-launch"
    URDF = "urdf"
    KALIBR = "kalibr"
    OPENCV = "opencv"


def _static_args(T: Transform, camera_frame: str, lidar_frame: str) -> list[str]:
    """tf2_ros static_transform_publisher's named arguments (ROS 2 Foxy and later)."""
    x, y, z = T.translation_m.tolist()
    qx, qy, qz, qw = T.quaternion_xyzw.tolist()
    values = {"x": x, "y": y, "z": z, "qx": qx, "qy": qy, "qz": qz, "qw": qw}
    return [a for k, v in values.items() for a in (f"--{k}", repr(v))] + \
        ["--frame-id", camera_frame, "--child-frame-id", lidar_frame]


def ros_tf(T: Transform, label: str, camera_frame: str, lidar_frame: str) -> str:
    """A geometry_msgs/TransformStamped (the LiDAR frame's pose in the camera frame) and the command that
    publishes it as a static transform."""
    x, y, z = T.translation_m.tolist()
    qx, qy, qz, qw = T.quaternion_xyzw.tolist()
    command = "ros2 run tf2_ros static_transform_publisher " + " ".join(_static_args(T, camera_frame, lidar_frame))
    message = {
        "header": {"frame_id": camera_frame},
        "child_frame_id": lidar_frame,
        "transform": {"translation": {"x": x, "y": y, "z": z}, "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}},
    }
    return f"# rigd {_plain(label)}\n# {command}\n" + yaml.safe_dump(message, sort_keys=False)


def ros2_launch(T: Transform, label: str, camera_frame: str, lidar_frame: str) -> str:
    """A ROS 2 Python launch file that publishes the transform with tf2_ros' static_transform_publisher."""
    arguments = ",\n                ".join(repr(a) for a in _static_args(T, camera_frame, lidar_frame))
    docstring = repr(f"rigd {label}: T_camera_lidar as a static transform {camera_frame} -> {lidar_frame}.")
    return f'''{docstring}

from launch import LaunchDescription
from launch_ros.actions import Node


def generate_launch_description():
    return LaunchDescription([
        Node(
            package="tf2_ros",
            executable="static_transform_publisher",
            name="rigd_camera_lidar",
            arguments=[
                {arguments},
            ],
        ),
    ])
'''


def urdf(T: Transform, label: str, camera_frame: str, lidar_frame: str) -> str:
    """A URDF fixed joint placing the LiDAR link in the camera link (rpy in radians, URDF's fixed-axis roll, pitch,
    yaw: the same R = Rz Ry Rx as rigd's rpy_deg)."""
    xyz = " ".join(repr(v) for v in T.translation_m.tolist())
    rpy = " ".join(repr(v) for v in np.radians(T.rpy_deg).tolist())
    name = quoteattr(f"{camera_frame}_to_{lidar_frame}".replace("/", "_"))
    # XML comments may not hold "--" (nor end in "-"): the label is a file's path, which may.
    text = _plain(f"rigd {label}: T_camera_lidar, p_{camera_frame} = R p_{lidar_frame} + t")
    comment = re.sub(r"-(?=-|$)", "- ", text)
    return (f"<!-- {comment} -->\n"
            f'<joint name={name} type="fixed">\n'
            f"  <parent link={quoteattr(camera_frame)}/>\n"
            f"  <child link={quoteattr(lidar_frame)}/>\n"
            f'  <origin xyz="{xyz}" rpy="{rpy}"/>\n'
            "</joint>\n")


def kalibr(T: Transform, label: str) -> str:
    """Kalibr camchain style: T_cam_lidar maps LiDAR points into cam0, as Kalibr's T_cam_imu does for an IMU."""
    body = {"cam0": {"T_cam_lidar": T.matrix.tolist()}}
    return f"# rigd {_plain(label)}\n" + yaml.safe_dump(body, sort_keys=False)


def opencv(T: Transform, version: int | None = None) -> str:
    """cv::FileStorage YAML (written by OpenCV itself): R (3x3), t (3x1, m), T (4x4), rpy_deg."""
    fs = cv2.FileStorage("extrinsics.yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    if version is not None:
        fs.write("extrinsics_version", version)
    fs.write("R", T.rotation)
    fs.write("t", T.translation_m.reshape(3, 1))
    fs.write("T", T.matrix)
    fs.write("rpy_deg", np.asarray(T.rpy_deg).reshape(1, 3))
    return fs.releaseAndGetString()


def render_transform(T: Transform, fmt: ExportFormat, *, label: str, camera_frame: str, lidar_frame: str,
                     version: int | None = None) -> str:
    """``T`` in one of the transform formats (not YAML or JSON, which are of a whole version record);
    ExportError when a frame name is no ROS name."""
    check_frames(camera_frame=camera_frame, lidar_frame=lidar_frame)
    if fmt is ExportFormat.ROS_TF:
        return ros_tf(T, label, camera_frame, lidar_frame)
    if fmt is ExportFormat.ROS2_LAUNCH:
        return ros2_launch(T, label, camera_frame, lidar_frame)
    if fmt is ExportFormat.URDF:
        return urdf(T, label, camera_frame, lidar_frame)
    if fmt is ExportFormat.KALIBR:
        return kalibr(T, label)
    if fmt is ExportFormat.OPENCV:
        return opencv(T, version)
    raise ValueError(f"{fmt.value} is a record format, not a transform format")
