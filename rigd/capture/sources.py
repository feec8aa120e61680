"""Sensor feeds for the capture loop: the LiDAR's sweeps and the camera's frames, each from its own thread.

A camera frame is a panorama and, from a source that has them (the SDK, the simulated head, a replay directory of
six-image frames), the raw sensor images it was stitched from with their head calibration (:class:`CameraFrame`).

A live source (UDP, the SDK, the simulated rig) is read by a thread that hands items over through a
bounded buffer, so the capture loop never blocks on a sensor and can check its stop flag and the sensors'
silence. Recorded sources are read as fast as the loop consumes them: a pcap through the same thread
(the bounded queue holds it back), a camera replay directory pulled up to the LiDAR's time (both were
recorded on one host clock).
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol, TypeVar, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.errors import DriverError
from drivers.ladybug5 import (
    DirectoryFrameSource,
    Exposure,
    HeadCalibration,
    HeadCalibrationError,
    HeadPolicy,
    HeadSource,
    LadybugLibrary,
    PanoramaFrame,
    PanoramaSpec,
    SdkCamera,
    SdkFrameSource,
    SdkLayout,
    SensorFrame,
    TimeBase,
    load_head,
)
from drivers.ladybug5.sim import simulated_head
from drivers.sim.motion import MotionRigSpec, load_spec
from drivers.sim.stream import START_LEAD_S, CameraProcess, LidarProcess, SimFrame, sim_head_rig
from drivers.vlp16 import PcapReplay, Ports, StreamStats, Sweep, UdpReceiver, Vlp16Config
from rigd.capture.config import RigSettings
from rigd.capture.errors import CaptureError, ConfigError, SourceEndedError, SourceSpecError
from rigd.capture.specs import CameraKind, CameraSpec, LidarKind, LidarSpec

_Item = TypeVar("_Item")
_POLL_S = 0.1
_CAMERA_BUFFER = 8  # frames kept for the loop (the newest win): 0.5 s of a 15 fps camera
_JOIN_S = 30.0  # a simulated frame may take a few seconds to finish rendering
# The simulated camera renders a 1024x512 frame in 1.5-4 s on a busy 2-core machine (2048x1024: 4x that).
SIM_FRAME_GAP_S = 20.0


@dataclass(frozen=True)
class SweepItem:
    """A sweep and the LiDAR source's statistics right after it (taken in the thread that decodes)."""

    sweep: Sweep
    stats: StreamStats


class _ThreadedFeed:
    """A source read by its own thread (``run``, named ``thread``); ``close`` stops it and calls ``on_close``."""

    def __init__(self, describe: str, on_close: Callable[[], None] | None, thread: str,
                 run: Callable[[], None]) -> None:
        self.describe = describe
        self._on_close = on_close
        self._closed = threading.Event()
        self._ended = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=run, name=thread, daemon=True)

    def close(self) -> None:
        self._closed.set()
        if self._on_close is not None:
            self._on_close()
        if self._thread.is_alive():
            self._thread.join(_JOIN_S)


class LidarFeed(_ThreadedFeed):
    """Iterates ``sweeps()`` in a thread; :meth:`get` hands the sweeps over. ``describe`` names the source."""

    def __init__(self, describe: str, sweeps: Callable[[], Iterable[Sweep]], stats: Callable[[], StreamStats],
                 on_close: Callable[[], None] | None = None, queue_sweeps: int = 50) -> None:
        super().__init__(describe, on_close, "capture-lidar", self._run)
        self._sweeps = sweeps
        self._stats = stats
        self._queue: queue.Queue[SweepItem] = queue.Queue(maxsize=queue_sweeps)

    def start(self) -> LidarFeed:
        self._thread.start()
        return self

    def _run(self) -> None:
        try:
            for sweep in self._sweeps():
                item = SweepItem(sweep, self._stats())
                while not self._closed.is_set():
                    with contextlib.suppress(queue.Full):
                        self._queue.put(item, timeout=_POLL_S)
                        break
                if self._closed.is_set():
                    return
        except DriverError as exc:  # a bad file, a failed socket: raised again in the capture loop
            self._error = exc
        finally:
            self._ended.set()

    def get(self, timeout_s: float) -> SweepItem | None:
        """The next sweep, or None after ``timeout_s``; raises what stopped the source."""
        try:
            return self._queue.get(timeout=timeout_s)
        except queue.Empty:
            if self._error is not None:
                raise self._error from None
            if self._ended.is_set() and self._queue.empty():
                raise SourceEndedError(f"LiDAR source {self.describe} ended") from None
            return None


