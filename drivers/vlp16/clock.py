"""Device time: microseconds past the hour unwrapped across hour rollovers and anchored to UTC.

The hour the device counts from comes from GPS (a position packet with PPS locked and a valid $GPRMC)
or, without GPS, from the host clock: the hour that puts the first packet nearest its host time, as
velodyne_decoder does. A device clock without GPS free-runs from power-up, so its "device" time can be
minutes away from UTC; :attr:`DeviceClock.host_offset_s` (host minus device, smallest seen) maps it to
the host clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.layout import HOUR_US, PpsStatus
from drivers.vlp16.position import PositionPacket

_HALF_HOUR_US = HOUR_US // 2


class TimeSource(Enum):
    """Where a sweep's absolute time comes from."""

    GPS = "gps"  # device clock disciplined by PPS; device time is UTC
    HOST = "host"  # device clock free-running; absolute time = device time + host offset


@dataclass(frozen=True)
class TimePair:
    """``host`` s: host clock (pcap record or receive time); ``device`` s since the epoch (see module doc)."""

    host: float
    device: float


def _wrapped(delta_us: NDArray[np.int64]) -> NDArray[np.int64]:
    """Differences of hour-modular stamps mapped into [-half hour, half hour)."""
    return (delta_us + _HALF_HOUR_US) % HOUR_US - _HALF_HOUR_US


class DeviceClock:
    """Continuous device microseconds (``count_us``) and their UTC anchor; one per stream."""

    def __init__(self) -> None:
        self._last_stamp_us: int | None = None  # last timestamp_us seen, and its continuous count
        self._last_count_us = 0
        self._hour_epoch_s: float | None = None  # epoch s of count_us == 0
        self._gps = False
        self.pps: PpsStatus | None = None
        self.host_offset_s = math.inf

    @property
    def source(self) -> TimeSource:
        return TimeSource.GPS if self._gps and self.pps is PpsStatus.LOCKED else TimeSource.HOST

    def unwrap(self, stamp_us: NDArray[np.integer]) -> NDArray[np.int64]:
        """(P,) continuous counts of (P,) stamps in arrival order; each step is taken as the shortest one."""
        stamp = np.asarray(stamp_us, dtype=np.int64)
        if len(stamp) == 0:
            return stamp
        if self._last_stamp_us is None:
            self._last_stamp_us = self._last_count_us = int(stamp[0])
        steps = _wrapped(np.diff(stamp, prepend=self._last_stamp_us))
        count = self._last_count_us + np.cumsum(steps)
        self._last_stamp_us, self._last_count_us = int(stamp[-1]), int(count[-1])
        return count

    def observe_host(self, host_s: NDArray[np.float64], count_us: NDArray[np.int64]) -> None:
        """Anchor to the host clock on first use and keep the smallest host-minus-device offset."""
        if len(count_us) == 0:
            return
        if self._hour_epoch_s is None:
            first_s = float(host_s[0])
            hour = math.floor(first_s / 3600.0) * 3600.0
            device = hour + count_us[0] * 1e-6
            self._hour_epoch_s = hour - 3600.0 * round((device - first_s) / 3600.0)
        offsets = np.asarray(host_s, dtype=np.float64) - self.epoch_s(count_us)
        self.host_offset_s = min(self.host_offset_s, float(offsets.min()))

    def observe_position(self, packet: PositionPacket) -> None:
        """Track PPS; with PPS locked and a valid $GPRMC, re-anchor the hour to GPS UTC."""
        self.pps = packet.pps
        if packet.pps is not PpsStatus.LOCKED or packet.utc_s is None:
            return
        if self._last_stamp_us is None:
            self._last_stamp_us = self._last_count_us = packet.timestamp_us
        step = (packet.timestamp_us - self._last_stamp_us + _HALF_HOUR_US) % HOUR_US - _HALF_HOUR_US
        count_us = self._last_count_us + step
        anchor = packet.utc_s - count_us * 1e-6
        new_epoch = 3600.0 * round(anchor / 3600.0)  # a locked device clock counts from the UTC hour
        if self._hour_epoch_s is not None:
            self.host_offset_s += self._hour_epoch_s - new_epoch
        self._hour_epoch_s = new_epoch
        self._gps = True

    def epoch_s(self, count_us: NDArray[np.int64] | int) -> NDArray[np.float64]:
        """Device time of continuous counts, s since the epoch."""
        assert self._hour_epoch_s is not None, "observe_host or observe_position comes first"
        return self._hour_epoch_s + np.asarray(count_us, dtype=np.float64) * 1e-6
