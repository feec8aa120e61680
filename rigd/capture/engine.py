"""The capture loop: wait until the rig stands still at a new place, take a pair, repeat until ``n`` pairs.

Per LiDAR sweep: judge it (a whole turn, complete to ``min_sweep_fraction`` of its packets, with returns);
a usable one updates the still window (rigd.capture.gate), then the camera frames received are read and
the loop decides: not moved since the last pair -> "move to the next place"; camera or LiDAR motion ->
"waiting for the rig to stop"; still for less than ``still_seconds`` -> "hold still"; still long enough and
a camera frame exposed inside the window -> fuse the ``sweeps`` sweeps nearest that frame, check that the
pair is synchronised (the sweeps' own receive times against their device times, inside the window), and
write it atomically (rigd.dataset.write_pair). A step of the LiDAR's clock restarts the window. No usable
sweep for the silence timeout ends the capture with an error that says why (no data, a stopped head, lost
packets, a blind sensor). A simulated rig that has stopped at all its places and stood at the last one longer
than a stop lasts, with pairs still missing, ends it too (:class:`SimRigEndedError`): it gives no new place.
``stop`` is looked at between sweeps and never while a pair is being taken, so a pair is either written whole
or not begun. A capture holds the dataset's writer lock (rigd.locks) from start to end: a second one
into the same folder is refused at once.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import threading
import time
from collections import deque
from pathlib import Path

import numpy as np

from drivers.sim.motion import MotionRigSpec
from drivers.vlp16 import StreamStats, Sweep
from rigd.capture.config import RigSettings, load_settings
from rigd.capture.errors import CaptureError, SensorSilenceError
from rigd.capture.frames import FrameLead, WindowFrames
from rigd.capture.fuse import fuse_sweeps, sweeps_for_frame
from rigd.capture.gate import (
    MOVING_SWEEPS,
    DirectionGrid,
    FrameSample,
    StillnessGate,
    StillThresholds,
    SweepSample,
    camera_image,
    range_change_m,
    range_image,
)
from rigd.capture.lidar_link import LidarLink, SweepUse
from rigd.capture.pair_meta import TakenPair, pair_meta
from rigd.capture.records import CaptureRequest, CaptureState, CaptureStatus, CaptureSummary, Progress
from rigd.capture.sim_end import SIM_MOVE_S, SIM_STOP_MARGIN_S, sim_stops
from rigd.capture.sources import CameraFrame, Sources, frame_time, open_sources
from rigd.capture.specs import parse_camera, parse_lidar
from rigd.capture.status import Counters, StatusLine, holding_line, motion_note
from rigd.capture.sync import sync_problem
from rigd.capture.watchdog import Watchdog
from rigd.capture.writer import PairWriter, lock
from rigd.dataset import read_pcd
from rigd.dataset.store import pair_folders

DEFAULT_TOLERANCE_DEG = 0.2  # the rig's rotation tolerance when the rig file gives none (calib.assess)
UNUSABLE_NOTE_S = 1.0  # no usable sweep for this long: the status line says why (the error comes later)
RECENT_SWEEPS = 100  # 10 s of sweeps kept with their points for fusing
_POLL_S = 0.1


def run_capture(request: CaptureRequest, progress: Progress | None = None,
                stop: threading.Event | None = None) -> CaptureSummary:
    """Capture until the dataset has ``request.n`` pairs or ``stop`` is set (then it returns between pairs)."""
    _validate(request)
    settings = settings_for(request)
    lidar, camera = parse_lidar(request.lidar), parse_camera(request.camera)
    out = Path(request.out)
    with contextlib.ExitStack() as stack:
        if len(existing_pairs(out)) < request.n:  # a complete dataset is only read: it may be read-only
            stack.enter_context(lock(out))
        existing = existing_pairs(out)  # under the lock: no other writer adds pairs from now on
        if len(existing) >= request.n:
            if progress:
                progress(CaptureStatus(CaptureState.DONE.value, len(existing), request.n, 0.0, 0.0, 0,
                                       f"{out} already has {len(existing)} pairs"))
            return CaptureSummary(out, (), ())
        sim_default = MotionRigSpec(stops=sim_stops(request.n - len(existing)),
                                    still_s=request.still_seconds + SIM_STOP_MARGIN_S, move_s=SIM_MOVE_S)
        sources = open_sources(stack, lidar, camera, settings, sim_default, places_done=len(existing),
                               nominal_head=request.nominal_head)
        return _Capture(request, settings, sources, existing, progress, stop or threading.Event()).run()


def settings_for(request: CaptureRequest) -> RigSettings:
    """The rig file's settings with the request's own choices over them (the SDK camera's serial)."""
    settings = load_settings(request.config)
    if request.serial is None:
        return settings
    return dataclasses.replace(settings, sdk=dataclasses.replace(settings.sdk, serial=request.serial))


def _validate(request: CaptureRequest) -> None:
    numbers = {"still_seconds": request.still_seconds, "min_move": request.min_move,
               "silence_timeout_s": request.silence_timeout_s, "min_sweep_fraction": request.min_sweep_fraction}
    for name, value in numbers.items():
        if not math.isfinite(value):
            raise CaptureError(f"capture: {name} must be a finite number, got {value}")
    checks = [
        (request.n >= 1, f"n must be >= 1, got {request.n}"),
        (request.still_seconds > 0, f"still_seconds must be > 0, got {request.still_seconds}"),
        (request.sweeps >= 1, f"sweeps must be >= 1, got {request.sweeps}"),
        (request.min_move >= 0, f"min_move must be >= 0 m, got {request.min_move}"),
        (request.silence_timeout_s > 0, f"silence_timeout_s must be > 0, got {request.silence_timeout_s}"),
        (0 < request.min_sweep_fraction <= 1,
         f"min_sweep_fraction must be in (0, 1], got {request.min_sweep_fraction}"),
    ]
    for ok, message in checks:
        if not ok:
            raise CaptureError(f"capture: {message}")


def existing_pairs(out: Path) -> list[Path]:
    """Complete pairs of the dataset ``out`` in index order (a leftover ``.NNNN.tmp`` is not one)."""
    return pair_folders(out)


def thresholds_for(settings: RigSettings) -> StillThresholds:
    """The stillness thresholds from the rig file's rotation tolerance (docs/capture.md)."""
    tolerance = settings.tolerance.tolerance_rot_deg if settings.tolerance is not None else DEFAULT_TOLERANCE_DEG
    return StillThresholds.from_tolerance(tolerance)


class _Capture:
    """One run of the capture loop over open sources."""

    def __init__(self, request: CaptureRequest, settings: RigSettings, sources: Sources, existing: list[Path],
                 progress: Progress | None, stop: threading.Event) -> None:
        self.request = request
        self.sources = sources
        self.out = Path(request.out)
        self.stop = stop
        self.done = len(existing)
        self.reference = _reference_image(existing[-1]) if existing else None
        self.gate = StillnessGate(thresholds_for(settings))
        self.recent: deque[tuple[SweepSample, Sweep]] = deque(maxlen=RECENT_SWEEPS)  # usable sweeps only
        self.frames = WindowFrames()
        self.lead = FrameLead(request.silence_timeout_s)
        self.link = LidarLink(sources.lidar.describe, request.min_sweep_fraction)
        self.writer = PairWriter(self.out, settings, sources.sim_spec)
        self.status = StatusLine(progress, request.n, self._counters)
        self.window_lossy = 0  # sweeps left out of the current still window for lost packets
        self.written: list[Path] = []
        self.seconds: list[float] = []
        self._since = time.monotonic()
        self.watchdog = Watchdog(request, sources, len(existing))

    # -- loop ----------------------------------------------------------------------------------------------
    def run(self) -> CaptureSummary:
        self._set(CaptureState.STARTING, f"waiting for the LiDAR ({self.sources.lidar.describe}) and the camera "
                                         f"({self.sources.camera.describe})")
        # Silence is counted from the last usable sweep: others (a stopped head, lost packets, a blind sensor)
        # are no data a pair can be made of, but they end the start-up allowance and say what is wrong.
        last_usable, any_data = time.monotonic(), False
        while self.done < self.request.n:
            if self.stop.is_set():
                self._set(CaptureState.STOPPED, f"stopped after {self.done}/{self.request.n} pairs; rerun the same "
                                                "command to continue")
                break
            item = self.sources.lidar.get(_POLL_S)
            now = time.monotonic()
            if item is not None:
                if not any_data:
                    last_usable, any_data = now, True
                if self._on_item(item.sweep, item.stats, now):
                    last_usable = now
            if now - last_usable > self.watchdog.silence_limit(any_data):
                raise SensorSilenceError(self.link.silence_error(now - last_usable))
            unusable_line = self.link.unusable_line()
            if now - last_usable > UNUSABLE_NOTE_S and unusable_line is not None:
                self._set(CaptureState.UNUSABLE_LIDAR, unusable_line)
            self.watchdog.check_camera()
            self.watchdog.check_sim_end(self.done, len(self.written), self.out)
            self.status.emit(force=False)
        else:
            self._set(CaptureState.DONE, f"captured {self.done}/{self.request.n}: done")
        return CaptureSummary(self.out, tuple(self.written), tuple(self.seconds))

    def _on_item(self, sweep: Sweep, stats: StreamStats, now: float) -> bool:
        """One sweep from the LiDAR; True when it was usable (and went to the gate)."""
        step = self.link.arrived(sweep, stats, now)
        if step is not None:  # the window built on the old offset is dropped
            self.gate.reset()
            self._set(CaptureState.NOT_SYNCHRONISED,
                      f"the LiDAR's clock stepped {'back' if step.step_s < 0 else 'forward'} {abs(step.step_s):.3f} s: "
                      "its offset to the host clock is measured again; the still window restarts")
        use, grid = self.link.judge(sweep)
        if use is not SweepUse.USABLE or grid is None:
            self.window_lossy += use is SweepUse.LOSSY
            return False
        self._on_sweep(sweep, grid)
        return True

    def _on_sweep(self, sweep: Sweep, grid: DirectionGrid) -> None:
        offset = sweep.clock_offset_s
        sample = SweepSample(sweep.start.device + offset, sweep.end.device + offset, grid.range_m, grid)
        self.recent.append((sample, sweep))
        self.gate.add_sweep(sample)
        if self.gate.sweeps <= 1:
            self.window_lossy = 0
        for frame in self.sources.camera.poll(sample.t_end):
            t = frame_time(frame.panorama, self.sources.camera.describe)
            self.gate.add_frame(FrameSample(t, camera_image(frame.panorama.image)))
            self.frames.add(t, frame)
        self.frames.prune(self.gate.window)
        self._decide(sample)

    def _decide(self, sample: SweepSample) -> None:
        gate, request = self.gate, self.request
        lead_since, self.lead.since = self.lead.since, None  # frames ahead count only while a frame is awaited
        moved_m = None if self.reference is None else range_change_m(self.reference, sample.image)
        if moved_m is not None and moved_m < request.min_move:
            self._set(CaptureState.NEED_MOVE, "move to the next place")
            return
        if gate.camera_saw_motion():
            change = gate.camera_change()
            gate.restart()
            self._set(CaptureState.WAITING_FOR_STOP, f"waiting for the rig to stop (the camera sees motion: "
                                                     f"{change:.2f} deg)")
            return
        if gate.sweeps < MOVING_SWEEPS:
            self._set(CaptureState.WAITING_FOR_STOP, f"waiting for the rig to stop{motion_note(gate)}")
            return
        if not gate.held(request.still_seconds, request.sweeps):
            self._set(CaptureState.HOLDING_STILL,
                      holding_line(gate, request.still_seconds, request.sweeps, self.window_lossy))
            return
        window = gate.window
        assert window is not None
        inside = self.frames.inside(window)
        if not inside:
            self.lead.since = lead_since
            self._waiting_for_frame(window)
            return
        self._take_pair(*inside[-1], window, moved_m)

    def _waiting_for_frame(self, window: tuple[float, float]) -> None:
        """No frame in the still window yet: normal for a while, unless the frames run ahead of the LiDAR."""
        lidar_offset = self.recent[-1][1].clock_offset_s if self.recent else math.nan
        what = self.lead.check(self.frames.newest(), window, lidar_offset)
        if what is None:
            self._set(CaptureState.WAITING_FOR_FRAME, "hold still: waiting for a camera frame")
        else:
            self._set(CaptureState.NOT_SYNCHRONISED, f"not synchronised: {what}")

    # -- a pair --------------------------------------------------------------------------------------------
    def _take_pair(self, frame_t: float, frame: CameraFrame, window: tuple[float, float],
                   moved_m: float | None) -> None:
        recent = list(self.recent)
        spans = [(s.t_start, s.t_end) for s, _ in recent]
        chosen = [recent[i] for i in sweeps_for_frame(spans, frame_t, window, self.request.sweeps)]
        problem = sync_problem([sw for _, sw in chosen], window, self.link.clock_steps())
        if problem is not None:
            self.gate.reset()
            self._set(CaptureState.NOT_SYNCHRONISED, f"not taking a pair: {problem}; the still window restarts")
            return
        self._set(CaptureState.CAPTURING, f"capturing pair {self.done + 1}/{self.request.n}")
        cloud = fuse_sweeps([sw for _, sw in chosen])
        meta = pair_meta(self.request, TakenPair(frame_t, frame, chosen, cloud, window, moved_m), self.gate,
                         clock_steps=self.link.clock_steps(), packets_lost=self.link.packets_lost())
        path = self.writer.write(frame, cloud, meta, self.done)
        now = time.monotonic()
        self.written.append(path)
        self.seconds.append(now - self._since)
        self._since = now
        self.done += 1
        self.watchdog.pair_taken(frame_t)
        assert cloud.ring is not None  # fuse_sweeps always gives the ring
        self.reference = range_image(cloud.points_lidar, cloud.ring)
        self.gate.restart()
        self._set(CaptureState.CAPTURED, f"captured {self.done}/{self.request.n}")

    # -- status ------------------------------------------------------------------------------------------------
    def _set(self, state: CaptureState, message: str) -> None:
        self.status.set(state, message)

    def _counters(self) -> Counters:
        return Counters(self.done, self.gate.still_for_s, self.link.packet_rate(), self.link.packets_lost())


def _reference_image(pair_dir: Path) -> np.ndarray | None:
    """The range image of a written pair's cloud: a resumed capture must move on from it too."""
    cloud = read_pcd(pair_dir / "cloud.pcd")
    return None if cloud.ring is None else range_image(cloud.points_lidar, cloud.ring)
