"""Device time: microseconds past the hour unwrapped across hour rollovers and anchored to UTC.

The hour the device counts from comes from GPS (a position packet with PPS locked and a valid $GPRMC)
or, without GPS, from the host clock: the hour that puts the first packet nearest its host time, as
velodyne_decoder does. A device clock without GPS free-runs from power-up, so its "device" time can be
minutes away from UTC; :attr:`DeviceClock.host_offset_s` (host minus device) maps it to the host clock.

The offset is tracked per clock *segment*: the smallest host-receive-minus-device time of the segment's
packets (the least delayed packet; every receive delay only adds). A device clock that steps (a reset, a
PPS lock setting it to GPS time) starts a new segment, detected from the receive times:

- forward: a packet's offset falls below the segment's by more than ``STEP_S`` (a receive delay can
  only raise it);
- back: the device time runs backwards by more than ``STEP_S`` between two packets received in a row
  while the offset rises by as much (a reordered packet is a few milliseconds back, not 0.1 s);
- back, unseen (the step fell in a gap of the stream): every packet's offset stays above the segment's by
  more than ``STEP_S`` for ``SETTLE_S`` of host time, steady (the smallest offsets of the run's two halves
  agree within ``STEADY_S``). A receiver that stalled reads its backlog within one burst, and a sender that
  falls further and further behind its own stamps is not steady: neither is a step.

A packet right after a step that still fits the previous segment is a straggler of it (reordered across
the step), not another step. Each step is recorded (:class:`ClockStep`), and the new segment's offset is
measured afresh from its own packets.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.layout import HOUR_US, PpsStatus
from drivers.vlp16.position import PositionPacket

_HALF_HOUR_US = HOUR_US // 2
# A change of the host-minus-device offset this large is the device clock stepping: receive delays on a
# sensor's own network stay in milliseconds, and a reordered packet is a few packets (ms) out of place.
STEP_S = 0.1
# Offsets all raised by more than STEP_S for this long (host s), steady within STEADY_S, are a step back that
# no packet pair showed (module doc).
SETTLE_S = 1.0
STEADY_S = 0.01
# Right after a step, packets that still fit the previous segment are stragglers reordered across it.
STRAGGLER_PACKETS = 16


class TimeSource(Enum):
    """Where a sweep's absolute time comes from."""

    GPS = "gps"  # device clock disciplined by PPS; device time is UTC
    HOST = "host"  # device clock free-running; absolute time = device time + host offset


class StepKind(Enum):
    """How a clock step was seen (module doc)."""

    FORWARD = "forward"
    BACK = "back"
    BACK_SETTLED = "back_settled"


@dataclass(frozen=True)
class TimePair:
    """``host`` s: host clock (pcap record or receive time); ``device`` s since the epoch (see module doc)."""

    host: float
    device: float


@dataclass(frozen=True)
class ClockStep:
    """A step of the device clock seen in the receive times. ``host_s``: receive time of the first packet
    on the new clock (s); ``device_s``: the device time (s since the epoch) of the packet it was seen at
    (for BACK_SETTLED the one that settled it, SETTLE_S later); ``step_s``: how far the device
    clock jumped, s (negative: back), measured as the change of the host-minus-device offset (to within
    the new segment's least delayed packet so far); ``offset_s``: the new segment's host-minus-device offset
    (refined, as the step, while the segment lasts)."""

    host_s: float
    device_s: float
    step_s: float
    offset_s: float
    kind: StepKind


@dataclass(frozen=True)
class HostObservation:
    """What a batch of P packets did to the clock. ``starts``: indices where a new clock segment starts
    (ascending); ``offsets_s``: host-minus-device offset s of each piece between them (len(starts) + 1;
    piece 0 continues the segment before the batch); ``stragglers`` (P,) bool: packets of the previous
    segment that arrived after a step (to be dropped as late)."""

    starts: tuple[int, ...]
    offsets_s: tuple[float, ...]
    stragglers: NDArray[np.bool_]


