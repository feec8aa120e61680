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
import errno
import math
import shutil
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np

from calib.geometry import Transform
from drivers.sim.motion import MotionRigSpec
from drivers.vlp16 import ClockStep, StreamStats, Sweep
from drivers.vlp16.layout import SEQUENCE_US
from rigd.capture.config import RigSettings, load_settings
from rigd.capture.errors import CaptureError, DiskFullError, SensorSilenceError, SimRigEndedError, SyncError
from rigd.capture.fuse import fuse_sweeps, sweeps_for_frame
from rigd.capture.gate import (
    AZIMUTH_BINS,
    MIN_INLIER_FRACTION,
    MOVING_SWEEPS,
    RINGS,
    DirectionGrid,
    FrameSample,
    StillnessGate,
    StillThresholds,
    SweepSample,
    camera_image,
    direction_grid,
    range_change_m,
    range_image,
)
from rigd.capture.pair_files import camera_difference, pair_bytes, pair_images, rig_camera
from rigd.capture.sources import CameraFrame, Sources, frame_time, open_sources
from rigd.capture.specs import CameraKind as SourceKind
from rigd.capture.specs import LidarKind, parse_camera, parse_lidar
from rigd.dataset import Cloud, RigConfig, read_pcd, write_ground_truth, write_pair, write_rig
from rigd.dataset.store import pair_folders, read_yaml
from rigd.errors import DatasetError
from rigd.locks import DatasetLock
from rigd.version import software_version

DEFAULT_MIN_MOVE_M = 0.5
DEFAULT_MIN_SWEEP_FRACTION = 0.99  # of a turn's packets, in every fused sweep
DEFAULT_TOLERANCE_DEG = 0.2  # the rig's rotation tolerance when the rig file gives none (calib.assess)
# A sweep's packets received more than this off its device time on the host clock (or outside the still
# window): the LiDAR's clock mapping is not what the window was built on, so the pair is not taken. Receive
# delays stay in milliseconds; half a turn still puts the sweep at the right turn.
SYNC_BOUND_S = 0.05
BLIND_FRACTION = 0.05  # a whole turn with returns in fewer of its 16 x 360 directions sees (almost) nothing
COVERAGE_SLACK_BLOCKS = 2  # where the cut falls moves a whole turn's count by a block either way
UNUSABLE_NOTE_S = 1.0  # no usable sweep for this long: the status line says why (the error comes later)
# Camera frames this far ahead of the LiDAR's latest sweep on the host clock cannot be explained by the
# loop being behind for long: one of the clocks is wrong (shown at once, an error after the silence timeout).
CLOCK_DISAGREE_S = 1.0
FRAMES_AHEAD_KEPT = 16  # frames newer than the still window kept for it (they are full images)
# The simulated rig stands still_seconds + this at each place: time for the gate to see the drive's slow end and
# for the pair; the camera renders each stop's view before the rig gets there (drivers.sim.stream), so a frame
# exposed in the still window arrives within a frame period. With 6 s the demo took 84 s, with 3 s 62 s (quiet).
SIM_STOP_MARGIN_S = 3.0
SIM_MOVE_S = 2.0
# The simulated rig stands at its last place for good. Once it has stood there as long as a stop lasts (or the
# gate's --still-seconds, if longer) and this much more, with pairs still missing, no pair can come: the capture
# ends with SimRigEndedError rather than waiting for a new place for ever. At once if the last place has its pair.
SIM_END_GRACE_S = 5.0


def sim_stops(pairs: int) -> int:
    """Places for a simulated rig that should yield ``pairs`` pairs: twice as many plus spares, since a stop
    whose frame rendered too slowly is skipped, and the rig never leaves its last place."""
    return 2 * pairs + 4


STATUS_PERIOD_S = 0.5
# Before its first data a sensor may take this long (the SDK starts the camera, the simulator's sensors start
# as processes and render a first frame); after it, silence_timeout_s applies.
STARTUP_S = 15.0
RECENT_SWEEPS = 100  # 10 s of sweeps kept with their points for fusing
RATE_WINDOW_S = 1.0  # packets/s is over this much of the latest data, and 0 once none came for this long
STOPPED_RPM = 60.0  # a head turning slower than this is stopped (a VLP-16 turns at 300-1200 rpm)
_POLL_S = 0.1


