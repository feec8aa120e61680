"""The camera frames a still window may use, and whether they run ahead of the LiDAR's sweeps on the host clock."""

from __future__ import annotations

import math
import time

from rigd.capture.errors import SyncError
from rigd.capture.sources import CameraFrame

FRAMES_AHEAD_KEPT = 16  # frames newer than the still window kept for it (they are full images)
# Camera frames this far ahead of the LiDAR's latest sweep on the host clock cannot be explained by the
# loop being behind for long: one of the clocks is wrong (shown at once, an error after the silence timeout).
CLOCK_DISAGREE_S = 1.0

TimedFrame = tuple[float, CameraFrame]  # (host time s, frame)


class WindowFrames:
    """The frames received that the still window may use: the newest inside it and those after it."""

    def __init__(self) -> None:
        self.frames: list[TimedFrame] = []

    def add(self, t: float, frame: CameraFrame) -> None:
        self.frames.append((t, frame))

    def prune(self, window: tuple[float, float] | None) -> None:
        """Keep the newest frame inside the still window and those after it (the window grows onto them)."""
        if window is None:
            self.frames = self.frames[-FRAMES_AHEAD_KEPT:]
            return
        inside = [f for f in self.frames if window[0] <= f[0] <= window[1]]
        self.frames = inside[-1:] + [f for f in self.frames if f[0] > window[1]][-FRAMES_AHEAD_KEPT:]

    def inside(self, window: tuple[float, float]) -> list[TimedFrame]:
        return [(t, f) for t, f in self.frames if window[0] <= t <= window[1]]

    def newest(self) -> TimedFrame | None:
        return max(self.frames, key=lambda f: f[0], default=None)


class FrameLead:
    """Since when (monotonic s) the camera's frames have run ahead of the LiDAR's sweeps by more than
    CLOCK_DISAGREE_S while the still window waits for a frame; SyncError once that lasts ``timeout_s``."""

    def __init__(self, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        self.since: float | None = None

    def check(self, newest: TimedFrame | None, window: tuple[float, float], lidar_offset_s: float) -> str | None:
        """None while no frame is that far ahead of ``window``; else what is wrong (host minus device offsets:
        the LiDAR's ``lidar_offset_s``, the newest frame's)."""
        ahead_s = -math.inf if newest is None else newest[0] - window[1]
        if newest is None or ahead_s <= CLOCK_DISAGREE_S:
            self.since = None
            return None
        now = time.monotonic()
        self.since = self.since if self.since is not None else now
        camera_offset = newest[0] - newest[1].panorama.device_time_s
        what = (f"the camera's frames are {ahead_s:.1f} s ahead of the LiDAR's sweeps on the host clock (host minus "
                f"device: camera {camera_offset:+.3f} s, LiDAR {lidar_offset_s:+.3f} s): one of the clocks is wrong")
        if now - self.since > self.timeout_s:
            raise SyncError(f"no synchronised pair for {now - self.since:.1f} s: {what}; check the camera's "
                            "and the LiDAR's time sources (GPS/PPS, NTP) and restart the sensor whose clock jumped")
        return what
