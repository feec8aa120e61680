"""Reading the named topics of a bag through ``rosbags``: ROS 1 ``.bag``, a ROS 2 bag folder (sqlite3 ``.db3`` or
MCAP inside), or a bare ``.db3`` / ``.mcap`` file.

``velodyne_msgs/VelodyneScan`` is not among rosbags' built-in types: bags that carry their message definitions
(ROS 1, MCAP, recent ROS 2 sqlite3) define it themselves; for the others it is registered here from its ``.msg``
definition. Every failure of the library (a truncated file, an unknown type, a message that does not
deserialise) becomes a :class:`BagError` naming the bag.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from types import TracebackType
from typing import Any

from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import Connection
from rosbags.rosbag1 import ReaderError as Ros1ReaderError
from rosbags.rosbag2 import ReaderError as Ros2ReaderError
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

from rigd.importers.bag.errors import BagError

VELODYNE_PACKET = "velodyne_msgs/msg/VelodynePacket"
VELODYNE_SCAN = "velodyne_msgs/msg/VelodyneScan"
# velodyne_msgs (ROS 2 spelling of the ROS 1 'time stamp'): one 1206-byte data packet and one turn of them.
VELODYNE_MSGS = {
    VELODYNE_PACKET: "builtin_interfaces/Time stamp\nuint8[1206] data\n",
    VELODYNE_SCAN: "std_msgs/Header header\nvelodyne_msgs/VelodynePacket[] packets\n",
}
# What a bag may throw at us while it is opened or read: a file cut short or overwritten shows as any of these.
READ_ERRORS = (AnyReaderError, Ros1ReaderError, Ros2ReaderError, SerdeError, TypesysError, struct.error, EOFError,
               ValueError, IndexError, KeyError, OSError)


class TopicKind(Enum):
    """The message types the importer reads, by their rosbags name."""

    IMAGE = "sensor_msgs/msg/Image"
    COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
    POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
    VELODYNE_SCAN = VELODYNE_SCAN
    CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
    IMU = "sensor_msgs/msg/Imu"
    ODOMETRY = "nav_msgs/msg/Odometry"


IMAGE_KINDS = (TopicKind.IMAGE, TopicKind.COMPRESSED_IMAGE)
CLOUD_KINDS = (TopicKind.POINTCLOUD2, TopicKind.VELODYNE_SCAN)
INFO_KINDS = (TopicKind.CAMERA_INFO,)
IMU_KINDS = (TopicKind.IMU,)
ODOMETRY_KINDS = (TopicKind.ODOMETRY,)


@dataclass(frozen=True)
class Topic:
    """A topic of the bag chosen for a role: its name, kind and rosbags connections (one per recording)."""

    name: str
    kind: TopicKind
    connections: tuple[Connection, ...]


@dataclass(frozen=True)
class Message:
    """One deserialised message: ``topic``, the bag's receive time ``bag_time_ns`` (ns), the header's
    ``stamp_s`` (s, the sensor's clock as the driver stamped it), ``frame_id`` and the message object."""

    topic: str
    bag_time_ns: int
    stamp_s: float
    frame_id: str
    body: Any


def read_error(path: Path, exc: BaseException) -> BagError:
    """The error of a bag whose messages cannot be read."""
    return BagError(f"{path}: cannot read the bag's messages, truncated or corrupt? ({type(exc).__name__}: {exc})")


def stamp_seconds(stamp: Any) -> float:
    """A ROS time (``sec`` + ``nanosec``, as rosbags gives ROS 1 times too) in seconds."""
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def _velodyne_types() -> dict[str, Any]:
    types: dict[str, Any] = {}
    for name, text in VELODYNE_MSGS.items():
        types.update(get_types_from_msg(text, name))
    return types


class Bag:
    """An open bag (use as a context manager). ``path``: a ``.bag`` file, a ROS 2 bag folder, a ``.db3`` or
    ``.mcap`` file."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise BagError(f"{self.path}: bag does not exist")
        default = get_typestore(Stores.ROS2_HUMBLE)
        default.register(_velodyne_types())
        try:
            self._reader = AnyReader([self.path], default_typestore=default)
        except READ_ERRORS as exc:
            raise BagError(f"{self.path}: not a readable ROS 1 / ROS 2 / MCAP bag ({exc})") from exc

    def __enter__(self) -> Bag:
        try:
            self._reader.open()
        except READ_ERRORS as exc:
            raise BagError(f"{self.path}: cannot open the bag, truncated or corrupt? ({exc})") from exc
        known = self._reader.typestore.fielddefs
        missing = {k: v for k, v in _velodyne_types().items() if k not in known}
        if missing and any(c.msgtype == VELODYNE_SCAN for c in self._reader.connections):
            self._reader.typestore.register(missing)
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self._reader.close()

    @property
    def topics(self) -> dict[str, str]:
        """Every topic of the bag with its message type."""
        return {c.topic: c.msgtype for c in self._reader.connections}

    def describe_topics(self) -> str:
        return ", ".join(f"{name} ({kind})" for name, kind in sorted(self.topics.items())) or "none"

    def topic(self, *, name: str, kinds: Sequence[TopicKind], role: str) -> Topic:
        """The topic ``name`` for ``role`` (e.g. "--image-topic"), which must carry one of ``kinds``."""
        connections = tuple(c for c in self._reader.connections if c.topic == name)
        if not connections:
            raise BagError(f"{self.path}: no topic {name!r} ({role}); the bag has: {self.describe_topics()}")
        msgtype = connections[0].msgtype
        kind = next((k for k in kinds if k.value == msgtype), None)
        if kind is None:
            wanted = " or ".join(k.value for k in kinds)
            raise BagError(f"{self.path}: topic {name!r} ({role}) carries {msgtype}, not {wanted}; the bag has: "
                           f"{self.describe_topics()}")
        return Topic(name, kind, connections)

    def messages(self, *, topics: Sequence[Topic], start_ns: int | None = None,
                 stop_ns: int | None = None) -> Iterator[Message]:
        """The messages of ``topics`` in bag time order (``start_ns`` <= t < ``stop_ns`` when given); a message that
        does not read is a :class:`BagError` naming the bag."""
        by_connection = {id(c): t for t in topics for c in t.connections}
        connections = [c for t in topics for c in t.connections]
        store, ros2 = self._reader.typestore, bool(self._reader.is2)
        try:
            for connection, bag_time_ns, data in self._reader.messages(connections, start=start_ns, stop=stop_ns):
                body: Any = (store.deserialize_cdr(data, connection.msgtype) if ros2
                             else store.deserialize_ros1(data, connection.msgtype))
                yield Message(by_connection[id(connection)].name, int(bag_time_ns), stamp_seconds(body.header.stamp),
                              str(body.header.frame_id), body)
        except READ_ERRORS as exc:
            raise read_error(self.path, exc) from exc
