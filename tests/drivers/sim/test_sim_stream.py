"""The simulated sensors in child processes: stopping them is quick, and never waits on a child that does not
answer (stopped with SIGSTOP, hung)."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from drivers.sim.motion import MotionRigSpec
from drivers.sim.stream import CameraProcess, LidarProcess, SimFrame
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