@dataclass(frozen=True)
class CaptureRequest:
    """A capture job: ``n`` pairs in the dataset ``out`` (counting pairs already there).

    Sources as in ``rigd capture`` (docs/capture.md); ``config``: the rig file for the dataset's rig.yaml
    (camera size, initial guess, the tolerance the stillness thresholds come from) and the SDK settings;
    None: built-in defaults. ``min_sweep_fraction``: every fused sweep holds at least this fraction of a
    turn's packets (0 < f <= 1). ``serial``: the SDK camera's head serial number (None: the rig file's
    camera.sdk.serial, else the only camera). ``nominal_head``: accept rigd's nominal head for the SDK camera
    (instead of reading its factory head when the rig file names no head file; refused otherwise).
    """

    out: Path
    n: int
    lidar: str = "sim"
    camera: str = "sim"
    still_seconds: float = 2.0
    sweeps: int = 5
    min_move: float = DEFAULT_MIN_MOVE_M
    silence_timeout_s: float = 5.0
    config: Path | None = None
    min_sweep_fraction: float = DEFAULT_MIN_SWEEP_FRACTION
    serial: int | None = None
    nominal_head: bool = False


class CaptureState(Enum):
    STARTING = "starting"
    WAITING_FOR_STOP = "waiting_for_stop"
    HOLDING_STILL = "holding_still"
    WAITING_FOR_FRAME = "waiting_for_frame"
    NOT_SYNCHRONISED = "not_synchronised"
    UNUSABLE_LIDAR = "unusable_lidar"
    NEED_MOVE = "need_move"
    CAPTURING = "capturing"
    CAPTURED = "captured"
    DONE = "done"
    STOPPED = "stopped"


class SweepUse(Enum):
    """Whether a LiDAR sweep can go into a pair, and if not, why."""

    USABLE = "usable"
    PARTIAL = "partial"  # not a whole turn: the stream's ends, a clock step, whole turns lost, a stopped head
    LOSSY = "lossy"  # packets lost: less than min_sweep_fraction of a turn
    BLIND = "blind"  # a whole turn with (almost) no returns


@dataclass(frozen=True)
class CaptureStatus:
    """Passed to the progress callback on every state change and every 0.5 s; ``state`` is a CaptureState value."""

    state: str
    pairs_done: int
    pairs_wanted: int
    still_for_s: float
    packet_rate_hz: float
    packets_lost: int
    message: str


@dataclass(frozen=True)
class CaptureSummary:
    """The pairs this run wrote (folders) and the seconds each took (from the start or the previous pair)."""

    out: Path
    pairs: tuple[Path, ...]
    seconds_per_pair: tuple[float, ...]


@dataclass(frozen=True)
class Unusable:
    """The latest sweep that could not go into a pair: why, the sweep, and its directions with a return."""

    use: SweepUse
    sweep: Sweep
    returns: int


Progress = Callable[[CaptureStatus], None]


def run_capture(request: CaptureRequest, progress: Progress | None = None,
                stop: threading.Event | None = None) -> CaptureSummary:
    """Capture until the dataset has ``request.n`` pairs or ``stop`` is set (then it returns between pairs)."""
    _validate(request)
    settings = settings_for(request)
    lidar, camera = parse_lidar(request.lidar), parse_camera(request.camera)
    out = Path(request.out)
    with contextlib.ExitStack() as stack:
        if len(existing_pairs(out)) < request.n:  # a complete dataset is only read: it may be read-only
            stack.enter_context(_lock(out))
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


def _lock(out: Path) -> DatasetLock:
    """The dataset's writer lock, for the whole capture; DatasetLockedError at once if another process has it."""
    try:
        return DatasetLock.acquire(out)
    except DatasetError as exc:
        if _disk_full(exc):
            raise DiskFullError(f"{exc}: free some space and rerun") from exc
        raise


def _disk_full(exc: DatasetError) -> bool:
    cause = exc.__cause__
    return isinstance(cause, OSError) and cause.errno in (errno.ENOSPC, errno.EDQUOT)


def thresholds_for(settings: RigSettings) -> StillThresholds:
    """The stillness thresholds from the rig file's rotation tolerance (docs/capture.md)."""
    tolerance = settings.tolerance.tolerance_rot_deg if settings.tolerance is not None else DEFAULT_TOLERANCE_DEG
    return StillThresholds.from_tolerance(tolerance)


