"""What the LiDAR's stream says about its link: whether a sweep can go into a pair, packets counted, lost and their
rate, the clock steps seen, and what to tell the operator when no usable sweep comes."""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass
from enum import Enum

import numpy as np

from drivers.vlp16 import ClockStep, StreamStats, Sweep
from drivers.vlp16.layout import SEQUENCE_US
from rigd.capture.gate import AZIMUTH_BINS, RINGS, DirectionGrid, direction_grid

BLIND_FRACTION = 0.05  # a whole turn with returns in fewer of its 16 x 360 directions sees (almost) nothing
COVERAGE_SLACK_BLOCKS = 2  # where the cut falls moves a whole turn's count by a block either way
RATE_WINDOW_S = 1.0  # packets/s is over this much of the latest data, and 0 once none came for this long
STOPPED_RPM = 60.0  # a head turning slower than this is stopped (a VLP-16 turns at 300-1200 rpm)


class SweepUse(Enum):
    """Whether a LiDAR sweep can go into a pair, and if not, why."""

    USABLE = "usable"
    PARTIAL = "partial"  # not a whole turn: the stream's ends, a clock step, whole turns lost, a stopped head
    LOSSY = "lossy"  # packets lost: less than min_sweep_fraction of a turn
    BLIND = "blind"  # a whole turn with (almost) no returns


@dataclass(frozen=True)
class Unusable:
    """The latest sweep that could not go into a pair: why, the sweep, and its directions with a return."""

    use: SweepUse
    sweep: Sweep
    returns: int


def judge_sweep(sweep: Sweep, min_sweep_fraction: float) -> tuple[SweepUse, DirectionGrid | None]:
    """Whether ``sweep`` can go into a pair: a whole turn, complete to min_sweep_fraction (less the two
    blocks by which where the cut falls changes a whole turn's count), with returns."""
    if not sweep.complete:
        return SweepUse.PARTIAL, None
    slack = COVERAGE_SLACK_BLOCKS * 2 * SEQUENCE_US * sweep.rpm / 60e6  # a block is two firing sequences
    if sweep.coverage < min_sweep_fraction - slack:
        return SweepUse.LOSSY, None
    xyz = np.stack([sweep.points["x"], sweep.points["y"], sweep.points["z"]], axis=1)
    grid = direction_grid(xyz, sweep.points["ring"])
    if grid.returns < BLIND_FRACTION * RINGS * AZIMUTH_BINS:
        return SweepUse.BLIND, grid
    return SweepUse.USABLE, grid


