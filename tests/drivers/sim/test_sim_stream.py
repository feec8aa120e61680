"""The simulated sensors in child processes: stopping them is quick, and never waits on a child that does not
answer (stopped with SIGSTOP, hung). The camera renders the next stop's view before the rig gets there."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

import drivers.sim.stream as stream_module
from drivers.sim import Pose, render_panorama
from drivers.sim.camera import panorama_display
from drivers.sim.disturbance import Disturbance
from drivers.sim.motion import MotionRigSpec, Trajectory
from drivers.sim.scene import Scene
from drivers.sim.stream import CameraProcess, CameraStream, LidarProcess, SimFrame, next_stop
from drivers.vlp16 import Ports, UdpReceiver

SPEC = MotionRigSpec(scene="indoor", seed=3, stops=2, still_s=5.0, move_s=1.0, width=64, height=32,
                     frame_period_s=1.0)  # a 64x32 frame renders in far less than its period: the child mostly waits


def closing_time(close: Callable[[], None], limit_s: float) -> float:
    """Seconds ``close()`` took; fails if it had not returned after ``limit_s``."""
    started = time.monotonic()
    thread = threading.Thread(target=close, daemon=True)
    thread.start()
    thread.join(limit_s)
    assert not thread.is_alive(), f"close() still waiting after {limit_s} s"
    return time.monotonic() - started


@contextlib.contextmanager
def reaped(pid: int) -> Iterator[None]:
    """Whatever the test did, the child does not outlive it."""
    try:
        yield
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


def first_frame(camera: CameraProcess) -> tuple[Iterator[SimFrame], SimFrame]:
    frames = camera.frames()
    return frames, next(frames)


@pytest.mark.parametrize("stopped", [False, True])
def test_closing_the_camera_process(stopped: bool) -> None:
    camera = CameraProcess(SPEC.started(time.time() + 0.2))
    process = camera._process
    assert process.pid is not None
    with reaped(process.pid):
        frames, frame = first_frame(camera)  # the child has rendered; now it waits for its next frame time
        assert frame.image.shape == (32, 64)
        if stopped:
            os.kill(process.pid, signal.SIGSTOP)
        elapsed = closing_time(camera.close, 15.0)
        frames.close()  # type: ignore[attr-defined]
    assert not process.is_alive()
    if stopped:  # not waited on: a grace period, then SIGTERM (continued so that it acts on it)
        assert process.exitcode == -signal.SIGTERM and elapsed < 6.0
    else:  # it saw its stop flag within a poll
        assert process.exitcode == 0 and elapsed < 1.0


@pytest.mark.parametrize("stopped", [False, True])
def test_closing_the_lidar_process(stopped: bool) -> None:
    with UdpReceiver(host="127.0.0.1", ports=Ports(0, 0)) as receiver:
        lidar = LidarProcess(SPEC.started(time.time() + 0.2), "127.0.0.1", receiver.ports.data,
                             receiver.ports.position).start()
        process = lidar._process
        assert process.pid is not None
        with reaped(process.pid):
            sweeps = receiver.sweeps(timeout_s=20.0)
            assert next(sweeps).points.size  # the child is up and sending
            if stopped:
                os.kill(process.pid, signal.SIGSTOP)
            elapsed = closing_time(lidar.close, 15.0)
    assert not process.is_alive()
    if stopped:
        assert process.exitcode == -signal.SIGTERM and elapsed < 6.0
    else:
        assert process.exitcode == 0 and elapsed < 2.0


A, B, C = (Pose.from_rpy_xyz((0.0, 0.0, yaw), (x, 0.0, 1.5)) for yaw, x in ((0.0, 0.0), (90.0, 3.0), (180.0, 6.0)))


def test_next_stop_is_the_pose_the_rig_will_stand_at() -> None:
    trajectory = Trajectory((A, B, C), still_s=2.0, move_s=1.0)  # stops at [0, 2), [3, 5), [6, inf)
    for t, start in ((-1.0, 0.0), (0.0, 3.0), (1.0, 3.0), (2.5, 3.0), (3.0, 6.0), (5.5, 6.0)):
        stop = next_stop(trajectory, t)
        assert stop is not None and stop[0] == start
        for during in (start, start + 0.5, start + 1.999):  # the same bytes as every pose the stop's frames get
            assert stop[1].matrix.tobytes() == trajectory.pose_at(during).matrix.tobytes()
    assert next_stop(trajectory, 6.0) is None and next_stop(trajectory, 100.0) is None  # the last stop has begun
    shaking = Trajectory((A, B, C), still_s=2.0, move_s=1.0, disturbance=Disturbance(vibration_deg=0.1))
    assert next_stop(shaking, 1.0) is None  # never quite still: no view to render ahead


AHEAD = MotionRigSpec(scene="indoor", seed=3, stops=3, still_s=0.8, move_s=0.4, width=256, height=128,
                      frame_period_s=0.1)  # stops at [0, 0.8), [1.2, 2.0), [2.4, inf) s


def test_the_camera_renders_a_stop_before_the_rig_gets_there(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each stop's view is rendered once, begun before the rig stops there; the stop's first frame is then
    exposed as the stop begins (not when a render at the stop, or a moving frame's, would end) and shows
    the view at its exposure, with its own read noise."""
    spec = AHEAD.started(time.time() + 0.1)
    start_host_s = spec.start_host_s
    assert start_host_s is not None
    renders: list[tuple[float, bytes]] = []  # (start s on the rig's clock, pose)

    def counted(scene: Scene, pose: Pose, *args: Any, **kwargs: Any) -> NDArray[np.float64]:
        renders.append((time.time() - start_host_s, pose.matrix.tobytes()))
        return panorama_display(scene, pose, *args, **kwargs)

    monkeypatch.setattr(stream_module, "panorama_display", counted)
    stream = CameraStream(spec)
    trajectory = stream.trajectory
    first: dict[int, SimFrame] = {}
    frames = stream.frames()
    try:
        for frame in frames:
            stop = trajectory.stop_index(frame.device_time_s)
            if stop is not None:
                first.setdefault(stop, frame)
            if 2 in first:
                break
    finally:
        stream.close()
        frames.close()  # type: ignore[attr-defined]
    for stop in (1, 2):
        start, _ = trajectory.stop_interval(stop)
        key = trajectory.pose_at(start + 0.5).matrix.tobytes()
        began = [t for t, k in renders if k == key]
        assert len(began) == 1 and began[0] < start, f"stop {stop} at {start} s: its view was rendered at {began}"
        frame = first[stop]
        assert frame.device_time_s - start <= max(2 * spec.frame_period_s, 0.3)
        expected = render_panorama(stream.scene, trajectory.pose_at(frame.device_time_s), 256, 128,
                                   np.random.default_rng([spec.seed, frame.sequence, 11]), spec.image_noise_grey)
        np.testing.assert_array_equal(frame.image, expected)


def ahead_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "sim-camera-ahead"]


@pytest.mark.parametrize("rig", ["moves", "one place", "disturbed"])
def test_rendering_ahead_ends_with_the_stream(rig: str) -> None:
    """The thread rendering ahead ends at close() (it is looked at between renders); a rig that never moves
    on, or never stands quite still, has none: its stream is what it was without rendering ahead."""
    spec = {"moves": AHEAD, "one place": dataclasses.replace(AHEAD, stops=1),
            "disturbed": dataclasses.replace(AHEAD, disturbance=Disturbance(creep_m_s=0.001))}[rig]
    assert not ahead_threads()
    stream = CameraStream(spec.started(time.time()))
    frames = stream.frames()
    next(frames)
    running = ahead_threads()
    assert len(running) == (1 if rig == "moves" else 0) and all(t.daemon for t in running)
    stream.close()
    assert next(frames, None) is None
    for thread in running:
        thread.join(5.0)
        assert not thread.is_alive()