class _Capture:
    """One run of the capture loop over open sources."""

    def __init__(self, request: CaptureRequest, settings: RigSettings, sources: Sources, existing: list[Path],
                 progress: Progress | None, stop: threading.Event) -> None:
        self.request = request
        self.settings = settings
        self.sources = sources
        self.out = Path(request.out)
        self.progress = progress
        self.stop = stop
        self.done = len(existing)
        self.reference = _reference_image(existing[-1]) if existing else None
        self.thresholds = thresholds_for(settings)
        self.gate = StillnessGate(self.thresholds)
        self.recent: deque[tuple[SweepSample, Sweep]] = deque(maxlen=RECENT_SWEEPS)  # usable sweeps only
        self.frames: list[tuple[float, CameraFrame]] = []  # (host time s, frame): those the window may use
        self.rates: deque[tuple[float, float, int]] = deque(maxlen=20)  # (start, end, packets) of sweeps
        self._rate_at = -math.inf  # monotonic time the latest sweep (whole or not) arrived
        self.unusable: Unusable | None = None  # the latest sweep that could not go into a pair
        self.window_lossy = 0  # sweeps left out of the current still window for lost packets
        self.stats: StreamStats | None = None
        self.steps_seen = 0  # LiDAR clock steps already acted on
        self.unsynced_since: float | None = None  # monotonic time camera frames were first seen ahead
        self.written: list[Path] = []
        self.seconds: list[float] = []
        self.state = CaptureState.STARTING
        self.message = ""
        self._last_emit = -math.inf
        self._since = time.monotonic()
        self.sim_end = _SimRigEnd.of(sources.sim_spec, request, len(existing))
        self.last_place_taken = False  # a pair at the simulated rig's last place: it gives no other

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
            if now - last_usable > self._silence_limit(any_data):
                raise SensorSilenceError(self._lidar_silence(now - last_usable))
            if now - last_usable > UNUSABLE_NOTE_S and self.unusable is not None:
                self._show_unusable(self.unusable)
            self._check_camera()
            self._check_sim_end()
            self._emit(force=False)
        else:
            self._set(CaptureState.DONE, f"captured {self.done}/{self.request.n}: done")
        return CaptureSummary(self.out, tuple(self.written), tuple(self.seconds))

    def _on_item(self, sweep: Sweep, stats: StreamStats, now: float) -> bool:
        """One sweep from the LiDAR; True when it was usable (and went to the gate)."""
        self.stats = stats
        self._count_packets(sweep, now)
        self._check_clock(stats)
        use, grid = self._judge(sweep)
        if use is not SweepUse.USABLE or grid is None:
            self.unusable = Unusable(use, sweep, 0 if grid is None else grid.returns)
            self.window_lossy += use is SweepUse.LOSSY
            return False
        self.unusable = None
        self._on_sweep(sweep, grid)
        return True

    def _judge(self, sweep: Sweep) -> tuple[SweepUse, DirectionGrid | None]:
        """Whether ``sweep`` can go into a pair: a whole turn, complete to min_sweep_fraction (less the two
        blocks by which where the cut falls changes a whole turn's count), with returns."""
        if not sweep.complete:
            return SweepUse.PARTIAL, None
        slack = COVERAGE_SLACK_BLOCKS * 2 * SEQUENCE_US * sweep.rpm / 60e6  # a block is two firing sequences
        if sweep.coverage < self.request.min_sweep_fraction - slack:
            return SweepUse.LOSSY, None
        xyz = np.stack([sweep.points["x"], sweep.points["y"], sweep.points["z"]], axis=1)
        grid = direction_grid(xyz, sweep.points["ring"])
        if grid.returns < BLIND_FRACTION * RINGS * AZIMUTH_BINS:
            return SweepUse.BLIND, grid
        return SweepUse.USABLE, grid

    def _check_clock(self, stats: StreamStats) -> None:
        """A step of the LiDAR's clock: the window built on the old offset is dropped (the new offset is the
        driver's, measured from the new clock's own packets)."""
        if len(stats.clock_steps) <= self.steps_seen:
            return
        self.steps_seen = len(stats.clock_steps)
        step = stats.clock_steps[-1]
        self.gate.reset()
        self._set(CaptureState.NOT_SYNCHRONISED,
                  f"the LiDAR's clock stepped {'back' if step.step_s < 0 else 'forward'} {abs(step.step_s):.3f} s: its "
                  "offset to the host clock is measured again; the still window restarts")

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
            self.frames.append((t, frame))
        self._prune_frames()
        self._decide(sample)

    def _prune_frames(self) -> None:
        """Keep the newest frame inside the still window and those after it (the window grows onto them)."""
        window = self.gate.window
        if window is None:
            self.frames = self.frames[-FRAMES_AHEAD_KEPT:]
            return
        inside = [f for f in self.frames if window[0] <= f[0] <= window[1]]
        self.frames = inside[-1:] + [f for f in self.frames if f[0] > window[1]][-FRAMES_AHEAD_KEPT:]

    def _decide(self, sample: SweepSample) -> None:
        gate, request = self.gate, self.request
        unsynced_since, self.unsynced_since = self.unsynced_since, None
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
            self._set(CaptureState.WAITING_FOR_STOP, f"waiting for the rig to stop{self._motion_note()}")
            return
        if not gate.held(request.still_seconds, request.sweeps):
            self._set(CaptureState.HOLDING_STILL, self._holding_line())
            return
        window = gate.window
        assert window is not None
        inside = [(t, f) for t, f in self.frames if window[0] <= t <= window[1]]
        if not inside:
            self.unsynced_since = unsynced_since
            self._waiting_for_frame(window)
            return
        self._take_pair(*inside[-1], window, moved_m)

    def _motion_note(self) -> str:
        motion, limits = self.gate.last_motion, self.thresholds
        if motion is None:
            return ""
        if not math.isfinite(motion.rotation_deg) or motion.inlier_fraction < MIN_INLIER_FRACTION:
            return " (LiDAR: the scene changed)"
        return (f" (LiDAR: {motion.rotation_deg:.3f} deg, {motion.translation_m * 1000:.1f} mm from the window's first "
                f"sweep; still is within {limits.rotation_deg:.3f} deg, {limits.translation_m * 1000:.1f} mm)")

    def _holding_line(self) -> str:
        remaining = max(self.request.still_seconds - self.gate.still_for_s, 0.0)
        if remaining > 0:
            return f"hold still {remaining:.1f} s"
        lossy = f" ({self.window_lossy} left out: packets lost)" if self.window_lossy else ""
        return f"hold still: {self.gate.sweeps} of {self.request.sweeps} sweeps{lossy}"

    def _waiting_for_frame(self, window: tuple[float, float]) -> None:
        """No frame in the still window yet: normal for a while, unless the frames run ahead of the LiDAR."""
        newest = max(self.frames, key=lambda f: f[0], default=None)
        ahead_s = -math.inf if newest is None else newest[0] - window[1]
        if newest is None or ahead_s <= CLOCK_DISAGREE_S:
            self.unsynced_since = None
            self._set(CaptureState.WAITING_FOR_FRAME, "hold still: waiting for a camera frame")
            return
        now = time.monotonic()
        self.unsynced_since = self.unsynced_since if self.unsynced_since is not None else now
        lidar_offset = self.recent[-1][1].clock_offset_s if self.recent else math.nan
        camera_offset = newest[0] - newest[1].panorama.device_time_s
        what = (f"the camera's frames are {ahead_s:.1f} s ahead of the LiDAR's sweeps on the host clock (host minus "
                f"device: camera {camera_offset:+.3f} s, LiDAR {lidar_offset:+.3f} s): one of the clocks is wrong")
        if now - self.unsynced_since > self.request.silence_timeout_s:
            raise SyncError(f"no synchronised pair for {now - self.unsynced_since:.1f} s: {what}; check the camera's "
                            "and the LiDAR's time sources (GPS/PPS, NTP) and restart the sensor whose clock jumped")
        self._set(CaptureState.NOT_SYNCHRONISED, f"not synchronised: {what}")

    # -- a pair --------------------------------------------------------------------------------------------
    def _take_pair(self, frame_t: float, frame: CameraFrame, window: tuple[float, float],
                   moved_m: float | None) -> None:
        recent = list(self.recent)
        spans = [(s.t_start, s.t_end) for s, _ in recent]
        chosen = [recent[i] for i in sweeps_for_frame(spans, frame_t, window, self.request.sweeps)]
        problem = self._sync_problem([sw for _, sw in chosen], window)
        if problem is not None:
            self.gate.reset()
            self._set(CaptureState.NOT_SYNCHRONISED, f"not taking a pair: {problem}; the still window restarts")
            return
        self._set(CaptureState.CAPTURING, f"capturing pair {self.done + 1}/{self.request.n}")
        cloud = fuse_sweeps([sw for _, sw in chosen])
        meta = self._meta(frame_t, frame, chosen, cloud, window, moved_m)
        index = max((int(p.name) for p in existing_pairs(self.out)), default=-1) + 1
        self._check_space(pair_bytes(frame), cloud)  # before anything is written, rig.yaml included
        self._ensure_rig(frame)
        path = self._write(index, frame, cloud, meta)
        now = time.monotonic()
        self.written.append(path)
        self.seconds.append(now - self._since)
        self._since = now
        self.done += 1
        if self.sim_end is not None and frame_t >= self.sim_end.last_stop_host_s:
            self.last_place_taken = True
        assert cloud.ring is not None  # fuse_sweeps always gives the ring
        self.reference = range_image(cloud.points_lidar, cloud.ring)
        self.gate.restart()
        self._set(CaptureState.CAPTURED, f"captured {self.done}/{self.request.n}")

    def _sync_problem(self, sweeps: list[Sweep], window: tuple[float, float]) -> str | None:
        """Why the sweeps cannot be shown to lie in the still window on the host clock, or None. Each sweep's
        own packets measure its host-minus-device offset; the window was built with its clock segment's."""
        for sweep in sweeps:
            lag = sweep.receive_offset_s - sweep.clock_offset_s
            if not abs(lag) <= SYNC_BOUND_S:
                return (f"a LiDAR sweep's packets arrived {lag:+.3f} s off its device time on the host clock (host "
                        f"minus device: measured {sweep.receive_offset_s:+.3f} s, used {sweep.clock_offset_s:+.3f} s; "
                        f"bound {SYNC_BOUND_S} s): the LiDAR's clock is not settled")
            if sweep.start.host < window[0] - SYNC_BOUND_S or sweep.end.host > window[1] + SYNC_BOUND_S:
                return (f"a LiDAR sweep was received at {sweep.start.host:.3f}-{sweep.end.host:.3f} s, outside the "
                        f"still window {window[0]:.3f}-{window[1]:.3f} s (host clock)")
        steps = [s for s in self._clock_steps() if s.host_s > window[0]]
        if steps:
            return f"the LiDAR's clock stepped {steps[-1].step_s:+.3f} s inside the still window"
        return None

    def _clock_steps(self) -> tuple[ClockStep, ...]:
        return () if self.stats is None else self.stats.clock_steps

    def _meta(self, frame_t: float, camera: CameraFrame, chosen: list[tuple[SweepSample, Sweep]], cloud: Cloud,
              window: tuple[float, float], moved_m: float | None) -> dict[str, Any]:
        frame = camera.panorama
        sweeps = [sw for _, sw in chosen]
        measured = min(s.receive_offset_s for s in sweeps)
        lidar_mid = 0.5 * (chosen[0][0].t_start + chosen[-1][0].t_end)
        return {
            "source": "captured",
            "software_version": software_version(),
            "camera": {
                "source": self.request.camera,
                "device_time_s": float(frame.device_time_s),
                "host_time_s": float(frame_t),
                "sequence_id": int(frame.sequence_id),
                "time_base": frame.time_base.value,
                "exposure": {"shutter_s": frame.exposure.shutter_s, "gain_db": frame.exposure.gain_db},
                **({} if camera.sensors is None else {"head": camera.sensors.head.summary(),
                                                      "head_source": camera.sensors.head.source.value}),
            },
            "lidar": self._lidar_meta(sweeps, cloud),
            "clock_offset_s": {"camera": float(frame_t - frame.device_time_s), "lidar": float(measured)},
            "sync": self._sync_meta(sweeps),
            "camera_minus_lidar_s": float(frame_t - lidar_mid),
            "still_window_host_s": [float(window[0]), float(window[1])],
            "motion": self._motion_meta(moved_m),
            "stream": {"packets_lost_total": self._packets_lost()},
        }

    def _lidar_meta(self, sweeps: list[Sweep], cloud: Cloud) -> dict[str, Any]:
        first, last = sweeps[0], sweeps[-1]
        return {
            "source": self.request.lidar,
            "device_time_s": [float(first.start.device), float(last.end.device)],
            "host_time_s": [float(first.start.host), float(last.end.host)],
            "sweeps_fused": len(sweeps),
            "points": len(cloud),
            "rpm": float(np.median([s.rpm for s in sweeps])),
            "packets": int(sum(s.packet_count for s in sweeps)),
            "packets_lost": int(sum(s.missing_packets for s in sweeps)),
            "sweep_coverage": [round(float(s.coverage), 4) for s in sweeps],
            "min_sweep_fraction": self.request.min_sweep_fraction,
            "pps": last.pps.name.lower() if last.pps is not None else None,
            "time_source": last.time_source.value,
        }

    def _sync_meta(self, sweeps: list[Sweep]) -> dict[str, Any]:
        """The LiDAR's host-minus-device offset as used (its clock segment's) and as measured on the fused
        sweeps' own packets, and every clock step seen so far in this capture."""
        return {
            "lidar_offset_used_s": float(sweeps[-1].clock_offset_s),
            "lidar_offset_measured_s": float(min(s.receive_offset_s for s in sweeps)),
            "lidar_receive_lag_s": float(max(s.receive_offset_s - s.clock_offset_s for s in sweeps)),
            "bound_s": SYNC_BOUND_S,
            "lidar_clock_steps": [{"host_time_s": float(s.host_s), "step_s": float(s.step_s), "seen": s.kind.value}
                                  for s in self._clock_steps()],
        }

    def _motion_meta(self, moved_m: float | None) -> dict[str, Any]:
        camera_change, camera_limit = self.gate.camera_change(), self.gate.camera_threshold_deg()
        limits = self.thresholds
        return {
            "still_seconds": self.request.still_seconds,
            "lidar_rotation_deg": float(self.gate.rotation_deg),
            "lidar_translation_m": float(self.gate.translation_m),
            "lidar_still_rotation_deg": limits.rotation_deg,
            "lidar_still_translation_m": limits.translation_m,
            "camera_change_deg": None if camera_change is None else float(camera_change),
            "camera_frames_in_window": len(self.gate.window_frames()),
            "camera_still_deg": None if camera_limit is None else float(camera_limit),
            "tolerance_deg": limits.tolerance_deg,
            "moved_since_previous_m": None if moved_m is None else float(moved_m),
            "min_move_m": self.request.min_move,
        }

    def _ensure_rig(self, frame: CameraFrame) -> None:
        """Write rig.yaml (and the simulator's ground truth) with the first pair; check it on a resumed one. Its
        camera is the panorama, or the head the frame's sensor images go with (rigd.capture.pair_files)."""
        camera = rig_camera(frame)
        rig_path = self.out / "rig.yaml"
        if rig_path.is_file():
            rig = RigConfig.from_yaml(read_yaml(rig_path), str(rig_path))
            difference = camera_difference(rig.camera, camera)
            if difference is not None:
                raise DatasetError(f"{rig_path}: {difference}: capture into a new dataset")
            return
        spec = self.sources.sim_spec
        sigma = self.settings.lidar_elevation_sigma_deg
        if sigma is None and spec is not None:
            sigma = 0.0  # the simulated beams are where the table says
        try:
            write_rig(self.out, RigConfig(camera, self.settings.lidar_model, self.settings.initial_guess,
                                          self.settings.prior, self.settings.tolerance, self.settings.search,
                                          self.settings.lidar_elevation_offset_deg, sigma))
            if spec is not None and not (self.out / "ground_truth.yaml").is_file():
                write_ground_truth(self.out, Transform.from_matrix(spec.T_camera_lidar.matrix))
        except DatasetError as exc:
            if _disk_full(exc):
                raise DiskFullError(f"{exc}: disk full before the first pair; free some space and rerun") from exc
            raise

    def _check_space(self, image_bytes: int, cloud: Cloud) -> None:
        needed = image_bytes + 20 * len(cloud) + (1 << 20)  # uncompressed images and cloud, and metadata
        try:
            free = shutil.disk_usage(self.out).free
        except OSError as exc:
            raise DatasetError(f"{self.out}: cannot read the free space ({exc.strerror})") from exc
        if free < 2 * needed:  # twice: the pair's temporary folder, and room left for what comes after it
            raise DiskFullError(f"{self.out}: {free / 1e6:.1f} MB free, a capture needs {2 * needed / 1e6:.1f} MB "
                                f"(twice a pair's {needed / 1e6:.1f} MB); free some space and rerun (the "
                                f"{self.done} pairs written are complete)")

    def _write(self, index: int, frame: CameraFrame, cloud: Cloud, meta: dict[str, Any]) -> Path:
        image, extras = pair_images(frame)
        try:
            return write_pair(self.out, index, image, cloud, meta, extras=extras)
        except DatasetError as exc:
            if _disk_full(exc):
                raise DiskFullError(f"{self.out}: disk full while writing pair {index:04d}; it was not written, the "
                                    f"{self.done} pairs before it are complete: free some space and rerun") from exc
            raise

    # -- sensors' health and status ------------------------------------------------------------------------
    def _lidar_silence(self, silent_s: float) -> str:
        """The error when no usable sweep came for ``silent_s``: what the LiDAR did send, and what to check."""
        describe, unusable = self.sources.lidar.describe, self.unusable
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
            return (f"the VLP-16 at {describe} sends packets ({self._packet_rate():.0f}/s) but its head does not turn "
                    f"({partial.rpm:.0f} rpm), no sweep for {silent_s:.1f} s: its motor is stopped or blocked; check "
                    "that nothing holds the head and the motor's rpm setting (web interface), then power-cycle it")
        if partial is not None:
            return (f"no complete VLP-16 sweep from {describe} for {silent_s:.1f} s: packets arrive with gaps of a "
                    f"turn or more ({self._packets_lost()} lost so far): check the network (deploy/network)")
        if self.stats is not None and self.stats.bad_packets:
            faults = ", ".join(f"{k.name} {v}" for k, v in self.stats.faults.items())
            return (f"no usable VLP-16 sweep from {describe} for {silent_s:.1f} s; bad packets: {faults} "
                    "(docs/vlp16.md, Validation)")
        return (f"no VLP-16 data from {describe} for {silent_s:.1f} s: check the sensor's power and cable, and "
                "that it sends to this host's address and port (deploy/network)")

    def _loss_error(self, sweep: Sweep, silent_s: float) -> str:
        return (f"the VLP-16 at {self.sources.lidar.describe} loses packets: no sweep with at least "
                f"{self.request.min_sweep_fraction:.0%} of a turn's packets for {silent_s:.1f} s (the latest held "
                f"{sweep.coverage:.0%}; {self._packets_lost()} packets lost so far): check its cable and switch, that "
                "nothing else floods its network, and the receive buffer (deploy/network); or accept more loss "
                "with --min-sweep-fraction")

    def _show_unusable(self, unusable: Unusable) -> None:
        """The status line while sweeps keep coming that cannot go into a pair (before the silence error)."""
        if unusable.use is SweepUse.LOSSY:
            self._set(CaptureState.UNUSABLE_LIDAR, f"the LiDAR's sweeps are incomplete: {unusable.sweep.coverage:.0%} "
                                                   f"of a turn's packets arrive, {self.request.min_sweep_fraction:.0%} "
                                                   "needed")
        elif unusable.use is SweepUse.BLIND:
            self._set(CaptureState.UNUSABLE_LIDAR, f"the LiDAR sees almost nothing: returns in {unusable.returns} "
                                                   f"of {RINGS * AZIMUTH_BINS} directions")

    def _silence_limit(self, any_data: bool) -> float:
        return self.request.silence_timeout_s if any_data else max(self.request.silence_timeout_s, STARTUP_S)

    def _check_camera(self) -> None:
        silence = self.sources.camera.seconds_since_frame()
        if silence is not None and silence[0] > max(self._silence_limit(silence[1]), self.sources.camera.frame_gap_s):
            check = ("its process is stopped or hung" if parse_camera(self.request.camera).kind is SourceKind.SIM
                     else "check the camera's power and USB 3 link (rigd camera info)")
            raise SensorSilenceError(f"no camera frame from {self.sources.camera.describe} for {silence[0]:.1f} s: "
                                     f"{check}")

    def _check_sim_end(self) -> None:
        """End a capture whose simulated rig can give no more pairs: it has stood at its last place longer than a
        stop lasts, or that place already has its pair, and the dataset is not complete."""
        end = self.sim_end
        if end is None or self.done >= self.request.n:
            return
        now = time.time()
        if self.last_place_taken or now > end.deadline_host_s:
            raise SimRigEndedError(end.message(now, self.done, len(self.written), self.out))

    def _packets_lost(self) -> int:
        return 0 if self.stats is None else int(self.stats.missing_packets + self.stats.overruns)

    def _count_packets(self, sweep: Sweep, now: float) -> None:
        start, end = sweep.start.device + sweep.clock_offset_s, sweep.end.device + sweep.clock_offset_s
        self.rates.append((start, end, sweep.packet_count))
        self._rate_at = now

    def _packet_rate(self) -> float:
        """Packets/s over the last second of data (the sensor's pace, also in a replay read faster than real
        time); 0 once no data has come for a second, so a stream that stopped does not show its last rate."""
        if not self.rates or time.monotonic() - self._rate_at > RATE_WINDOW_S:
            return 0.0
        latest = self.rates[-1][1]
        recent = [r for r in self.rates if r[1] >= latest - RATE_WINDOW_S]
        span = latest - recent[0][0]
        return sum(r[2] for r in recent) / span if span > 0 else 0.0

    def _set(self, state: CaptureState, message: str) -> None:
        # A new sync fault (a clock step, a pair refused) is an event: shown even when one was showing already.
        event = state is CaptureState.NOT_SYNCHRONISED and message != self.message
        changed = state is not self.state or state is CaptureState.CAPTURED or event
        self.state, self.message = state, message
        self._emit(force=changed or state is CaptureState.STARTING)

    def _emit(self, force: bool) -> None:
        now = time.monotonic()
        if self.progress is None or (not force and now - self._last_emit < STATUS_PERIOD_S):
            return
        self._last_emit = now
        self.progress(CaptureStatus(self.state.value, self.done, self.request.n, round(self.gate.still_for_s, 3),
                                    round(self._packet_rate(), 1), self._packets_lost(), self.message))


