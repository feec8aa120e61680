"""The stationarity gate: is the rig standing still, and has it moved since the last pair?

LiDAR. A sweep becomes a range image: per ring (16) and 1 degree of azimuth (360), the mean range of
its returns, m. Two range images are compared by the 90th percentile over directions (bins with a return
in both) of the absolute range change, m: "90 % of the directions changed by less than this". A
percentile rather than the median: along a corridor or a street, most directions see surfaces parallel
to the motion (floor, facades) whose range does not change, and the median misses a 1 m drive (measured
on the simulator's street: median 1.3 cm, 90th percentile 2.2 m); up to 10 % of the directions may change
for other reasons (a person walking by, beams on depth edges that hit either side from turn to turn).

- Still: every sweep of the window is compared with the window's first sweep (its anchor), not only with
  its predecessor, so slow creep adds up; a change above ``still_range_m`` restarts the window at that
  sweep. The rig is still once the window spans ``still_seconds``.
- Moved: the latest sweep against the last pair's cloud; at least ``min_move_m`` (or no pair yet).

Camera (confirmation, when frames are available): 128x64 grey thumbnails (area average); a frame's change
is the mean absolute difference from the window's first frame after removing the median difference (an
exposure step shifts every pixel alike), grey levels. Noise figures: docs/capture.md.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

RINGS = 16
AZIMUTH_BINS = 360
CHANGE_QUANTILE = 90.0  # percent of directions
MIN_COMMON_BINS = 100  # fewer bins with a return in both images: no verdict (treated as a change)
THUMBNAIL_SIZE = (128, 64)  # width, height

F32 = NDArray[np.float32]


def range_image(points_lidar: NDArray[np.floating], ring: NDArray[np.integer]) -> F32:
    """(16, 360) float32: mean range m per ring and degree of azimuth (clockwise from x, as the VLP-16
    turns); NaN where no return. ``points_lidar`` (N,3) m in the LiDAR frame, ``ring`` (N,) 0..15."""
    xyz = np.asarray(points_lidar, dtype=np.float64)
    rng = np.sqrt(np.einsum("ij,ij->i", xyz, xyz))
    azimuth = np.degrees(np.arctan2(-xyz[:, 1], xyz[:, 0])) % 360.0
    column = np.minimum((azimuth * (AZIMUTH_BINS / 360.0)).astype(np.int64), AZIMUTH_BINS - 1)
    ring_index = np.asarray(ring, dtype=np.int64)
    ok = (ring_index >= 0) & (ring_index < RINGS) & (rng > 0)
    key = ring_index[ok] * AZIMUTH_BINS + column[ok]
    total = np.bincount(key, rng[ok], RINGS * AZIMUTH_BINS)
    count = np.bincount(key, None, RINGS * AZIMUTH_BINS)
    mean = np.full(RINGS * AZIMUTH_BINS, np.nan)
    np.divide(total, count, out=mean, where=count > 0)
    return mean.reshape(RINGS, AZIMUTH_BINS).astype(np.float32)


def range_change_m(a: F32, b: F32) -> float:
    """90th percentile of |a - b| m over bins with a return in both; inf when too few bins compare."""
    diff = np.abs(a - b)
    diff = diff[np.isfinite(diff)]
    if len(diff) < MIN_COMMON_BINS:
        return math.inf
    return float(np.percentile(diff, CHANGE_QUANTILE))


def thumbnail(image: NDArray[np.uint8]) -> F32:
    """(64, 128) float32 grey thumbnail (area average) of an (H,W) grey or (H,W,3) BGR uint8 image."""
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    return cv2.resize(grey, THUMBNAIL_SIZE, interpolation=cv2.INTER_AREA).astype(np.float32)


def image_change_grey(a: F32, b: F32) -> float:
    """Mean |a - b - median(a - b)| in grey levels between two thumbnails."""
    diff = a - b
    return float(np.mean(np.abs(diff - np.median(diff))))


@dataclass(frozen=True)
class SweepSample:
    """A complete sweep reduced for the gate: host-clock start and end s and its (16,360) range image."""

    t_start: float
    t_end: float
    image: F32


@dataclass(frozen=True)
class FrameSample:
    """A camera frame reduced for the gate: exposure on the host clock s and its (64,128) thumbnail."""

    t: float
    thumb: F32


class StillnessGate:
    """The current still window from LiDAR sweeps, confirmed by camera frames (module doc)."""

    def __init__(self, still_range_m: float, camera_grey: float, frames_kept: int = 256) -> None:
        self.still_range_m = still_range_m
        self.camera_grey = camera_grey
        self.anchor: SweepSample | None = None
        self.latest: SweepSample | None = None
        self.sweeps = 0  # in the window
        self.lidar_change_m = 0.0  # largest change from the anchor in the window
        self.last_change_m = 0.0  # of the latest sweep
        self._frames: deque[FrameSample] = deque(maxlen=frames_kept)

    @property
    def window(self) -> tuple[float, float] | None:
        """[start, end] s on the host clock: first sweep's start to the latest sweep's end."""
        if self.anchor is None or self.latest is None:
            return None
        return self.anchor.t_start, self.latest.t_end

    @property
    def still_for_s(self) -> float:
        window = self.window
        return 0.0 if window is None else window[1] - window[0]

    def add_sweep(self, sample: SweepSample) -> float:
        """Take a sweep; returns its change from the anchor m (0 when it starts a new window)."""
        self.latest = sample
        change = math.inf if self.anchor is None else range_change_m(self.anchor.image, sample.image)
        self.last_change_m = change
        if change > self.still_range_m:
            self.restart()
            return 0.0
        self.sweeps += 1
        self.lidar_change_m = max(self.lidar_change_m, change)
        return change

    def restart(self) -> None:
        """Start a new window at the latest sweep (motion seen by the LiDAR or the camera)."""
        self.anchor = self.latest
        self.sweeps = 1 if self.latest is not None else 0
        self.lidar_change_m = 0.0

    def add_frame(self, sample: FrameSample) -> None:
        self._frames.append(sample)

    def window_frames(self) -> list[FrameSample]:
        window = self.window
        if window is None:
            return []
        return [f for f in self._frames if window[0] <= f.t <= window[1]]

    def camera_change(self) -> float | None:
        """Largest change of a window frame from the window's first frame, grey levels; None with < 2 frames."""
        frames = sorted(self.window_frames(), key=lambda f: f.t)
        if len(frames) < 2:
            return None
        return max(image_change_grey(frames[0].thumb, f.thumb) for f in frames[1:])

    def camera_saw_motion(self) -> bool:
        change = self.camera_change()
        return change is not None and change > self.camera_grey
