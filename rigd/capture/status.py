"""The capture's status line: its state and message, sent to the progress callback on every change of state and
every STATUS_PERIOD_S, and the words of the waits it shows."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import NamedTuple

from rigd.capture.gate import MIN_INLIER_FRACTION, StillnessGate
from rigd.capture.records import CaptureState, CaptureStatus, Progress

STATUS_PERIOD_S = 0.5


class Counters(NamedTuple):
    """What the status line shows beside its message: pairs done, seconds still, LiDAR packets/s and lost."""

    pairs_done: int
    still_for_s: float
    packet_rate_hz: float
    packets_lost: int


class StatusLine:
    """The state and message of a capture of ``pairs_wanted`` pairs; ``counters`` reads the numbers shown."""

    def __init__(self, progress: Progress | None, pairs_wanted: int, counters: Callable[[], Counters]) -> None:
        self.progress = progress
        self.pairs_wanted = pairs_wanted
        self.counters = counters
        self.state = CaptureState.STARTING
        self.message = ""
        self._last_emit = -math.inf

    def set(self, state: CaptureState, message: str) -> None:
        # A new sync fault (a clock step, a pair refused) is an event: shown even when one was showing already.
        event = state is CaptureState.NOT_SYNCHRONISED and message != self.message
        changed = state is not self.state or state is CaptureState.CAPTURED or event
        self.state, self.message = state, message
        self.emit(force=changed or state is CaptureState.STARTING)

    def emit(self, force: bool) -> None:
        now = time.monotonic()
        if self.progress is None or (not force and now - self._last_emit < STATUS_PERIOD_S):
            return
        self._last_emit = now
        counters = self.counters()
        self.progress(CaptureStatus(self.state.value, counters.pairs_done, self.pairs_wanted,
                                    round(counters.still_for_s, 3), round(counters.packet_rate_hz, 1),
                                    counters.packets_lost, self.message))


def motion_note(gate: StillnessGate) -> str:
    """The LiDAR's motion in the still window, for "waiting for the rig to stop" (empty before any)."""
    motion, limits = gate.last_motion, gate.thresholds
    if motion is None:
        return ""
    if not math.isfinite(motion.rotation_deg) or motion.inlier_fraction < MIN_INLIER_FRACTION:
        return " (LiDAR: the scene changed)"
    return (f" (LiDAR: {motion.rotation_deg:.3f} deg, {motion.translation_m * 1000:.1f} mm from the window's first "
            f"sweep; still is within {limits.rotation_deg:.3f} deg, {limits.translation_m * 1000:.1f} mm)")


def holding_line(gate: StillnessGate, still_seconds: float, sweeps: int, lossy: int) -> str:
    """"Hold still" while the window is shorter than ``still_seconds`` or holds fewer than ``sweeps`` sweeps
    (``lossy`` left out of it for lost packets)."""
    remaining = max(still_seconds - gate.still_for_s, 0.0)
    if remaining > 0:
        return f"hold still {remaining:.1f} s"
    lost = f" ({lossy} left out: packets lost)" if lossy else ""
    return f"hold still: {gate.sweeps} of {sweeps} sweeps{lost}"