@dataclass(frozen=True)
class CameraFrame:
    """A frame as capture takes it: the ``panorama`` (the stillness check, a panorama dataset's image, for people
    in a head dataset) and ``sensors``, the raw sensor images it was stitched from with their head calibration,
    from a source that has them (a head dataset's images; None: a panorama source)."""

    panorama: PanoramaFrame
    sensors: SensorFrame | None = None


class CameraFeed(Protocol):
    describe: str
    frame_gap_s: float  # the longest normal gap between two frames; silence shorter than this is no error

    def poll(self, until_host_s: float) -> list[CameraFrame]:
        """Frames received since the last poll (recorded sources: those up to ``until_host_s``)."""
        ...

    def seconds_since_frame(self) -> tuple[float, bool] | None:
        """Live camera: wall-clock seconds since the last frame (or the start) and whether any frame came;
        None for a recorded one."""
        ...

    def close(self) -> None: ...


class ThreadedCameraFeed(_ThreadedFeed):
    """A live camera: ``frames()`` iterated in a thread; the newest frames are kept for :meth:`poll`."""

    def __init__(self, describe: str, frames: Callable[[], Iterator[CameraFrame]],
                 on_close: Callable[[], None] | None = None, frame_gap_s: float = 0.0) -> None:
        super().__init__(describe, on_close, "capture-camera", self._run)
        self.frame_gap_s = frame_gap_s
        self._frames = frames
        self._buffer: deque[CameraFrame] = deque(maxlen=_CAMERA_BUFFER)
        self._lock = threading.Lock()
        self._last = time.monotonic()
        self._frames_seen = False

    def start(self) -> ThreadedCameraFeed:
        self._last = time.monotonic()
        self._thread.start()
        return self

    def _run(self) -> None:
        stream = self._frames()
        try:
            for frame in stream:
                if self._closed.is_set():
                    return
                with self._lock:
                    self._buffer.append(frame)
                    self._last = time.monotonic()
                    self._frames_seen = True
        except DriverError as exc:
            self._error = exc
        finally:
            _close(stream)  # a generator holding the SDK camera releases it here, in its own thread
            self._ended.set()

    def poll(self, until_host_s: float) -> list[CameraFrame]:
        with self._lock:
            frames = list(self._buffer)
            self._buffer.clear()
        if not frames:
            if self._error is not None:
                raise self._error
            if self._ended.is_set() and not self._closed.is_set():
                raise SourceEndedError(f"camera source {self.describe} ended")
        return frames

    def seconds_since_frame(self) -> tuple[float, bool] | None:
        with self._lock:
            return time.monotonic() - self._last, self._frames_seen


class PulledCameraFeed:
    """A recorded camera: frames are read up to the LiDAR's host time, so the two replays stay in step."""

    def __init__(self, describe: str, frames: Iterator[CameraFrame]) -> None:
        self.describe = describe
        self.frame_gap_s = 0.0
        self._frames = frames
        self._pending: CameraFrame | None = None
        self._ended = False

    def poll(self, until_host_s: float) -> list[CameraFrame]:
        if self._ended:
            raise SourceEndedError(f"camera source {self.describe} has no more frames")
        out: list[CameraFrame] = []
        while True:
            if self._pending is None:
                self._pending = next(self._frames, None)
                if self._pending is None:
                    self._ended = True
                    return out
            if frame_time(self._pending.panorama, self.describe) > until_host_s:
                return out
            out.append(self._pending)
            self._pending = None

    def seconds_since_frame(self) -> tuple[float, bool] | None:
        return None

    def close(self) -> None:
        _close(self._frames)


def _close(stream: object) -> None:
    """Close ``stream`` if it can be closed (a generator holding a camera releases it)."""
    close = getattr(stream, "close", None)
    if close is not None:
        close()


def frame_time(frame: PanoramaFrame, describe: str) -> float:
    """The frame's exposure on the host clock; capture cannot place a frame without it."""
    if frame.host_time_s is None:
        raise CaptureError(f"camera source {describe}: frame {frame.sequence_id} has no host time; capture "
                           "needs it to match frames with LiDAR sweeps (timestamps.csv column host_time_s)")
    return frame.host_time_s


def _bgr(grey: NDArray[np.uint8]) -> NDArray[np.uint8]:
    return cast(NDArray[np.uint8], cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR))


def sim_frame(frame: SimFrame, head: HeadCalibration | None) -> CameraFrame:
    """A simulated frame as the Ladybug5 sources give it: BGR, camera clock and host time; with the six sensor
    images and ``head`` (the simulated head) when the rig renders them."""
    times = (frame.device_time_s, frame.exposure_host_s, frame.sequence, Exposure(), TimeBase.CAMERA)
    panorama = PanoramaFrame(_bgr(frame.image), *times)
    if head is None or not frame.sensors:
        return CameraFrame(panorama)
    return CameraFrame(panorama, SensorFrame(tuple(_bgr(s) for s in frame.sensors), head, *times))