@dataclass(frozen=True)
class _SimRigEnd:
    """When the simulated rig a capture follows has given all the places it will: it reaches its last place at
    ``last_stop_host_s`` (UNIX s; drivers.sim.motion.Trajectory.stop_interval: stop ``i`` begins ``i`` legs
    after the rig's start) and stands there for good; after ``deadline_host_s`` no pair is to be had there."""

    source: str  # the option that names the rig, as given: "--lidar sim", "--lidar sim:FILE", "--camera sim:FILE"
    file: Path | None  # its sim rig file (None: the rig capture builds for --lidar sim)
    in_process: bool  # run by this capture (--lidar sim[:FILE]), not followed elsewhere (--camera sim:FILE)
    stops: int  # its places
    places: int  # of which the capture could use: from the one the rig was at or driving to when it began
    asked: int  # pairs the dataset should have (--n)
    wanted: int  # of which this capture was to add
    still_s: float
    move_s: float
    last_stop_host_s: float
    deadline_host_s: float

    @classmethod
    def of(cls, spec: MotionRigSpec | None, request: CaptureRequest, existing: int) -> _SimRigEnd | None:
        if spec is None or spec.start_host_s is None:  # a real rig: people move it on for as long as it takes
            return None
        lidar = parse_lidar(request.lidar)
        in_process = lidar.kind is LidarKind.SIM
        file = lidar.path if in_process else parse_camera(request.camera).path
        source = f"--lidar {request.lidar}" if in_process else f"--camera {request.camera}"
        leg_s = spec.still_s + spec.move_s
        last_stop = spec.start_host_s + (spec.stops - 1) * leg_s
        began = time.time()
        passed = min(max(math.floor((began - spec.start_host_s) / leg_s), 0), spec.stops - 1)  # legs already done
        stand_s = max(spec.still_s, request.still_seconds)  # the gate may need longer than the rig's stops
        return cls(source, file, in_process, spec.stops, spec.stops - passed, request.n, request.n - existing,
                   spec.still_s, spec.move_s, last_stop, max(last_stop, began) + stand_s + SIM_END_GRACE_S)

    def message(self, now: float, done: int, written: int, out: Path) -> str:
        stood_s = max(now - self.last_stop_host_s, 0.0)
        kept = f"{written} written by this run, complete" if written else "none written by this run"
        head = (f"the simulated rig ({self.source}) has stopped at all its {self.stops} places and stands at the "
                f"last one for good ({stood_s:.1f} s so far): {out} has {done} of the {self.asked} pairs asked "
                f"({kept})")
        if self.places < self.wanted:
            where = "its sim rig file" if self.file is None else self.file
            more = f"{'give it' if self.in_process else 'restart it with'} more places (stops in {where})"
            return f"{head}; it has too few places for the {self.wanted} pairs missing: {more}, or ask for fewer (--n)"
        if self.file is None:
            fix = ("lengthen its stops with a larger --still-seconds (it stands --still-seconds + "
                   f"{SIM_STOP_MARGIN_S:g} s at each place)")
        elif self.in_process:
            fix = (f"lengthen its stops (still_s) or shrink its panorama (width, height) in {self.file} (for `rigd "
                   "demo`: a smaller --width)")
        else:
            fix = f"restart it with longer stops (still_s) or a smaller panorama (width, height) in {self.file}"
        rerun = "; rerunning the same command adds the missing pairs at new places" if self.file is None else ""
        missed = max(self.places - written, 0)
        return (f"{head}; {missed} of its stops gave no pair: the simulated camera renders too slowly for this "
                f"machine's load (each stop's view must be rendered within a leg: {self.still_s:g} s "
                f"standing + {self.move_s:g} s driving); close other jobs, or {fix}{rerun}")


def _reference_image(pair_dir: Path) -> np.ndarray | None:
    """The range image of a written pair's cloud: a resumed capture must move on from it too."""
    cloud = read_pcd(pair_dir / "cloud.pcd")
    return None if cloud.ring is None else range_image(cloud.points_lidar, cloud.ring)
