"""Still moments of a recording, found with the capture's stillness gate (rigd.capture.gate).

The sweeps go through :class:`~rigd.capture.gate.StillnessGate` in time order, exactly as ``rigd capture``
feeds it live: every sweep against its window's first one (point to plane), a motion beyond the thresholds
restarting the window. :class:`WindowTracker` records each window the gate held; a window is a still stretch
when it spans ``still_seconds`` and ``sweeps`` sweeps (``StillnessGate.held``). :func:`select_pairs` then keeps,
in time order, up to ``n`` stretches that

- hold an image stamped within ``max_offset_s`` of one of their sweeps, taken as ``rigd capture`` takes it: the
  latest image inside the window when the gate first holds it (grown until one lies inside), and
- lie at a new place: the 90th percentile of the range change against every kept place
  (``rigd.capture.gate.range_change_m``, capture's "moved" test) is at least ``min_move_m``,
- and that no other evidence of motion (:mod:`.motion`: an IMU, odometry, the images) says was moving,

and says for every stretch not kept why not.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from rigd.capture.gate import MOVING_SWEEPS, Motion, StillnessGate, StillThresholds, SweepSample, range_change_m
from rigd.importers.bag.motion import MotionEvidence

F32 = NDArray[np.float32]


@dataclass(frozen=True)
class StillOptions:
    """``n`` pairs at most; a still stretch spans ``still_seconds`` s and ``sweeps`` sweeps (rigd capture's
    defaults); places ``min_move_m`` m apart (capture's 90th percentile range change); an image within
    ``max_offset_s`` s of its sweep; ``tolerance_deg`` the rig's rotation tolerance the thresholds come from."""

    n: int = 12
    still_seconds: float = 2.0
    sweeps: int = 5
    min_move_m: float = 0.5
    max_offset_s: float = 0.05
    tolerance_deg: float = 0.2


class Verdict(Enum):
    """What became of a stretch of the recording."""

    KEPT = "kept"
    MOVING = "moving"
    TOO_SHORT = "too short"
    NO_IMAGE = "no image"
    SAME_PLACE = "same place"
    ENOUGH = "enough pairs"


@dataclass(frozen=True)
class SweepTime:
    """A sweep's first and last return, s on the header clock."""

    t_start_s: float
    t_end_s: float

    def offset_s(self, t_s: float) -> float:
        """How far ``t_s`` lies outside the sweep, s (0 inside it)."""
        return max(self.t_start_s - t_s, t_s - self.t_end_s, 0.0)


@dataclass(frozen=True)
class Window:
    """One window of the gate: sweeps ``first`` .. ``last`` (indices in the recording), their time span s, the
    largest rotation deg and translation m from its first sweep, whether it ``held`` as a still stretch, the
    first sweep's (16,360) float32 range image m, and the motion that ended it (None: the recording did)."""

    first: int
    last: int
    t_start_s: float
    t_end_s: float
    rotation_deg: float
    translation_m: float
    held: bool
    anchor_range_m: F32
    ended_by: Motion | None

    @property
    def sweeps(self) -> int:
        return self.last - self.first + 1

    @property
    def seconds(self) -> float:
        return self.t_end_s - self.t_start_s


class WindowTracker:
    """Feeds sweeps to a :class:`StillnessGate` and records its windows (module doc)."""

    def __init__(self, options: StillOptions) -> None:
        self.options = options
        self.gate = StillnessGate(StillThresholds.from_tolerance(options.tolerance_deg))
        self.windows: list[Window] = []
        self._first: int | None = None
        self._last = -1

    def add(self, *, index: int, sample: SweepSample) -> None:
        """Sweep ``index`` (increasing) of the recording."""
        closing = self._snapshot()
        motion = self.gate.add_sweep(sample)
        if self.gate.anchor is sample:  # the gate started a window at this sweep
            if closing is not None:
                self.windows.append(dataclasses.replace(closing, ended_by=motion))
            self._first = index
        self._last = index

    def finish(self) -> list[Window]:
        """Every window, in time order (the last one closed by the end of the recording)."""
        last = self._snapshot()
        if last is not None:
            self.windows.append(last)
            self._first = None
        return self.windows

    def _snapshot(self) -> Window | None:
        gate, window = self.gate, self.gate.window
        if self._first is None or window is None or gate.anchor is None:
            return None
        return Window(self._first, self._last, window[0], window[1], gate.rotation_deg, gate.translation_m,
                      gate.held(self.options.still_seconds, self.options.sweeps), gate.anchor.image, None)


@dataclass(frozen=True)
class Decision:
    """A stretch ``t_start_s`` .. ``t_end_s`` s of the recording, its :class:`Verdict` and the reason in words;
    for a kept one the image (index into the image stamps) and the sweep (index into the sweeps) of its pair, and
    the last sweep of the window when the pair was taken (capture's window then: ``window.first`` .. it)."""

    t_start_s: float
    t_end_s: float
    verdict: Verdict
    reason: str
    window: Window | None = None
    image: int | None = None
    sweep: int | None = None
    last_sweep: int | None = None


def _moving(run: Sequence[Window], options: StillOptions) -> Decision:
    """A run of windows the gate never held: motion, or stops shorter than a still stretch."""
    longest = max(run, key=lambda w: w.seconds)
    start, end = run[0].t_start_s, run[-1].t_end_s
    if longest.sweeps >= MOVING_SWEEPS:
        return Decision(start, end, Verdict.TOO_SHORT,
                        f"still for at most {longest.seconds:.2f} s and {longest.sweeps} sweeps (needs "
                        f"{options.still_seconds:g} s and {options.sweeps} sweeps)")
    motions = [w.ended_by for w in run if w.ended_by is not None]
    finite = [m for m in motions if math.isfinite(m.rotation_deg)]
    if finite:
        rot = max(m.rotation_deg for m in finite)
        trans = max(m.translation_m for m in finite)
        what = f"moving: up to {rot:.2f} deg and {trans * 100:.1f} cm from sweep to sweep"
    else:
        what = "moving: the scene changed from sweep to sweep"
    changed = len(motions) - len(finite)
    if finite and changed:
        what += f" ({changed} sweeps too different to align)"
    return Decision(start, end, Verdict.MOVING, what)


def _pair_in(window: Window, image_t_s: Sequence[float], sweeps: Sequence[SweepTime],
             options: StillOptions) -> tuple[int, int, int] | None:
    """(image, sweep, last) as ``rigd capture`` takes the pair: the window as it stands when the gate first holds
    it (``still_seconds`` and ``sweeps``), grown sweep by sweep until an image lies inside it; its latest image,
    the sweep nearest that image (within ``max_offset_s``) and the window's last sweep then. None: no image."""
    start = sweeps[window.first].t_start_s
    for last in range(window.first + max(options.sweeps, MOVING_SWEEPS) - 1, window.last + 1):
        end = sweeps[last].t_end_s
        newest = int(np.searchsorted(image_t_s, end, side="right")) - 1
        if end - start < options.still_seconds or newest < 0 or image_t_s[newest] < start:
            continue
        t = image_t_s[newest]
        sweep = min(range(window.first, last + 1), key=lambda k: sweeps[k].offset_s(t))
        if sweeps[sweep].offset_s(t) <= options.max_offset_s:
            return newest, sweep, last
    return None


def select_pairs(*, windows: Sequence[Window], image_t_s: Sequence[float], sweeps: Sequence[SweepTime],
                 options: StillOptions, motion: MotionEvidence | None = None) -> list[Decision]:
    """A :class:`Decision` for every stretch of the recording, in time order (module doc). ``image_t_s``: the
    images' stamps s, sorted; ``sweeps``: every sweep's span, in the order the windows index them; ``motion``:
    the other sources of motion (None: the LiDAR alone)."""
    decisions: list[Decision] = []
    kept: list[tuple[int, Window]] = []
    run: list[Window] = []
    for window in windows:
        if not window.held:
            run.append(window)
            continue
        if run:
            decisions.append(_moving(run, options))
            run = []
        decisions.append(_still(window, kept, image_t_s, sweeps, options, motion))
        if decisions[-1].verdict is Verdict.KEPT:
            kept.append((len(kept), window))
    if run:
        decisions.append(_moving(run, options))
    return decisions


def _still(window: Window, kept: Sequence[tuple[int, Window]], image_t_s: Sequence[float],
           sweeps: Sequence[SweepTime], options: StillOptions, motion: MotionEvidence | None) -> Decision:
    span = (window.t_start_s, window.t_end_s)
    what = (f"still {window.seconds:.2f} s, {window.sweeps} sweeps, within {window.rotation_deg:.3f} deg and "
            f"{window.translation_m * 1000:.1f} mm")
    moving = None if motion is None else motion.moving_in(t_start_s=window.t_start_s, t_end_s=window.t_end_s)
    if moving is not None:
        return Decision(*span, Verdict.MOVING, f"the LiDAR {what}, but {moving}", window)
    if len(kept) >= options.n:
        return Decision(*span, Verdict.ENOUGH, f"{what}; {options.n} pairs kept already (--n)", window)
    for number, other in kept:
        change = range_change_m(other.anchor_range_m, window.anchor_range_m)
        if change < options.min_move_m:
            return Decision(*span, Verdict.SAME_PLACE, f"{what}; the place of pair {number:04d} (range change "
                            f"{change:.2f} m < {options.min_move_m:g} m)", window)
    pair = _pair_in(window, image_t_s, sweeps, options)
    if pair is None:
        return Decision(*span, Verdict.NO_IMAGE,
                        f"{what}; no image within {options.max_offset_s:g} s of one of its sweeps", window)
    return Decision(*span, Verdict.KEPT, what, window, pair[0], pair[1], pair[2])
