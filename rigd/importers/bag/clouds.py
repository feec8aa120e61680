"""sensor_msgs/PointCloud2 and velodyne_msgs/VelodyneScan as LiDAR sweeps in the LiDAR frame.

PointCloud2: ``x y z`` (float32 or float64) required; ``intensity`` and ``ring`` kept when present; a per-point
time (``time``, ``t``, ``timestamp``: seconds, or nanoseconds when an integer) gives the sweep's span, either
relative to the header's stamp or absolute. Without a ring field the ring is the nearest VLP-16 elevation (the
rig's LiDAR: its beams are 2 degrees apart, far more than a laser's offset moves a return's elevation).

VelodyneScan: the raw 1206-byte data packets of one turn, checked and decoded by rigd's own VLP-16 decoder
(drivers.vlp16: the manual's geometry, velodyne_decoder's arithmetic) with each packet's ROS stamp as its time;
as a :class:`BagSweep`, or as the driver's own Sweep (:func:`velodyne_scan_vlp16`) for the capture's fusion.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivers.vlp16 import (
    DATA_PACKET_SIZE,
    LEGACY_PRODUCT_ID,
    VLP16_PRODUCT_ID,
    ReturnMode,
    Sweep,
    TimePair,
    TimeSource,
    check_packets,
    decode_packets,
)
from drivers.vlp16.layout import AZIMUTH_UNITS, NOMINAL_ELEVATION_DEG, as_packet_records
from drivers.vlp16.sweep import packet_rate  # the driver's rpm of a packet, so a fused pair's beams are capture's
from rigd.importers.bag.errors import BagError
from rigd.importers.bag.reader import stamp_seconds

F64 = NDArray[np.float64]
# PointField datatypes (sensor_msgs/PointField) as numpy type codes.
POINT_FIELD_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
TIME_FIELDS = ("time", "t", "timestamp", "time_stamp")
ABSOLUTE_TIME_S = 1e6  # per-point times beyond this are absolute (UNIX seconds), below relative to the stamp
PRODUCT_IDS = frozenset({VLP16_PRODUCT_ID, LEGACY_PRODUCT_ID})  # pre-2015 firmware writes the HDL-32E's id
RING_ELEVATIONS_DEG = np.sort(NOMINAL_ELEVATION_DEG)  # ring 0 = lowest beam


@dataclass(frozen=True)
class BagSweep:
    """One LiDAR sweep of a bag. ``points_lidar`` (N,3) float64 m in the LiDAR frame; ``intensity`` (N,) float32;
    ``ring`` (N,) int16, 0 = lowest beam; ``t_start_s``/``t_end_s`` its first and last return on the header's
    clock, s (equal when the message has no per-point time); ``frame_id`` the LiDAR's frame."""

    points_lidar: F64
    intensity: NDArray[np.float32]
    ring: NDArray[np.int16]
    t_start_s: float
    t_end_s: float
    frame_id: str

    def __len__(self) -> int:
        return len(self.points_lidar)


def rings_from_elevation(points_lidar: F64) -> NDArray[np.int16]:
    """(N,) int16: the VLP-16 ring whose nominal elevation is nearest each point's (N,3) m elevation."""
    p = np.asarray(points_lidar, dtype=np.float64)
    elevation = np.degrees(np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1])))
    nearest = np.abs(elevation[:, None] - RING_ELEVATIONS_DEG[None, :]).argmin(axis=1)
    return np.asarray(nearest, dtype=np.int16)


def _cloud_dtype(message: Any, where: str) -> np.dtype[Any]:
    fields = {str(f.name): f for f in message.fields}
    missing = [n for n in ("x", "y", "z") if n not in fields]
    if missing:
        have = ", ".join(fields) or "none"
        raise BagError(f"{where}: PointCloud2 without field(s) {', '.join(missing)} (it has {have})")
    order = ">" if int(message.is_bigendian) else "<"
    names, formats, offsets = [], [], []
    for name, f in fields.items():
        code = POINT_FIELD_TYPES.get(int(f.datatype))
        if code is None or int(f.count) != 1:
            if name in ("x", "y", "z"):
                raise BagError(f"{where}: PointCloud2 field {name} has datatype {int(f.datatype)} x {int(f.count)}; "
                               "rigd reads one number per point")
            continue
        names.append(name)
        formats.append(order + code if code not in ("i1", "u1") else code)
        offsets.append(int(f.offset))
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": int(message.point_step)})


def _cloud_records(message: Any, where: str) -> NDArray[Any]:
    dtype = _cloud_dtype(message, where)
    height, width, row_step = int(message.height), int(message.width), int(message.row_step)
    data = np.asarray(message.data, dtype=np.uint8)
    row_bytes = width * dtype.itemsize
    if row_step < row_bytes or data.size < row_step * height:
        raise BagError(f"{where}: PointCloud2 data of {data.size} bytes does not hold {width}x{height} points of "
                       f"{dtype.itemsize} bytes (row step {row_step})")
    rows = data[: row_step * height].reshape(height, row_step)[:, :row_bytes]
    return np.ascontiguousarray(rows).view(dtype).reshape(-1)