class LidarLink:
    """The LiDAR ``describe`` as its sweeps arrive: the stream's counters, the packet rate, and the latest sweep
    that could not go into a pair (with fewer than ``min_sweep_fraction`` of a turn's packets it is lossy)."""

    def __init__(self, describe: str, min_sweep_fraction: float) -> None:
        self.describe = describe
        self.min_sweep_fraction = min_sweep_fraction
        self.stats: StreamStats | None = None
        self.rates: deque[tuple[float, float, int]] = deque(maxlen=20)  # (start, end, packets) of sweeps
        self._rate_at = -math.inf  # monotonic time the latest sweep (whole or not) arrived
        self.unusable: Unusable | None = None  # the latest sweep that could not go into a pair
        self._steps_seen = 0  # clock steps already reported

    def arrived(self, sweep: Sweep, stats: StreamStats, now: float) -> ClockStep | None:
        """A sweep (whole or not) and the stream's counters with it, at monotonic time ``now``; the LiDAR's clock
        step if ``stats`` has one not seen before (the new offset is the driver's, measured from the new clock's
        own packets)."""
        self.stats = stats
        start, end = sweep.start.device + sweep.clock_offset_s, sweep.end.device + sweep.clock_offset_s
        self.rates.append((start, end, sweep.packet_count))
        self._rate_at = now
        if len(stats.clock_steps) <= self._steps_seen:
            return None
        self._steps_seen = len(stats.clock_steps)
        return stats.clock_steps[-1]

    def judge(self, sweep: Sweep) -> tuple[SweepUse, DirectionGrid | None]:
        """:func:`judge_sweep`, keeping the sweep as the latest unusable one unless it is usable."""
        use, grid = judge_sweep(sweep, self.min_sweep_fraction)
        usable = use is SweepUse.USABLE and grid is not None
        self.unusable = None if usable else Unusable(use, sweep, 0 if grid is None else grid.returns)
        return use, grid

    def packets_lost(self) -> int:
        return 0 if self.stats is None else int(self.stats.missing_packets + self.stats.overruns)

    def packet_rate(self) -> float:
        """Packets/s over the last second of data (the sensor's pace, also in a replay read faster than real
        time); 0 once no data has come for a second, so a stream that stopped does not show its last rate."""
        if not self.rates or time.monotonic() - self._rate_at > RATE_WINDOW_S:
            return 0.0
        latest = self.rates[-1][1]
        recent = [r for r in self.rates if r[1] >= latest - RATE_WINDOW_S]
        span = latest - recent[0][0]
        return sum(r[2] for r in recent) / span if span > 0 else 0.0

    def clock_steps(self) -> tuple[ClockStep, ...]:
        return () if self.stats is None else self.stats.clock_steps

    def silence_error(self, silent_s: float) -> str:
        """The error when no usable sweep came for ``silent_s``: what the LiDAR did send, and what to check."""
        describe, unusable = self.describe, self.unusable
        if unusable is not None and unusable.use is SweepUse.LOSSY:
            return self._loss_error(unusable.sweep, silent_s)
        if unusable is not None and unusable.use is SweepUse.BLIND:
            return (f"the VLP-16 at {describe} turns ({unusable.sweep.rpm:.0f} rpm) and sends whole turns but sees "
                    f"almost nothing: returns in {unusable.returns} of {RINGS * AZIMUTH_BINS} directions (at least "
                    f"{BLIND_FRACTION:.0%} needed) for {silent_s:.1f} s: its window is covered, dirty or blinded, or "
                    "its lasers are off (every range zero); clean and uncover it, then check its settings (web "
                    "interface)")
        partial = unusable.sweep if unusable is not None else None
        if partial is not None and partial.rpm < STOPPED_RPM:
            return (f"the VLP-16 at {describe} sends packets ({self.packet_rate():.0f}/s) but its head does not turn "
                    f"({partial.rpm:.0f} rpm), no sweep for {silent_s:.1f} s: its motor is stopped or blocked; check "
                    "that nothing holds the head and the motor's rpm setting (web interface), then power-cycle it")
        if partial is not None:
            return (f"no complete VLP-16 sweep from {describe} for {silent_s:.1f} s: packets arrive with gaps of a "
                    f"turn or more ({self.packets_lost()} lost so far): check the network (deploy/network)")
        if self.stats is not None and self.stats.bad_packets:
            faults = ", ".join(f"{k.name} {v}" for k, v in self.stats.faults.items())
            return (f"no usable VLP-16 sweep from {describe} for {silent_s:.1f} s; bad packets: {faults} "
                    "(docs/vlp16.md, Validation)")
        return (f"no VLP-16 data from {describe} for {silent_s:.1f} s: check the sensor's power and cable, and "
                "that it sends to this host's address and port (deploy/network)")

    def _loss_error(self, sweep: Sweep, silent_s: float) -> str:
        return (f"the VLP-16 at {self.describe} loses packets: no sweep with at least "
                f"{self.min_sweep_fraction:.0%} of a turn's packets for {silent_s:.1f} s (the latest held "
                f"{sweep.coverage:.0%}; {self.packets_lost()} packets lost so far): check its cable and switch, that "
                "nothing else floods its network, and the receive buffer (deploy/network); or accept more loss "
                "with --min-sweep-fraction")

    def unusable_line(self) -> str | None:
        """The status line while sweeps keep coming that cannot go into a pair (before the silence error)."""
        unusable = self.unusable
        if unusable is None:
            return None
        if unusable.use is SweepUse.LOSSY:
            return (f"the LiDAR's sweeps are incomplete: {unusable.sweep.coverage:.0%} of a turn's packets arrive, "
                    f"{self.min_sweep_fraction:.0%} needed")
        if unusable.use is SweepUse.BLIND:
            return f"the LiDAR sees almost nothing: returns in {unusable.returns} of {RINGS * AZIMUTH_BINS} directions"
        return None
