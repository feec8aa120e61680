"""Camera time -> host time.

The Ladybug stamps each frame with its own clock (cycle time; GPS time when a Ladybug5+ is PPS-locked).
The host learns of a frame some time after it was exposed: ``host_receive = device + offset + latency``
with ``latency >= 0``. Sampling (device, host) pairs, the smallest ``host - device`` over a sliding window
estimates ``offset`` (the frames that arrived with the least delay), robust to USB and scheduling jitter;
the window lets it follow the slow drift of the camera's oscillator. ``spread_s`` (median minus minimum)
reports the latency jitter.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import Ladybug5Error
from drivers.ladybug5.frames import TimeBase


def unwrap_times(raw_s: NDArray[np.float64], period_s: float) -> NDArray[np.float64]:
    """Unwrap a counter that wraps every ``period_s`` (e.g. 128 s of cycle time); (N,) s -> (N,) s.

    Assumes consecutive samples are less than half a period apart.
    """
    raw = np.asarray(raw_s, dtype=np.float64)
    steps = np.diff(raw)
    wraps = np.concatenate([[0.0], np.cumsum(np.round(-steps / period_s))])
    return raw + wraps * period_s


@dataclass(frozen=True)
class ClockReport:
    offset_s: float  # host = device + offset
    spread_s: float  # median - min of (host - device) in the window: latency jitter
    samples: int
    time_base: TimeBase


class ClockSync:
    """Streaming estimate of the device -> host clock offset from (device, host) time pairs."""

    def __init__(self, window: int = 300, wrap_period_s: float | None = None, time_base: TimeBase = TimeBase.CAMERA):
        if window < 1:
            raise Ladybug5Error("clock window must hold at least one sample")
        self.time_base = time_base
        self._wrap = wrap_period_s
        self._deltas: deque[float] = deque(maxlen=window)
        self._last_raw: float | None = None
        self._wrapped_s = 0.0
        self._count = 0

    def unwrap(self, device_raw_s: float) -> float:
        """Device time with counter wraps removed (identity when the counter does not wrap)."""
        if self._wrap is not None and self._last_raw is not None:
            self._wrapped_s += round((self._last_raw - device_raw_s) / self._wrap) * self._wrap
        self._last_raw = device_raw_s
        return device_raw_s + self._wrapped_s

    def add(self, device_raw_s: float, host_s: float) -> float:
        """Record one frame's device time and host receive time; returns the unwrapped device time."""
        device_s = self.unwrap(device_raw_s)
        self._deltas.append(host_s - device_s)
        self._count += 1
        return device_s

    @property
    def offset_s(self) -> float:
        if not self._deltas:
            raise Ladybug5Error("no (device, host) time samples yet: cannot map camera time to host time")
        return min(self._deltas)

    def to_host(self, device_s: float) -> float:
        return device_s + self.offset_s

    def report(self) -> ClockReport:
        offset = self.offset_s
        return ClockReport(offset, float(np.median(self._deltas)) - offset, self._count, self.time_base)
