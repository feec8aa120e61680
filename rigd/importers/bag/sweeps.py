"""Pass 1's sweeps: every message of the cloud topic deserialised, decoded and reduced to the stillness gate's
direction grid (rigd.capture.gate), in bag order. Only the grid and the span are kept: the pairs' clouds are
decoded again in pass 2 from the few sweeps they fuse."""

from __future__ import annotations

from dataclasses import dataclass

from rigd.capture.gate import DirectionGrid, direction_grid
from rigd.importers.bag.clouds import BagSweep, pointcloud2_sweep, velodyne_scan_sweep
from rigd.importers.bag.reader import Message, TopicKind
from rigd.importers.bag.stills import SweepTime


def where(message: Message) -> str:
    """A message named in errors: its topic and stamp."""
    return f"{message.topic} at {message.stamp_s:.6f} s"


def decode_sweep(message: Message, kind: TopicKind) -> BagSweep | None:
    """A cloud-topic message as a sweep (None: a VelodyneScan without a valid packet)."""
    if kind is TopicKind.VELODYNE_SCAN:
        return velodyne_scan_sweep(message.body, where=where(message))
    return pointcloud2_sweep(message.body, stamp_s=message.stamp_s, where=where(message))


@dataclass(frozen=True)
class ReducedSweep:
    """A cloud message as pass 1 keeps it: bag time ns, the header's frame id, the sweep's span and its direction
    grid (both None when the message holds no valid return; its points are not kept)."""

    bag_time_ns: int
    frame_id: str
    time: SweepTime | None
    grid: DirectionGrid | None


def reduce_sweep(message: Message, kind: TopicKind) -> ReducedSweep:
    """``message`` decoded and reduced to the gate's direction grid."""
    sweep = decode_sweep(message, kind)
    if sweep is None or len(sweep) == 0:
        return ReducedSweep(message.bag_time_ns, message.frame_id, None, None)
    return ReducedSweep(message.bag_time_ns, message.frame_id, SweepTime(sweep.t_start_s, sweep.t_end_s),
                        direction_grid(sweep.points_lidar, sweep.ring))