@dataclass
class _RaisedRun:
    """Packets whose offsets all stay above their segment's by more than STEP_S, from ``since_s`` (host s):
    the smallest offset s in the first and in the second half of the SETTLE_S they must last."""

    since_s: float
    first_min_s: float = math.inf
    second_min_s: float = math.inf

    @property
    def offset_s(self) -> float:
        return min(self.first_min_s, self.second_min_s)


@dataclass
class _Segment:
    """The current clock segment: its offset s (smallest seen), the previous segment's, packets since it
    began, the last packet's device time s, a run of raised offsets if one is going on, the steps so far."""

    offset_s: float = math.inf
    previous_s: float | None = None
    packets: int = 0
    last_device_s: float | None = None
    run: _RaisedRun | None = None
    steps: list[ClockStep] = field(default_factory=list)


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
        self._segment = _Segment()

    @property
    def source(self) -> TimeSource:
        return TimeSource.GPS if self._gps and self.pps is PpsStatus.LOCKED else TimeSource.HOST

    @property
    def host_offset_s(self) -> float:
        """Host minus device time s of the current clock segment (inf before the first packet)."""
        return self._segment.offset_s

    @property
    def steps(self) -> tuple[ClockStep, ...]:
        """Every step of the device clock seen so far, oldest first."""
        return tuple(self._segment.steps)

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

    def observe_host(self, host_s: NDArray[np.float64], count_us: NDArray[np.int64]) -> HostObservation:
        """Track the host-minus-device offset of (P,) packets in arrival order (receive times ``host_s`` s,
        continuous ``count_us``), anchoring to the host clock on first use; steps start new segments."""
        stragglers = np.zeros(len(count_us), dtype=bool)
        if len(count_us) == 0:
            return HostObservation((), (self._segment.offset_s,), stragglers)
        if self._hour_epoch_s is None:
            first_s = float(host_s[0])
            hour = math.floor(first_s / 3600.0) * 3600.0
            device = hour + count_us[0] * 1e-6
            self._hour_epoch_s = hour - 3600.0 * round((device - first_s) / 3600.0)
        host = np.asarray(host_s, dtype=np.float64)
        device_s = self.epoch_s(count_us)
        offset = host - device_s
        starts: list[int] = []
        offsets: list[float] = []
        i = 0
        while i < len(offset):
            j, kind = _next_event(self._segment, host[i:], device_s[i:], offset[i:])
            _absorb(self._segment, device_s[i : i + j], offset[i : i + j])
            i += j
            if kind is None:
                break
            if kind is not StepKind.BACK_SETTLED and _straggler(self._segment, float(offset[i])):
                stragglers[i] = True
            else:
                offsets.append(self._segment.offset_s)
                starts.append(i)
                _start_segment(self._segment, float(host[i]), float(device_s[i]), float(offset[i]), kind)
            i += 1
        offsets.append(self._segment.offset_s)
        return HostObservation(tuple(starts), tuple(offsets), stragglers)

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
            _relabel(self._segment, new_epoch - self._hour_epoch_s)
        self._hour_epoch_s = new_epoch
        self._gps = True

    def epoch_s(self, count_us: NDArray[np.int64] | int) -> NDArray[np.float64]:
        """Device time of continuous counts, s since the epoch."""
        assert self._hour_epoch_s is not None, "observe_host or observe_position comes first"
        return self._hour_epoch_s + np.asarray(count_us, dtype=np.float64) * 1e-6


