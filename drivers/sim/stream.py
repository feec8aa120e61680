"""The simulated rig with motion running in real time: a VLP-16 that sends real UDP packets, and a camera.

:class:`LidarEmitter` scans one VLP-16 turn at a time at the rig's pose, encodes it into data packets with
``drivers.vlp16``'s encoder and sends them with its paced sender at the sensor's own rate (754 packets/s,
one turn per 1800 firing sequences = 99.53 ms), plus one position packet per turn (PPS absent, as a
VLP-16 without GPS reports). Its device clock is the host clock (only microseconds past the hour are in
the packets), as on a sensor synchronised by PTP or GPS. A turn is scanned from one pose, the rig's pose
at the middle of the turn: there is no motion distortion within a turn (0.1 s). Turns are scanned ahead in a
thread; one that would leave more than a turn late (a busy machine) is dropped, as a real sensor's packets
are lost but never sent much later than their time (that would look like a clock running behind:
drivers.vlp16.clock); one less late leaves at once and the sender catches up within the turn.

:class:`CameraStream` renders the panorama seen at the rig's pose at the instant the frame starts, as
often as ``frame_period_s`` allows; while the rig stands still the view is rendered once and each frame
only adds its own read noise, so a still rig streams at that rate as a real camera does (rendering a moving
rig is slower than a real camera: see MotionRigSpec). A rig with ``sensor_width`` renders the six raw images of
its Ladybug-like head instead (drivers.ladybug5.sim) and stitches the panorama from them, as the SDK source
gives a real camera's frames. Frames
carry their exposure instant on the host clock and the camera's own clock (seconds since the rig
started).

The trajectory is known in advance, so a thread renders the next stop's view before the rig gets there (one
render at a time, begun about two render times ahead), and a moving frame that would still be rendering when
the rig stops is skipped: a stop's first frame is then exposed as the stop begins and arrives within a frame
period, as a real camera's does, not one or two renders (seconds) later, which kept the capture waiting. A
disturbed rig never stands quite still, so nothing is rendered ahead for it.

Both follow one :class:`drivers.sim.motion.MotionRigSpec`; its ``start_host_s`` is time 0 of the
trajectory, so a LiDAR emitter in one process and a camera stream in another simulate the same rig.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import queue
import signal
import threading
import time
from collections import deque
from collections.abc import Generator, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.rig import RigCameras, scaled_ladybug5_rig
from drivers.ladybug5.sim import pixel_rays_optical, sensor_displays
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher
from drivers.sim.camera import panorama_display, quantise
from drivers.sim.errors import SimError
from drivers.sim.lidar import FIRINGS_PER_TURN, BeamReturns, LidarConfig, beam_returns, scan
from drivers.sim.motion import MotionRigSpec, Trajectory
from drivers.sim.pose import Pose
from drivers.vlp16 import PpsStatus, encode_data_packets, encode_position_packet, send_datagrams
from drivers.vlp16.layout import HOUR_US, SEQUENCE_US

TURN_S = FIRINGS_PER_TURN * SEQUENCE_US * 1e-6  # one simulated turn: 1800 firing sequences
FIRING_AZIMUTH_DEG = 360.0 * np.arange(FIRINGS_PER_TURN) / FIRINGS_PER_TURN  # as drivers.sim.lidar fires
START_LEAD_S = 0.2  # time 0 is set this far ahead, so the first turn is ready when it is due
_SCAN_ALLOWANCE_S = 0.2  # time to scan and encode a turn before it is due
_TURNS_AHEAD = 2  # turns scanned ahead of the sender
# A turn whose first packet would leave more than a turn late is dropped. Less late, the sender catches up
# within the turn (its later packets leave on time), as a sensor's packets delayed in a switch would.
_LATE_S = TURN_S
_STREAM_LIDAR, _STREAM_CAMERA = 7, 11  # random streams of the moving rig's noise
# The next stop's view is begun this many render times before the stop (as the rig leaves the last one at the
# latest): a busy machine renders slower than the last renders took. A render time is the longest of the last few.
_AHEAD_RENDERS = 2.0
_RENDERS_TIMED = 3
_AHEAD_POLL_S = 0.05  # how often the camera's threads look again while they wait for the other one


def _require_started(spec: MotionRigSpec) -> float:
    if spec.start_host_s is None:
        raise SimError("the moving sim rig has no start time (start the LiDAR emitter first)")
    return spec.start_host_s


class LidarEmitter:
    """Send the moving rig's VLP-16 stream to ``host``: data packets to ``data_port``, position packets to
    ``position_port`` (None: none sent). Use as a context manager; ``spec`` holds the start time."""

    def __init__(self, spec: MotionRigSpec, host: str, data_port: int, position_port: int | None = None) -> None:
        self.scene, self.trajectory = spec.build()
        self.spec = spec
        self.host = host
        self.data_port = data_port
        self.position_port = position_port
        self.lidar = LidarConfig(range_noise_m=spec.range_noise_m)
        self._returns: tuple[bytes, BeamReturns] | None = None  # the last pose scanned and what its beams hit
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> LidarEmitter:
        if self._thread is not None:
            raise SimError("LiDAR emitter: start() may be called once")
        if self.spec.start_host_s is None:
            self.spec = self.spec.started(time.time() + START_LEAD_S)
        self._thread = threading.Thread(target=self._run, name="sim-vlp16-emitter", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()

    def __enter__(self) -> LidarEmitter:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _run(self) -> None:
        ahead: queue.Queue[tuple[int, list[tuple[float, int, bytes]]]] = queue.Queue(maxsize=_TURNS_AHEAD)
        scanner = threading.Thread(target=self._scan_ahead, args=(ahead,), name="sim-vlp16-scanner", daemon=True)
        scanner.start()
        try:
            send_datagrams(self._datagrams(ahead), self.host, on_host_clock=True)
        finally:
            self._stop.set()
            scanner.join()

    def _due_turn(self) -> int:
        """The first turn that a scan started now can still send on time."""
        start = _require_started(self.spec)
        return max(0, math.ceil((time.time() + _SCAN_ALLOWANCE_S - start) / TURN_S))

    def _scan_ahead(self, ahead: queue.Queue[tuple[int, list[tuple[float, int, bytes]]]]) -> None:
        """Scan turns ahead of the sender. A scan that falls behind (a busy machine) skips to a turn it can
        still deliver on time: a real sensor loses packets, it never sends them late."""
        start = _require_started(self.spec)
        turn = self._due_turn()
        while not self._stop.is_set():
            if time.time() > start + turn * TURN_S + _LATE_S:  # too late already: skip to what can be on time
                turn = self._due_turn()
            item = (turn, self.turn_datagrams(turn))
            while not self._stop.is_set():
                with contextlib.suppress(queue.Full):
                    ahead.put(item, timeout=0.1)
                    break
            turn += 1

    def _datagrams(self, ahead: queue.Queue[tuple[int, list[tuple[float, int, bytes]]]]
                   ) -> Iterator[tuple[float, int, bytes]]:
        start = _require_started(self.spec)
        # A sensor started before anyone listens has been turning all along: begin with the first turn not
        # yet due (waiting for it here, where close() can interrupt). Each datagram leaves at its own host time;
        # a turn that would leave late is dropped (lost), as a sensor's packets are never late.
        first = True
        while not self._stop.is_set():
            try:
                turn, datagrams = ahead.get(timeout=0.1)
            except queue.Empty:
                continue
            if time.time() > start + turn * TURN_S + _LATE_S:
                continue
            if first:
                self._stop.wait(max(0.0, start + turn * TURN_S - time.time()))
                first = False
            yield from datagrams

    def turn_datagrams(self, turn: int) -> list[tuple[float, int, bytes]]:
        """The datagrams (host send time s, port, payload) of turn ``turn``: one position packet, 75 data packets."""
        start = _require_started(self.spec)
        t_turn = turn * TURN_S
        pose_lidar = self.trajectory.pose_at(t_turn + TURN_S / 2).compose(self.spec.T_camera_lidar)
        rng = np.random.default_rng([self.spec.seed, turn, _STREAM_LIDAR])
        key = pose_lidar.matrix.tobytes()
        if self._returns is None or self._returns[0] != key:  # standing still: the same surfaces, new noise
            self._returns = key, beam_returns(self.scene, pose_lidar, self.lidar)
        sweep = scan(self.scene, pose_lidar, rng, self.lidar, self._returns[1])
        packets = encode_data_packets(sweep.ranges_m, sweep.reflectivity, FIRING_AZIMUTH_DEG, start + t_turn)
        out: list[tuple[float, int, bytes]] = []
        if self.position_port is not None:
            stamp_us = round((start + t_turn) * 1e6) % HOUR_US
            out.append((start + t_turn, self.position_port, encode_position_packet(stamp_us, PpsStatus.ABSENT)))
        out.extend((float(t), self.data_port, p.tobytes()) for t, p in zip(packets.time_s, packets.payloads,
                                                                              strict=True))
        return out


@dataclass(frozen=True)
class SimFrame:
    """A rendered panorama ``image`` (H,W) uint8 grey, exposed at ``exposure_host_s`` (UNIX s) =
    ``device_time_s`` (the camera's clock: s since the rig started) + the rig's start time. ``sensors``: a
    head rig's six raw sensor images (H_s, W_s) uint8 grey, in the head's order (the panorama is stitched from
    them); empty for a panorama rig."""

    image: NDArray[np.uint8]
    exposure_host_s: float
    device_time_s: float
    sequence: int
    sensors: tuple[NDArray[np.uint8], ...] = ()


def sim_head_rig(spec: MotionRigSpec) -> RigCameras | None:
    """The head a rig with ``sensor_width`` renders (None: a panorama rig)."""
    return None if spec.sensor_width is None else scaled_ladybug5_rig(spec.sensor_width)


def next_stop(trajectory: Trajectory, t: float) -> tuple[float, Pose] | None:
    """The start (s) and pose of the first stop that begins after time ``t`` s; None once the last stop has
    begun, or when a disturbance moves the rig all the time (its pose at a stop changes: no view lasts)."""
    if trajectory.disturbance.active:
        return None
    place = max(0, math.floor(t / trajectory.leg_s) + 1)
    if place >= len(trajectory.places):
        return None
    start, _ = trajectory.stop_interval(place)
    return start, trajectory.pose_at(start + trajectory.still_s / 2)  # away from the stop's ends


class CameraStream:
    """The moving rig's panorama camera; ``frames()`` renders until ``close()`` (from any thread)."""

    def __init__(self, spec: MotionRigSpec, stop: Any = None) -> None:
        """``stop``: what ends ``frames()`` (``is_set()``, ``wait(timeout)``: an event, a child's stop flag);
        by default its own."""
        self.start_host_s = _require_started(spec)
        self.spec = spec
        self.scene, self.trajectory = spec.build()
        self._stop = stop if stop is not None else threading.Event()
        # At most two views, each keyed by its pose's bytes: the last pose frames() used, and the next stop's
        # (rendered ahead). _lock guards them, the pose being rendered ahead and whether frames() is rendering.
        self._view: tuple[bytes, list[NDArray[np.float64]]] | None = None
        self._next: tuple[bytes, list[NDArray[np.float64]]] | None = None
        self._ahead_key: bytes | None = None
        self._rendering = False
        self._lock = threading.Condition()
        self._render_s: deque[float] = deque(maxlen=_RENDERS_TIMED)
        self._ahead = next_stop(self.trajectory, 0.0) is not None  # a later stop where the rig stands still
        self.rig = sim_head_rig(spec)
        self._rays = [] if self.rig is None else [pixel_rays_optical(c) for c in self.rig.cameras]
        self._stitcher = None if self.rig is None else Stitcher(self.rig, PanoramaSpec(spec.width, spec.height))

    def frames(self) -> Iterator[SimFrame]:
        done = threading.Event()  # the thread rendering ahead ends with this generator, or at the stop flag
        if self._ahead:
            threading.Thread(target=self._render_ahead, args=(done,), name="sim-camera-ahead", daemon=True).start()
        sequence = 0
        try:
            while not self._stop.is_set():
                now = time.time()
                if now < self.start_host_s:
                    self._stop.wait(self.start_host_s - now)
                    continue
                t = now - self.start_host_s
                hold = self._hold_s(t) if self._ahead else 0.0
                if hold > 0:
                    self._stop.wait(hold)
                    continue
                rng = np.random.default_rng([self.spec.seed, sequence, _STREAM_CAMERA])
                yield self._frame(self._display(t), rng, now, t, sequence)
                sequence += 1
                self._stop.wait(max(0.0, now + self.spec.frame_period_s - time.time()))
        finally:
            done.set()

    def _hold_s(self, t: float) -> float:
        """How long frames() waits before a frame at time ``t`` s: none at a stop. While the rig drives, until
        the next stop's view is rendered (one render at a time: the stop's frame matters more than a moving
        one), then until the stop when a moving frame begun now would still be rendering as the rig stops."""
        if self.trajectory.stop_index(t) is not None:
            return 0.0
        stop = next_stop(self.trajectory, t)
        if stop is None:
            return 0.0
        start, pose = stop
        left = max(start - t, 1e-3)  # never 0: the stop is ahead until stop_index says otherwise
        with self._lock:
            ready = self._cached(pose.matrix.tobytes()) is not None
        if not ready:
            return min(left, _AHEAD_POLL_S)
        return left if t + self._render_estimate() >= start else 0.0

    def _frame(self, displays: list[NDArray[np.float64]], rng: np.random.Generator, host_s: float, t: float,
               sequence: int) -> SimFrame:
        """The frame of ``displays`` with its read noise: the panorama, or the sensors and their stitch."""
        noise = self.spec.image_noise_grey
        if self._stitcher is None:
            return SimFrame(quantise(displays[0], rng, noise), host_s, t, sequence)
        sensors = tuple(quantise(d, rng, noise) for d in displays)
        return SimFrame(self._stitcher.stitch(list(sensors)), host_s, t, sequence, sensors)

    def _display(self, t: float) -> list[NDArray[np.float64]]:
        """The noise-free view at time ``t`` s (the panorama, or each sensor's image): rendered again only when
        the rig has moved, and not at a stop rendered ahead. A real camera streams at 10 Hz whatever it sees; a
        render takes seconds, so without this a still rig waited that long for each frame (and a busy machine's
        capture missed still windows)."""
        pose = self.trajectory.pose_at(t)
        key = pose.matrix.tobytes()
        with self._lock:
            while self._ahead_key == key:  # being rendered ahead: wait for it rather than render it twice
                self._lock.wait(_AHEAD_POLL_S)
            if self._next is not None and self._next[0] == key:  # the stop rendered ahead: now the current view
                self._view, self._next = self._next, None
            if self._view is not None and self._view[0] == key:
                return self._view[1]
            self._rendering = True
        views = None
        try:
            views = self._render(pose)
        finally:
            with self._lock:
                self._rendering = False
                if views is not None:
                    self._view = key, views
        return views

    def _render(self, pose: Pose) -> list[NDArray[np.float64]]:
        """The noise-free view(s) at ``pose``, timed (the render-time estimate)."""
        started = time.monotonic()
        views = ([panorama_display(self.scene, pose, self.spec.width, self.spec.height)] if self.rig is None
                 else sensor_displays(self.scene, pose, self.rig.cameras, self._rays))
        with self._lock:
            self._render_s.append(time.monotonic() - started)
        return views

    def _render_estimate(self) -> float:
        with self._lock:
            return max(self._render_s, default=0.0)

    def _cached(self, key: bytes) -> list[NDArray[np.float64]] | None:
        """The view(s) of the pose ``key`` if either cached view is of it (call with _lock held)."""
        for view in (self._view, self._next):
            if view is not None and view[0] == key:
                return view[1]
        return None

    def _render_ahead(self, done: threading.Event) -> None:
        """Render each stop's view before the rig gets there, into ``_next``: from ``_AHEAD_RENDERS`` render
        times before the stop (as the rig leaves the last one at the latest), never while frames() renders or
        still lacks the view of the stop the rig stands at (one render at a time). Ends once the last stop has
        begun, or at the stop flag or ``done``, looked at between renders."""
        while not (done.is_set() or self._stop.is_set()):
            t = time.time() - self.start_host_s
            stop = next_stop(self.trajectory, t)
            if stop is None:
                return
            start, pose = stop
            key = pose.matrix.tobytes()
            begin = start - max(self.trajectory.move_s, _AHEAD_RENDERS * self._render_estimate())
            here = None if self.trajectory.stop_index(t) is None else self.trajectory.pose_at(t).matrix.tobytes()
            with self._lock:
                idle = not self._rendering and (here is None or self._cached(here) is not None)
                due = t >= begin and idle and self._cached(key) is None
                if due:
                    self._ahead_key = key
            if not due:
                self._stop.wait(_AHEAD_POLL_S)
                continue
            views = None
            try:
                views = self._render(pose)
            finally:
                with self._lock:
                    if views is not None:
                        self._next = key, views
                    self._ahead_key = None
                    self._lock.notify_all()

    def close(self) -> None:
        self._stop.set()


# -- the simulated sensors as separate processes ------------------------------------------------------------
# A real rig's sensors run whatever the capturing program does; in one Python process the simulator's
# rendering and ray casting would compete with the capture for the interpreter lock and skew both.

_SPAWN = multiprocessing.get_context("spawn")  # safe with threads in the parent (the capture's feeds, a server)
_GRACE_S = 2.0  # for a child to see its stop flag (a LiDAR turn, not a render: an unfinished frame is not wanted)
_KILL_S = 2.0  # for a terminated or killed child to be gone
_DRAIN_S = 1.0  # reading what a stopping camera child still sends
_STOP_POLL_S = 0.05


class _StopFlag:
    """A stop request that children poll. Not a multiprocessing Event: its set() waits until every process
    sleeping in wait() has woken, which a stopped (SIGSTOP) or hung child never does; and its lock, held by a
    child stopped inside is_set(), would block the parent too. A lock-free shared byte blocks no one."""

    def __init__(self) -> None:
        self._flag = _SPAWN.RawValue("b", 0)

    def set(self) -> None:
        self._flag.value = 1

    def is_set(self) -> bool:
        return bool(self._flag.value)

    def wait(self, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not self.is_set():
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            time.sleep(min(left, _STOP_POLL_S))
        return True


def _lidar_child(spec: MotionRigSpec, host: str, data_port: int, position_port: int | None, stop: _StopFlag,
                 parent: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is for the capture, which stops its sensors itself
    with LidarEmitter(spec, host, data_port, position_port):
        while not stop.wait(0.5) and os.getppid() == parent:  # a killed parent leaves no orphan sensor
            pass


def _camera_child(spec: MotionRigSpec, conn: Any, stop: _StopFlag, parent: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with contextlib.suppress(BrokenPipeError):  # the reader has gone
        for frame in CameraStream(spec, stop).frames():
            if os.getppid() != parent:
                return
            conn.send(frame)


class LidarProcess:
    """:class:`LidarEmitter` in a child process; ``spec`` must be started (``start_host_s`` set)."""

    def __init__(self, spec: MotionRigSpec, host: str, data_port: int, position_port: int | None = None) -> None:
        _require_started(spec)
        self.spec = spec
        self._stop = _StopFlag()
        args = (spec, host, data_port, position_port, self._stop, os.getpid())
        self._process = _SPAWN.Process(target=_lidar_child, args=args, name="sim-vlp16", daemon=True)

    def start(self) -> LidarProcess:
        self._process.start()
        return self

    def close(self) -> None:
        _stop_child(self._process, self._stop)

    def __enter__(self) -> LidarProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()


class CameraProcess:
    """:class:`CameraStream` in a child process; ``frames()`` yields what it renders until ``close()``."""

    def __init__(self, spec: MotionRigSpec) -> None:
        _require_started(spec)
        self.spec = spec
        self._stop = _StopFlag()
        self._closed = threading.Event()
        self._reading = False
        self._receive, send = _SPAWN.Pipe(duplex=False)
        args = (spec, send, self._stop, os.getpid())
        self._process = _SPAWN.Process(target=_camera_child, args=args, name="sim-camera", daemon=True)
        self._process.start()
        send.close()  # the child holds the sending end

    def frames(self) -> Generator[SimFrame, None, None]:
        """Frames as the child renders them; call from one thread (the pipe's only reader)."""
        self._reading = True
        try:
            while not self._closed.is_set():
                if self._receive.poll(0.1):
                    try:
                        yield self._receive.recv()
                    except EOFError:
                        break
                elif not self._process.is_alive():
                    break
            if not self._closed.is_set():
                raise SimError(f"the simulated camera process ended (exit code {self._process.exitcode})")
        finally:
            self._stop.set()
            # A child blocked sending a frame finishes once it is read; one that sends nothing (stopped, hung)
            # is not waited for: close() ends it, and the closed pipe ends a send.
            deadline = time.monotonic() + _DRAIN_S
            with contextlib.suppress(EOFError, OSError):
                while self._process.is_alive() and time.monotonic() < deadline:
                    if self._receive.poll(0.1):
                        self._receive.recv()
            self._receive.close()

    def close(self) -> None:
        self._closed.set()
        _stop_child(self._process, self._stop)
        if not self._reading:
            self._receive.close()


def _stop_child(process: Any, stop: _StopFlag) -> None:
    """Ask the child to stop, then end it: it holds nothing worth saving, and exit must never hang on it."""
    stop.set()
    if process.pid is None:
        return
    process.join(_GRACE_S)
    if process.is_alive():  # stuck: blocked sending a frame nobody reads, inside a long render, or stopped
        process.terminate()
        with contextlib.suppress(ProcessLookupError):
            os.kill(process.pid, signal.SIGCONT)  # a stopped (SIGSTOP) child acts on SIGTERM once continued
        process.join(_KILL_S)
    if process.is_alive():
        process.kill()
        process.join(_KILL_S)