@dataclass
class Sources:
    """The open feeds; ``sim_spec`` is the simulated rig the camera follows (None for a real camera)."""

    lidar: LidarFeed
    camera: CameraFeed
    sim_spec: MotionRigSpec | None


def open_sources(stack: contextlib.ExitStack, lidar: LidarSpec, camera: CameraSpec, settings: RigSettings,
                 sim_default: MotionRigSpec, places_done: int, *, nominal_head: bool = False) -> Sources:
    """Start both feeds; everything started is closed when ``stack`` closes (also after an error).

    ``sim_default`` is the rig simulated here for ``--lidar sim`` without a file. A rig simulated here
    starts ``places_done`` places further on, so a resumed capture does not go back to places it has.
    ``nominal_head``: the SDK camera may run on rigd's nominal head when the settings name no head calibration
    (else that is refused: :func:`sdk_head`).
    """
    if lidar.kind is LidarKind.SIM:
        if camera.kind is not CameraKind.SIM or camera.path not in (None, lidar.path):
            raise SourceSpecError(f"--lidar {lidar}: the simulated rig's LiDAR goes with its own camera: "
                                  "use --camera sim")
        spec = load_spec(lidar.path) if lidar.path is not None else sim_default
        return _sim_rig(stack, replace(spec, first_place=spec.first_place + places_done, start_host_s=None))
    feed = _lidar_feed(stack, lidar)
    if camera.kind is CameraKind.SIM:
        if camera.path is None:
            raise SourceSpecError("--camera sim follows the rig simulated in this process (--lidar sim); to follow "
                                  "a simulated rig emitting elsewhere give its file: --camera sim:FILE")
        spec = load_spec(camera.path)
        if spec.start_host_s is None:
            raise SourceSpecError(f"--camera {camera}: {camera.path} has no start_host_s: it is not the file of a "
                                  "running simulated rig")
        return Sources(feed, _sim_camera(stack, str(camera), spec), spec)
    if camera.kind is CameraKind.REPLAY:
        assert camera.path is not None
        pulled = PulledCameraFeed(str(camera), _replay_frames(camera.path, settings, nominal_head=nominal_head))
        stack.callback(pulled.close)
        return Sources(feed, pulled, None)
    return Sources(feed, _start_camera(stack, _sdk_feed(settings, nominal_head=nominal_head)), None)


def _replay_frames(directory: Path, settings: RigSettings, *, nominal_head: bool) -> Iterator[CameraFrame]:
    """A replay directory's frames: panoramas, or six-image frames stitched at the rig file's panorama size with the
    head the live camera's frames would go with (:func:`sdk_head`; a head file, as no camera is there to read the
    factory head from), each with its sensor images: the head dataset's, as from the live camera."""
    head = sdk_head(settings, nominal_head=nominal_head)
    spec = PanoramaSpec(settings.width, settings.height, settings.sdk.radius_m)
    source = DirectoryFrameSource(directory, spec, head=head if isinstance(head, HeadCalibration) else None)
    return _converted(source.frames_with_sensors(), lambda pair: CameraFrame(*pair))


def _start_camera(stack: contextlib.ExitStack, feed: ThreadedCameraFeed) -> ThreadedCameraFeed:
    feed.start()
    stack.callback(feed.close)
    return feed


def _sim_rig(stack: contextlib.ExitStack, spec: MotionRigSpec) -> Sources:
    """The moving simulated rig, its sensors in child processes: the VLP-16 sends real UDP packets to a
    receiver on loopback, the camera renders frames at the rig's pose of the moment."""
    started = spec.started(time.time() + START_LEAD_S)
    receiver = UdpReceiver(Vlp16Config(), host="127.0.0.1", ports=Ports(0, 0)).start()
    lidar = _receiver_feed(stack, f"sim (udp 127.0.0.1:{receiver.ports.data})", receiver)
    stack.enter_context(LidarProcess(started, "127.0.0.1", receiver.ports.data, receiver.ports.position))
    return Sources(lidar, _sim_camera(stack, "sim", started), started)


def _sim_camera(stack: contextlib.ExitStack, describe: str, spec: MotionRigSpec) -> ThreadedCameraFeed:
    camera = CameraProcess(spec)
    stack.callback(camera.close)
    rig = sim_head_rig(spec)
    head = None if rig is None else simulated_head(rig)

    def frames() -> Iterator[CameraFrame]:
        return _converted(camera.frames(), lambda frame: sim_frame(frame, head))

    return _start_camera(stack, ThreadedCameraFeed(describe, frames, camera.close, SIM_FRAME_GAP_S))