def _next_event(segment: _Segment, host: NDArray[np.float64], device: NDArray[np.float64],
                offset: NDArray[np.float64]) -> tuple[int, StepKind | None]:
    """Index of the first packet (of P, arrival order) that does not fit ``segment``, and how; (P, None)
    when all fit. Offsets may lower the segment's as they go (its smallest so far is the reference)."""
    if not math.isfinite(segment.offset_s):
        return len(offset), None  # the stream's first packets: they set the offset
    level = np.minimum.accumulate(np.concatenate([[segment.offset_s], offset]))[:-1]  # before each packet
    forward = offset < level - STEP_S
    previous = np.concatenate([[segment.last_device_s if segment.last_device_s is not None else device[0]],
                               device[:-1]])
    back = (device < previous - STEP_S) & (offset > level + STEP_S)
    events = [(int(np.argmax(mask)), kind) for mask, kind in ((forward, StepKind.FORWARD), (back, StepKind.BACK))
              if mask.any()]
    first, kind = min(events, key=lambda e: e[0]) if events else (len(offset), None)
    settled = _follow_raised(segment, host[:first], offset[:first], level[:first])
    return (settled, StepKind.BACK_SETTLED) if settled is not None else (first, kind)


def _follow_raised(segment: _Segment, host: NDArray[np.float64], offset: NDArray[np.float64],
                   level: NDArray[np.float64]) -> int | None:
    """Follow runs of raised offsets packet by packet (rare: a stall's backlog, a hidden step back); the
    index of the packet at which one has stayed raised and steady for SETTLE_S, or None."""
    raised = offset > level + STEP_S
    if len(raised) == 0 or (segment.run is None and not raised.any()):
        return None
    for k in np.flatnonzero(raised):
        if segment.run is None or (k > 0 and not raised[k - 1]):
            segment.run = _RaisedRun(float(host[k]))
        run, elapsed = segment.run, float(host[k]) - segment.run.since_s
        if elapsed < SETTLE_S / 2:
            run.first_min_s = min(run.first_min_s, float(offset[k]))
            continue
        run.second_min_s = min(run.second_min_s, float(offset[k]))
        if elapsed < SETTLE_S:
            continue
        if abs(run.second_min_s - run.first_min_s) <= STEADY_S:
            return int(k)
        segment.run = _RaisedRun(run.since_s + SETTLE_S / 2, run.second_min_s)  # not steady: slide on
    if not raised[-1]:
        segment.run = None
    return None


def _absorb(segment: _Segment, device: NDArray[np.float64], offset: NDArray[np.float64]) -> None:
    """Packets that fit the segment: lower its offset (and refine the step that began it), count them."""
    if len(offset) == 0:
        return
    lowest = float(offset.min())
    if lowest < segment.offset_s and segment.steps and segment.previous_s is not None:
        last = segment.steps[-1]
        segment.steps[-1] = replace(last, step_s=segment.previous_s - lowest, offset_s=lowest)
    segment.offset_s = min(segment.offset_s, lowest)
    segment.packets += len(offset)
    segment.last_device_s = float(device[-1])


def _straggler(segment: _Segment, offset: float) -> bool:
    """A packet right after a step that fits the previous segment was reordered across the step."""
    return (segment.previous_s is not None and segment.packets < STRAGGLER_PACKETS
            and abs(offset - segment.previous_s) < STEP_S)


def _start_segment(segment: _Segment, host_s: float, device_s: float, offset_s: float, kind: StepKind) -> None:
    """Record a step at the packet (host, device, offset) and begin a segment with it."""
    if kind is StepKind.BACK_SETTLED and segment.run is not None:
        offset_s, host_s = min(offset_s, segment.run.offset_s), segment.run.since_s
    segment.steps.append(ClockStep(host_s, device_s, segment.offset_s - offset_s, offset_s, kind))
    segment.previous_s, segment.offset_s = segment.offset_s, offset_s
    segment.packets, segment.last_device_s, segment.run = 1, device_s, None


def _relabel(segment: _Segment, epoch_change_s: float) -> None:
    """The device hour was re-anchored by ``epoch_change_s``: every device time moves, every offset the
    other way."""
    segment.offset_s -= epoch_change_s
    if segment.run is not None:
        segment.run.first_min_s -= epoch_change_s
        segment.run.second_min_s -= epoch_change_s
    if segment.previous_s is not None:
        segment.previous_s -= epoch_change_s
    if segment.last_device_s is not None:
        segment.last_device_s += epoch_change_s