def _time_span(records: NDArray[Any], stamp_s: float) -> tuple[float, float]:
    name = next((n for n in TIME_FIELDS if n in (records.dtype.names or ())), None)
    if name is None or len(records) == 0:
        return stamp_s, stamp_s
    times = records[name].astype(np.float64)
    if records.dtype[name].kind in "iu":
        times = times * 1e-9
    times = times[np.isfinite(times)]
    if len(times) == 0:
        return stamp_s, stamp_s
    base = 0.0 if float(np.median(np.abs(times))) > ABSOLUTE_TIME_S else stamp_s
    return base + float(times.min()), base + float(times.max())


def pointcloud2_sweep(message: Any, *, stamp_s: float, where: str) -> BagSweep:
    """A sensor_msgs/PointCloud2 as a :class:`BagSweep`; points with a non-finite coordinate are dropped."""
    records = _cloud_records(message, where)
    points = np.stack([records[n].astype(np.float64) for n in ("x", "y", "z")], axis=1)
    keep = np.all(np.isfinite(points), axis=1) & np.any(points != 0.0, axis=1)
    names = records.dtype.names or ()
    intensity = records["intensity"].astype(np.float32) if "intensity" in names else np.zeros(len(records), np.float32)
    ring = records["ring"].astype(np.int16)[keep] if "ring" in names else rings_from_elevation(points[keep])
    t_start, t_end = _time_span(records[keep], stamp_s)
    return BagSweep(points[keep], intensity[keep], ring, t_start, t_end, str(message.header.frame_id))


def _valid_packets(message: Any, where: str) -> tuple[NDArray[np.uint8], F64] | None:
    """A VelodyneScan's data packets (P,1206) uint8 that pass the driver's checks and their ROS stamps (P,) s;
    None when none does."""
    packets = list(message.packets)
    if not packets:
        return None
    payloads = np.stack([np.asarray(p.data, dtype=np.uint8) for p in packets])
    if payloads.shape[1] != DATA_PACKET_SIZE:
        raise BagError(f"{where}: VelodyneScan packets of {payloads.shape[1]} bytes, not {DATA_PACKET_SIZE}")
    stamps = np.array([stamp_seconds(p.stamp) for p in packets], dtype=np.float64)
    check = check_packets(as_packet_records(payloads), PRODUCT_IDS)
    if not check.valid.any():
        return None
    return payloads[check.valid], stamps[check.valid]


def velodyne_scan_sweep(message: Any, *, where: str) -> BagSweep | None:
    """A velodyne_msgs/VelodyneScan decoded by drivers.vlp16 (None: no valid data packet in it). Each point's time
    is its packet's stamp plus its firing delay; packets that fail the driver's checks are left out."""
    sweep = velodyne_scan_vlp16(message, where=where)
    if sweep is None:
        return None
    points = np.stack([sweep.points["x"], sweep.points["y"], sweep.points["z"]], axis=1).astype(np.float64)
    return BagSweep(points, sweep.points["intensity"].astype(np.float32), sweep.points["ring"].astype(np.int16),
                    sweep.start.device, sweep.end.device, str(message.header.frame_id))


def velodyne_scan_vlp16(message: Any, *, where: str) -> Sweep | None:
    """A velodyne_msgs/VelodyneScan as the VLP-16 driver's :class:`~drivers.vlp16.Sweep` (what
    rigd.capture.fuse.fuse_sweeps takes; None: no valid data packet or return in it). Its device and host times
    are both the header clock's: ``start``/``end`` the first and last return (a point's ``time`` is since the
    first), ``rpm`` the packets' median rate as the driver measures it, the return mode the first packet's."""
    valid = _valid_packets(message, where)
    if valid is None:
        return None
    payloads, stamps = valid
    points = decode_packets(payloads, None, stamps).points
    if len(points) == 0:
        return None
    t_start, t_end = float(points["time"].min()), float(points["time"].max())
    points["time"] -= t_start
    records = as_packet_records(payloads)
    dual = records["return_mode"] == ReturnMode.DUAL
    rate = packet_rate(records["blocks"]["azimuth"].astype(np.int64), dual)  # azimuth units per us
    return Sweep(index=0, points=points, start=TimePair(t_start, t_start), end=TimePair(t_end, t_end),
                 packet_count=len(payloads), missing_packets=0,
                 rpm=float(np.median(rate)) * 1e6 / AZIMUTH_UNITS * 60.0,
                 return_mode=ReturnMode(int(records["return_mode"][0])), complete=True,
                 time_source=TimeSource.HOST, clock_offset_s=0.0, pps=None, receive_offset_s=0.0)
