"""Small bags for the bag importer's tests, written with rosbags' own writers (ROS 1, ROS 2 sqlite3, MCAP) from the
real data in tests/data: the legacy VLP-16 capture's turns as velodyne_msgs/VelodyneScan, turned about the
LiDAR's z axis (the blocks' azimuths shifted) to play a rig that turns between stops, and the pinhole sample's
image (reduced) as CompressedImage with its CameraInfo."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import cv2
import numpy as np
import yaml
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from drivers.vlp16 import read_batches
from drivers.vlp16.layout import as_packet_records
from tests.testdata import LEGACY_PCAP, PINHOLE_FRAME

T0_S = 1_700_000_000.0
SCALE = 0.25  # the pinhole sample's 1920x1200 image reduced to 480x300 (K with it)
ROS1_VELODYNE = {"velodyne_msgs/msg/VelodynePacket": "time stamp\nuint8[1206] data\n",
                 "velodyne_msgs/msg/VelodyneScan": "Header header\nvelodyne_msgs/VelodynePacket[] packets\n"}
ROS2_VELODYNE = {"velodyne_msgs/msg/VelodynePacket": "builtin_interfaces/Time stamp\nuint8[1206] data\n",
                 "velodyne_msgs/msg/VelodyneScan": "std_msgs/Header header\nvelodyne_msgs/VelodynePacket[] packets\n"}


class BagFormat(Enum):
    ROS1 = "ros1"
    SQLITE3 = "sqlite3"
    MCAP = "mcap"


STILL_TURNS = 12  # the capture's sensor creeps: its turns after the first ~25 move by more than the gate allows


@functools.cache
def legacy_turns() -> tuple[np.ndarray, ...]:
    """The legacy capture's first whole turns: (P,1206) uint8 data packets each (split where the azimuth wraps);
    the gate sees them within 0.02 deg and 1 mm of each other, a still sensor."""
    packets = np.concatenate([b.data for b in read_batches(LEGACY_PCAP) if len(b.data)])
    azimuth = as_packet_records(packets)["blocks"]["azimuth"][:, 0].astype(np.int64)
    wraps = np.flatnonzero(np.diff(azimuth) < 0) + 1
    return tuple(packets[a:b] for a, b in zip(wraps[:-1], wraps[1:], strict=True))[:STILL_TURNS]


def turned(packets: np.ndarray, yaw_deg: float) -> np.ndarray:
    """The packets of a LiDAR turned by ``yaw_deg`` about its z axis (clockwise azimuths shifted)."""
    out = packets.copy()
    records = as_packet_records(out)
    blocks = records["blocks"]
    blocks["azimuth"] = (blocks["azimuth"].astype(np.int64) + int(round(yaw_deg * 100))) % 36000
    records["blocks"] = blocks
    return out


@functools.cache
def pinhole_jpeg() -> tuple[bytes, np.ndarray, tuple[int, int]]:
    """The pinhole sample reduced by SCALE: JPEG bytes, its K (3,3) px and (width, height)."""
    image = cv2.imread(str(PINHOLE_FRAME / "image.jpg"))
    small = cv2.resize(image, None, fx=SCALE, fy=SCALE, interpolation=cv2.INTER_AREA)
    calib = yaml.safe_load((PINHOLE_FRAME / "calibration.yaml").read_text())["camera"]
    K = np.asarray(calib["K"], dtype=np.float64) * np.array([[SCALE], [SCALE], [1.0]])
    ok, jpeg = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return jpeg.tobytes(), K, (small.shape[1], small.shape[0])


@dataclass(frozen=True)
class Recording:
    """What goes into a test bag: (stamp s, yaw deg) per LiDAR turn, image stamps s, topic names; the images
    stamped within ``image_motion_s`` (first, last s) shifted sideways further at each (a camera that moves)."""

    sweeps: tuple[tuple[float, float], ...]
    image_t_s: tuple[float, ...]
    image_topic: str = "/camera/image/compressed"
    cloud_topic: str = "/velodyne_packets"
    info_topic: str = "/camera/camera_info"
    camera_frame: str = "camera_optical"
    lidar_frame: str = "velodyne"
    extra: dict[str, str] = field(default_factory=dict)
    image_motion_s: tuple[float, float] | None = None


def stops(*, yaws_deg: list[float], still_sweeps: int, move_sweeps: int, turn_s: float = 0.05,
          image_period_s: float = 0.1, image_offset_s: float = 0.0) -> Recording:
    """A rig that stands still at each yaw for ``still_sweeps`` turns and turns to the next in ``move_sweeps``."""
    sweeps: list[tuple[float, float]] = []
    for i, yaw in enumerate(yaws_deg):
        if i:
            previous = yaws_deg[i - 1]
            sweeps += [(0.0, previous + (yaw - previous) * (k + 1) / (move_sweeps + 1)) for k in range(move_sweeps)]
        sweeps += [(0.0, yaw)] * still_sweeps
    timed = tuple((T0_S + k * turn_s, yaw) for k, (_, yaw) in enumerate(sweeps))
    end = len(timed) * turn_s
    images = tuple(T0_S + image_offset_s + t for t in np.arange(0.0, end, image_period_s))
    return Recording(timed, images)


def _writer(path: Path, fmt: BagFormat) -> Writer1 | Writer2:
    if fmt is BagFormat.ROS1:
        return Writer1(path)
    plugin = StoragePlugin.MCAP if fmt is BagFormat.MCAP else StoragePlugin.SQLITE3
    return Writer2(path, version=9, storage_plugin=plugin)


@dataclass(frozen=True)
class BagTypes:
    """The message types of a bag format (with velodyne_msgs registered) and how its messages are built."""

    fmt: BagFormat
    store: Typestore

    @classmethod
    def of(cls, fmt: BagFormat) -> BagTypes:
        ros1 = fmt is BagFormat.ROS1
        store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        for name, text in (ROS1_VELODYNE if ros1 else ROS2_VELODYNE).items():
            store.register(get_types_from_msg(text, name))
        return cls(fmt, store)

    def new(self, msgtype: str, **fields: object) -> object:
        return self.store.types[msgtype](**fields)

    def time(self, t: float) -> object:
        sec = int(np.floor(t))
        return self.new("builtin_interfaces/msg/Time", sec=sec, nanosec=int(round((t - sec) * 1e9)))

    def header(self, t: float, frame: str) -> object:
        if self.fmt is BagFormat.ROS1:
            return self.new("std_msgs/msg/Header", seq=0, stamp=self.time(t), frame_id=frame)
        return self.new("std_msgs/msg/Header", stamp=self.time(t), frame_id=frame)

    def velodyne_scan(self, t: float, frame: str, packets: np.ndarray, packet_t_s: np.ndarray) -> object:
        """A velodyne_msgs/VelodyneScan of (P,1206) uint8 ``packets`` stamped ``packet_t_s`` (P,) s."""
        body = [self.new("velodyne_msgs/msg/VelodynePacket", stamp=self.time(float(s)), data=p)
                for s, p in zip(packet_t_s, packets, strict=True)]
        return self.new("velodyne_msgs/msg/VelodyneScan", header=self.header(t, frame), packets=body)

    def write(self, path: Path, messages: list[tuple[float, str, str, object]]) -> Path:
        """Write (bag time s, topic, message type, message) in bag time order at ``path``; returns ``path``."""
        serialize = self.store.serialize_ros1 if self.fmt is BagFormat.ROS1 else self.store.serialize_cdr
        with _writer(path, self.fmt) as writer:
            kinds = {topic: msgtype for _, topic, msgtype, _ in messages}
            connections = {topic: writer.add_connection(topic, msgtype, typestore=self.store)
                           for topic, msgtype in kinds.items()}
            for t, topic, msgtype, message in sorted(messages, key=lambda m: m[0]):
                writer.write(connections[topic], int(t * 1e9), serialize(message, msgtype))
        return path


Messages = list[tuple[float, str, str, object]]


def _shifted_jpeg(shift_px: int) -> bytes:
    """The pinhole sample reduced by SCALE and rolled ``shift_px`` px sideways, as JPEG bytes."""
    image = cv2.imdecode(np.frombuffer(pinhole_jpeg()[0], np.uint8), cv2.IMREAD_COLOR)
    ok, jpeg = cv2.imencode(".jpg", np.roll(image, shift_px, axis=1), [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return jpeg.tobytes()


def _image_data(recording: Recording, k: int, t: float) -> bytes:
    span = recording.image_motion_s
    if span is not None and span[0] <= t <= span[1]:
        return _shifted_jpeg(24 * (k % 8 + 1))
    return pinhole_jpeg()[0]


def vector3(types: BagTypes, xyz: tuple[float, float, float]) -> object:
    return types.new("geometry_msgs/msg/Vector3", x=xyz[0], y=xyz[1], z=xyz[2])


def imu_messages(types: BagTypes, topic: str, samples: list[tuple[float, float]]) -> Messages:
    """sensor_msgs/Imu of a level IMU (gravity on z) turning about z at (stamp s, rate deg/s)."""
    out: Messages = []
    for t, rate in samples:
        imu = types.new("sensor_msgs/msg/Imu", header=types.header(t, "imu"),
                        orientation=types.new("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=0.0, w=1.0),
                        orientation_covariance=np.zeros(9), angular_velocity=vector3(types, (0.0, 0.0,
                                                                                               np.radians(rate))),
                        angular_velocity_covariance=np.zeros(9),
                        linear_acceleration=vector3(types, (0.0, 0.0, 9.80665)),
                        linear_acceleration_covariance=np.zeros(9))
        out.append((t, topic, "sensor_msgs/msg/Imu", imu))
    return out


def odometry_messages(types: BagTypes, topic: str, samples: list[tuple[float, float]]) -> Messages:
    """nav_msgs/Odometry driving forward at (stamp s, speed m/s)."""
    out: Messages = []
    for t, speed in samples:
        pose = types.new("geometry_msgs/msg/Pose",
                         position=types.new("geometry_msgs/msg/Point", x=0.0, y=0.0, z=0.0),
                         orientation=types.new("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=0.0, w=1.0))
        twist = types.new("geometry_msgs/msg/Twist", linear=vector3(types, (speed, 0.0, 0.0)),
                          angular=vector3(types, (0.0, 0.0, 0.0)))
        odom = types.new("nav_msgs/msg/Odometry", header=types.header(t, "odom"), child_frame_id="base_link",
                         pose=types.new("geometry_msgs/msg/PoseWithCovariance", pose=pose, covariance=np.zeros(36)),
                         twist=types.new("geometry_msgs/msg/TwistWithCovariance", twist=twist,
                                         covariance=np.zeros(36)))
        out.append((t, topic, "nav_msgs/msg/Odometry", odom))
    return out


def write_bag(path: Path, fmt: BagFormat, recording: Recording, *, with_info: bool = True,
              extra: Callable[[BagTypes], Messages] | None = None) -> Path:
    """Write ``recording`` as a bag at ``path`` (a .bag file for ROS 1, a folder for ROS 2), with the messages
    ``extra`` makes of the bag's types; returns ``path``."""
    types = BagTypes.of(fmt)
    _, K, (width, height) = pinhole_jpeg()
    turns = legacy_turns()
    messages: list[tuple[float, str, str, object]] = []
    for k, (t, yaw) in enumerate(recording.sweeps):
        packets = turned(turns[k % len(turns)], yaw)
        scan = types.velodyne_scan(t, recording.lidar_frame, packets, t + np.arange(len(packets)) * 0.05 / len(packets))
        messages.append((t + 0.05, recording.cloud_topic, "velodyne_msgs/msg/VelodyneScan", scan))
    for k, t in enumerate(recording.image_t_s):
        image = types.new("sensor_msgs/msg/CompressedImage", header=types.header(t, recording.camera_frame),
                          format="jpeg", data=np.frombuffer(_image_data(recording, k, t), np.uint8))
        messages.append((t + 0.01, recording.image_topic, "sensor_msgs/msg/CompressedImage", image))
    if with_info:
        Roi = "sensor_msgs/msg/RegionOfInterest"
        fields = dict(height=height, width=width, distortion_model="plumb_bob", binning_x=0, binning_y=0,
                      roi=types.new(Roi, x_offset=0, y_offset=0, height=0, width=0, do_rectify=False))
        cal = dict(D=np.zeros(5), K=K.ravel(), R=np.eye(3).ravel(), P=np.zeros(12)) if fmt is BagFormat.ROS1 else \
            dict(d=np.zeros(5), k=K.ravel(), r=np.eye(3).ravel(), p=np.zeros(12))
        info = types.new("sensor_msgs/msg/CameraInfo", header=types.header(recording.image_t_s[0],
                                                                            recording.camera_frame), **fields, **cal)
        messages.append((recording.image_t_s[0], recording.info_topic, "sensor_msgs/msg/CameraInfo", info))
    return types.write(path, messages + (extra(types) if extra is not None else []))


def bag_file(path: Path, fmt: BagFormat) -> Path:
    """The file of a written bag: the .bag itself, or the .db3 / .mcap inside a ROS 2 bag's folder."""
    if fmt is BagFormat.ROS1:
        return path
    return next(p for p in path.iterdir() if p.suffix in (".db3", ".mcap"))