def _converted(stream: Iterator[_Item], convert: Callable[[_Item], CameraFrame]) -> Iterator[CameraFrame]:
    """``stream``'s items converted; closing this closes ``stream`` (a generator holding a camera releases it)."""
    try:
        for item in stream:
            yield convert(item)
    finally:
        _close(stream)


def _lidar_feed(stack: contextlib.ExitStack, spec: LidarSpec) -> LidarFeed:
    if spec.kind is not LidarKind.PCAP:
        receiver = UdpReceiver(Vlp16Config(), host=spec.host, ports=Ports(spec.data_port, spec.position_port)).start()
        return _receiver_feed(stack, str(spec), receiver)
    assert spec.path is not None
    replay = PcapReplay(spec.path, Vlp16Config())
    feed = LidarFeed(str(spec), lambda: replay, lambda: replay.stats).start()
    stack.callback(feed.close)
    return feed


def _receiver_feed(stack: contextlib.ExitStack, describe: str, receiver: UdpReceiver) -> LidarFeed:
    """The sweeps of the started ``receiver``; both are closed with ``stack``."""
    stack.callback(receiver.close)
    feed = LidarFeed(describe, lambda: receiver.sweeps(timeout_s=float("inf")), lambda: receiver.stats,
                     receiver.close).start()
    stack.callback(feed.close)
    return feed


NOMINAL_FIX = (
    "capture does not run on rigd's nominal head, which is not a calibration of any camera (every extrinsic "
    "calibration would absorb its lens errors): export the camera's factory head with `rigd camera export-head "
    "--out /etc/rigd/ladybug_head.yaml` (from the camera, or from a .pgr stream or .cal file with --pgr / "
    "--calibration) and set camera.sdk.rig_file to it, or pass --nominal-head to capture with the nominal head "
    "anyway (docs/ladybug5.md)"
)


def sdk_head(settings: RigSettings, *, nominal_head: bool) -> HeadCalibration | HeadPolicy:
    """The head calibration the live camera's frames go with: ``camera.sdk.rig_file``, else the rig file itself
    when its camera.model is head, else the camera's factory head read through the SDK at the first frame
    (``HeadPolicy.FACTORY``); rigd's nominal head only when ``nominal_head``. A file whose head says ``source:
    nominal`` is refused without ``nominal_head`` (ConfigError naming the fix)."""
    path = settings.sdk.rig_file or (settings.path if settings.head else None)
    if path is None:
        return HeadPolicy.NOMINAL if nominal_head else HeadPolicy.FACTORY
    head = load_head(path)
    if head.source is HeadSource.NOMINAL and not nominal_head:
        raise ConfigError(f"{path}: this head calibration is rigd's nominal head (head.source: nominal), not the "
                          f"camera's: {NOMINAL_FIX}")
    return head


def _sdk_feed(settings: RigSettings, *, nominal_head: bool) -> ThreadedCameraFeed:
    """The live Ladybug5 through FLIR's SDK: each frame's six sensor images with the head calibration, and the
    panorama at the rig file's panorama size, stitched by rigd or rendered by the SDK (camera.sdk.panorama)."""
    sdk = settings.sdk
    if not sdk.layout.exists():
        # The usual first-run state of a rig computer: say where the file comes from, not only that it is missing.
        raise ConfigError(
            f"{sdk.layout}: the Ladybug SDK layout file does not exist (camera.sdk.layout). The live Ladybug5 "
            "needs it: install FLIR's Ladybug SDK (not on PyPI, rigd does not ship it), then measure its header "
            f"with `rigd camera sdk-layout --include /usr/include/ladybug --out {sdk.layout}` (the directory "
            "holding ladybug.h), or set camera.sdk.layout in the rig file to an existing layout file "
            "(docs/ladybug5.md). Without the camera, capture from the simulated rig (source sim).")
    head = sdk_head(settings, nominal_head=nominal_head)
    library = LadybugLibrary(SdkLayout.load(sdk.layout), sdk.library)
    camera = SdkCamera(library, serial=sdk.serial, grab_timeout_ms=sdk.grab_timeout_ms)
    source = SdkFrameSource(camera, PanoramaSpec(settings.width, settings.height, sdk.radius_m), head=head,
                            panorama=sdk.panorama)

    def frames() -> Iterator[CameraFrame]:
        try:
            yield from _converted(source.frames_with_sensors(), lambda pair: CameraFrame(*pair))
        except HeadCalibrationError as exc:  # the factory head unreadable, or not the camera's sensor size
            raise HeadCalibrationError(f"{exc}; {NOMINAL_FIX}") from exc

    describe = "sdk" if sdk.serial is None else f"sdk (camera {sdk.serial})"
    return ThreadedCameraFeed(describe, frames)
