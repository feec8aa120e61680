"""The stationarity gate: is the rig standing still, and has it moved since the last pair?

Thresholds come from what the calibration tolerates (:class:`StillThresholds`, derived in docs/capture.md):
the rig's tolerance (0.2 deg, about 1 px of a 2048 px panorama) split between the rig's motion during a pair
and everything else.

LiDAR (the fine test). A sweep becomes a :class:`DirectionGrid`: per ring (16) and degree of azimuth
(360) the mean point and range of its returns. 1 degree holds 5 firings at 600 rpm (2.5 at 1200), whose
mean has a fraction of one return's noise, and is still small beside the 2 degree ring spacing.

- Still: every sweep of the window is compared with the window's first sweep (its anchor), so slow creep
  adds up: :func:`estimate_motion` solves the rigid motion that moves the anchor's surfaces (point to
  plane, per bin) onto the sweep's, robustly (a person walking by, depth edges). A rotation or a
  translation above the thresholds, or too few bins agreeing, restarts the window at that sweep. The rig
  is still once the window spans ``still_seconds``.
- Moved: the latest sweep against the last pair's cloud by the 90th percentile over directions of the
  absolute range change, m (:func:`range_change_m`); at least ``min_move_m`` (or no pair yet). A
  percentile rather than the median: along a corridor most directions see surfaces parallel to the motion.

Camera (confirmation, when frames are available): frames reduced to at most 1024 px wide, grey; the band
between 45 deg above and below the horizon is cut into 8 sectors of azimuth, each phase-correlated with the
window's first frame; a frame's change is the largest sector shift, in degrees. It sees rotation and the
parallax of a translation; it resolves about half a pixel of the compared image (0.18 deg at 1024 px), so
below that the LiDAR decides alone.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.layout import NOMINAL_ELEVATION_DEG

RINGS = 16
AZIMUTH_BINS = 360
CHANGE_QUANTILE = 90.0  # percent of directions
MIN_COMMON_BINS = 100  # fewer bins to compare: no verdict (treated as a change)
# Point-to-plane comparison of two sweeps (estimate_motion): a bin is a plane sample when its returns spread
# less than this along the range (a depth edge mixes two surfaces) and its neighbours are on the same surface.
PLANE_SPREAD_M = 0.1
PLANE_SPREAD_FRACTION = 0.05  # + this fraction of the range: a slanted plane spreads its returns within a bin
NEIGHBOUR_FRACTION = 0.2  # neighbours' ranges within this fraction of the bin's: one surface
NOISE_FLOOR_M = 0.003  # the residual scale is never taken below this (a perfectly repeated simulated scan)
HUBER_K = 1.5  # residuals beyond this many scales are down-weighted (a person walking by, a depth edge)
INLIER_SIGMAS = 3.0
MIN_INLIER_FRACTION = 0.5  # fewer bins agreeing with the estimated motion: it is not a small motion
MOVING_SWEEPS = 3  # a window shorter than this many sweeps is motion, not the start of a stop
IRLS_ROUNDS = 4
# The thresholds' derivation (docs/capture.md): each sweep within rotation_deg and translation_m of the
# anchor keeps any two instants of a window within twice that; twice is half the tolerance, the other half
# is the calibration's. A translation t shifts a surface NEAR_RANGE_M away by t / NEAR_RANGE_M radians.
TOLERANCE_SHARE = 0.25
NEAR_RANGE_M = 3.0
CAMERA_WIDTH = 1024  # frames are compared at most this wide (halved with pyrDown until they fit)
CAMERA_SECTORS = 8
CAMERA_MIN_PX = 0.5  # what phase correlation resolves reliably on the simulator's frames (docs/capture.md)
CAMERA_MIN_RESPONSE = 0.5  # a sector whose correlation peak is weaker has no clear match (little texture, sky)

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]


@dataclass(frozen=True)
class StillThresholds:
    """How much the rig may move during a still window, from its rotation tolerance ``tolerance_deg``:
    ``rotation_deg`` and ``translation_m`` of the LiDAR from the window's first sweep; a camera frame may
    shift the tolerance from the window's first frame (or what the compared image resolves, if coarser:
    :meth:`camera_threshold_deg`)."""

    tolerance_deg: float
    rotation_deg: float
    translation_m: float

    @classmethod
    def from_tolerance(cls, tolerance_deg: float = 0.2) -> StillThresholds:
        """Derived from the rig's rotation tolerance, deg (module constants; docs/capture.md)."""
        share = TOLERANCE_SHARE * tolerance_deg
        return cls(tolerance_deg, share, math.radians(share) * NEAR_RANGE_M)

    def camera_threshold_deg(self, width_px: int) -> float:
        """The camera's threshold for frames compared ``width_px`` wide, deg."""
        return max(self.tolerance_deg, CAMERA_MIN_PX * 360.0 / max(width_px, 1))


@dataclass(frozen=True)
class DirectionGrid:
    """A sweep per direction bin (ring x degree of azimuth, clockwise from x): ``range_m`` (16,360) float32
    mean range m, ``points`` (16,360,3) float32 mean point m in the LiDAR frame, ``spread_m`` (16,360) float32
    standard deviation of the ranges m, ``count`` (16,360) int32 returns; NaN where there is no return."""

    range_m: F32
    points: F32
    spread_m: F32
    count: NDArray[np.int32]

    @property
    def returns(self) -> int:
        """Directions with at least one return."""
        return int(np.count_nonzero(self.count))


def direction_grid(points_lidar: NDArray[np.floating], ring: NDArray[np.integer]) -> DirectionGrid:
    """The :class:`DirectionGrid` of ``points_lidar`` (N,3) m with their ``ring`` (N,) 0..15."""
    xyz = np.asarray(points_lidar, dtype=np.float64)
    rng = np.sqrt(np.einsum("ij,ij->i", xyz, xyz))
    azimuth = np.degrees(np.arctan2(-xyz[:, 1], xyz[:, 0])) % 360.0
    column = np.minimum((azimuth * (AZIMUTH_BINS / 360.0)).astype(np.int64), AZIMUTH_BINS - 1)
    ring_index = np.asarray(ring, dtype=np.int64)
    ok = (ring_index >= 0) & (ring_index < RINGS) & (rng > 0)
    key = ring_index[ok] * AZIMUTH_BINS + column[ok]
    size = RINGS * AZIMUTH_BINS
    count = np.bincount(key, None, size)
    sums = [np.bincount(key, w, size) for w in (rng[ok], rng[ok] ** 2, *xyz[ok].T)]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, np.stack(sums) / count, np.nan)
    spread = np.sqrt(np.maximum(mean[1] - mean[0] ** 2, 0.0))
    shape = (RINGS, AZIMUTH_BINS)
    return DirectionGrid(mean[0].reshape(shape).astype(np.float32), mean[2:].T.reshape(*shape, 3).astype(np.float32),
                         spread.reshape(shape).astype(np.float32), count.reshape(shape).astype(np.int32))


def range_image(points_lidar: NDArray[np.floating], ring: NDArray[np.integer]) -> F32:
    """(16, 360) float32: mean range m per ring and degree of azimuth (clockwise from x, as the VLP-16
    turns); NaN where no return. ``points_lidar`` (N,3) m in the LiDAR frame, ``ring`` (N,) 0..15."""
    return direction_grid(points_lidar, ring).range_m


def range_change_m(a: F32, b: F32) -> float:
    """90th percentile of |a - b| m over bins with a return in both; inf when too few bins compare."""
    diff = np.abs(a - b)
    diff = diff[np.isfinite(diff)]
    if len(diff) < MIN_COMMON_BINS:
        return math.inf
    return float(np.percentile(diff, CHANGE_QUANTILE))


@dataclass(frozen=True)
class PlaneBins:
    """The bins of a reference sweep that sample a surface: flat bin indices (M,), their mean points (M,3) m
    and unit surface normals (M,3) (from the neighbouring bins), for :func:`estimate_motion`."""

    index: NDArray[np.int64]
    points: F64
    normals: F64


def _plane_sample(grid: DirectionGrid) -> NDArray[np.bool_]:
    """(16,360) bins whose returns lie on one surface: enough of them, little spread along the range."""
    with np.errstate(invalid="ignore"):
        return np.asarray((grid.count >= 2) & (grid.spread_m < PLANE_SPREAD_M + PLANE_SPREAD_FRACTION * grid.range_m),
                          dtype=bool)


def plane_bins(grid: DirectionGrid) -> PlaneBins:
    """Normals from the neighbouring bins (azimuth wraps; the top and bottom rings use one-sided
    differences); bins on a depth edge or without four neighbours on their surface are left out."""
    points = grid.points.astype(np.float64)
    rng = grid.range_m.astype(np.float64)
    up, down = np.r_[1:RINGS, RINGS - 1], np.r_[0, 0 : RINGS - 1]
    along = np.roll(points, -1, axis=1) - np.roll(points, 1, axis=1)
    across = points[up] - points[down]
    normal = np.cross(along, across)
    length = np.linalg.norm(normal, axis=2)
    with np.errstate(invalid="ignore"):
        near = [np.abs(nb - rng) < NEIGHBOUR_FRACTION * rng
                for nb in (np.roll(rng, 1, axis=1), np.roll(rng, -1, axis=1), rng[up], rng[down])]
        ok = _plane_sample(grid) & np.all(near, axis=0) & (length > 0)
    index = np.flatnonzero(ok)
    flat_normal = (normal / np.where(length > 0, length, 1.0)[..., None]).reshape(-1, 3)
    return PlaneBins(index, points.reshape(-1, 3)[index], flat_normal[index])


@dataclass(frozen=True)
class Motion:
    """The LiDAR's rigid motion from a reference sweep to another: rotation deg and translation m (small-motion
    point-to-plane estimate), the bins compared and the fraction of them that agree with it."""

    rotation_deg: float
    translation_m: float
    bins: int
    inlier_fraction: float

    @classmethod
    def unknown(cls, bins: int) -> Motion:
        return cls(math.inf, math.inf, bins, 0.0)


def estimate_motion(reference: PlaneBins, grid: DirectionGrid) -> Motion:
    """How far the sensor moved from the ``reference`` sweep to ``grid``'s: each plane bin of the reference
    against the same bin now (the displacement along the normal), solved for a small rotation and
    translation by iteratively re-weighted least squares (Huber). A bin's mean point lies on its surface
    wherever the firings fell in it, so the beams' own jitter from turn to turn is no motion."""
    current = grid.points.reshape(-1, 3)[reference.index].astype(np.float64)
    ok = np.isfinite(current).all(axis=1) & _plane_sample(grid).ravel()[reference.index]
    if np.count_nonzero(ok) < MIN_COMMON_BINS:
        return Motion.unknown(int(np.count_nonzero(ok)))
    normals, current = reference.normals[ok], current[ok]
    jacobian = np.concatenate([np.cross(current, normals), normals], axis=1)  # (M,6): d(residual)/d(omega, t)
    displacement = np.einsum("ij,ij->i", normals, reference.points[ok] - current)
    weight = np.ones(len(displacement))
    for _ in range(IRLS_ROUNDS):
        weighted = jacobian * weight[:, None]
        hessian = np.einsum("ij,ik->jk", weighted, jacobian)
        hessian += np.eye(6) * 1e-9 * np.trace(hessian)  # keeps an unobservable direction (a corridor's axis) at 0
        x = np.linalg.solve(hessian, np.einsum("ij,i->j", weighted, displacement))
        residual = np.abs(displacement - np.einsum("ij,j->i", jacobian, x))
        scale = max(1.4826 * float(np.median(residual)), NOISE_FLOOR_M)
        weight = np.minimum(1.0, HUBER_K * scale / np.maximum(residual, 1e-12))
    inliers = float(np.mean(residual < INLIER_SIGMAS * scale))
    return Motion(math.degrees(float(np.linalg.norm(x[:3]))), float(np.linalg.norm(x[3:])), len(displacement), inliers)


def grid_from_range_image(image: F32) -> DirectionGrid:
    """A :class:`DirectionGrid` from a (16,360) range image alone: points along each bin's centre direction
    at the nominal ring elevations (no spread; 5 returns per bin), for callers that only have ranges."""
    elevation = np.radians(np.sort(NOMINAL_ELEVATION_DEG))[:, None]
    azimuth = np.radians((np.arange(AZIMUTH_BINS) + 0.5) * 360.0 / AZIMUTH_BINS)[None, :]
    directions = np.stack(np.broadcast_arrays(np.cos(elevation) * np.cos(azimuth), -np.cos(elevation) * np.sin(azimuth),
                                              np.sin(elevation)), axis=-1)
    rng = np.asarray(image, dtype=np.float32)
    count = np.where(np.isfinite(rng), 5, 0).astype(np.int32)
    return DirectionGrid(rng, (rng[..., None] * directions).astype(np.float32), np.zeros_like(rng), count)


def camera_image(image: U8) -> U8:
    """An (H,W) grey or (H,W,3) BGR uint8 frame as the camera test compares it: grey, halved with pyrDown
    until it is at most CAMERA_WIDTH wide (pyrDown keeps pixel centres: docs/conventions.md)."""
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    while grey.shape[1] > CAMERA_WIDTH:
        grey = cv2.pyrDown(grey)
    return np.ascontiguousarray(grey, dtype=np.uint8)


def camera_shift_deg(a: U8, b: U8) -> float:
    """Largest shift between two :func:`camera_image` panoramas over 8 sectors of the band 45 deg either side
    of the horizon (phase correlation), deg; NaN when no sector has texture to correlate or sizes differ."""
    if a.shape != b.shape:
        return math.nan
    height, width = a.shape
    rows = slice(height // 4, height - height // 4)
    step = width // CAMERA_SECTORS
    if step < 8 or rows.stop - rows.start < 8:
        return math.nan
    window = cv2.createHanningWindow((step, rows.stop - rows.start), cv2.CV_32F)
    shifts = []
    for k in range(CAMERA_SECTORS):
        cols = slice(k * step, (k + 1) * step)
        (dx, dy), response = cv2.phaseCorrelate(a[rows, cols].astype(np.float32), b[rows, cols].astype(np.float32),
                                                window)
        if response >= CAMERA_MIN_RESPONSE:
            shifts.append(math.hypot(dx, dy))
    return max(shifts) * 360.0 / width if shifts else math.nan


@dataclass(frozen=True)
class SweepSample:
    """A complete sweep reduced for the gate: host-clock start and end s, its (16,360) range image m, and
    its direction grid (None: made from the range image by :func:`grid_from_range_image`)."""

    t_start: float
    t_end: float
    image: F32
    grid: DirectionGrid | None = None

    @property
    def directions(self) -> DirectionGrid:
        return self.grid if self.grid is not None else grid_from_range_image(self.image)


@dataclass(frozen=True)
class FrameSample:
    """A camera frame reduced for the gate: exposure on the host clock s and its :func:`camera_image`."""

    t: float
    image: U8


class StillnessGate:
    """The current still window from LiDAR sweeps, confirmed by camera frames (module doc)."""

    def __init__(self, thresholds: StillThresholds, frames_kept: int = 32) -> None:
        self.thresholds = thresholds
        self.anchor: SweepSample | None = None
        self.latest: SweepSample | None = None
        self.sweeps = 0  # in the window
        self.rotation_deg = 0.0  # largest motion from the anchor in the window
        self.translation_m = 0.0
        self.last_motion: Motion | None = None  # of the latest sweep against its window's anchor
        self._planes: PlaneBins | None = None
        self._frames: deque[FrameSample] = deque(maxlen=frames_kept)
        self._shifts: dict[tuple[float, float], float] = {}  # (first frame t, frame t) -> deg

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

    def add_sweep(self, sample: SweepSample) -> Motion | None:
        """Take a sweep; returns its motion from the anchor (None when it starts the first window)."""
        self.latest = sample
        if self._planes is None:
            self.restart()
            return None
        motion = estimate_motion(self._planes, sample.directions)
        self.last_motion = motion
        if not self.is_still(motion):
            self.restart()
            return motion
        self.sweeps += 1
        self.rotation_deg = max(self.rotation_deg, motion.rotation_deg)
        self.translation_m = max(self.translation_m, motion.translation_m)
        return motion

    def held(self, still_seconds: float, sweeps: int) -> bool:
        """Whether the window is a still period: ``still_seconds`` long and ``sweeps`` sweeps (at least 3)."""
        return self.sweeps >= max(sweeps, MOVING_SWEEPS) and self.still_for_s >= still_seconds

    def is_still(self, motion: Motion) -> bool:
        return (motion.inlier_fraction >= MIN_INLIER_FRACTION and motion.rotation_deg <= self.thresholds.rotation_deg
                and motion.translation_m <= self.thresholds.translation_m)

    def restart(self) -> None:
        """Start a new window at the latest sweep (motion seen by the LiDAR or the camera, a clock step)."""
        self.anchor = self.latest
        self._planes = None if self.latest is None else plane_bins(self.latest.directions)
        self.sweeps = 1 if self.latest is not None else 0
        self.rotation_deg = self.translation_m = 0.0

    def reset(self) -> None:
        """No window at all: the next sweep starts one (the sweeps so far are on a clock no longer trusted)."""
        self.anchor = self.latest = None
        self._planes = None
        self.sweeps = 0
        self.rotation_deg = self.translation_m = 0.0
        self.last_motion = None

    def add_frame(self, sample: FrameSample) -> None:
        self._frames.append(sample)

    def window_frames(self) -> list[FrameSample]:
        window = self.window
        if window is None:
            return []
        return sorted((f for f in self._frames if window[0] <= f.t <= window[1]), key=lambda f: f.t)

    def camera_change(self) -> float | None:
        """Largest shift of a window frame from the window's first frame, deg; None with < 2 frames (or no
        texture to compare)."""
        frames = self.window_frames()
        shifts = [self._shift(frames[0], f) for f in frames[1:]]
        shifts = [s for s in shifts if math.isfinite(s)]
        return max(shifts) if shifts else None

    def camera_threshold_deg(self) -> float | None:
        frames = self.window_frames()
        return self.thresholds.camera_threshold_deg(frames[0].image.shape[1]) if frames else None

    def camera_saw_motion(self) -> bool:
        change, threshold = self.camera_change(), self.camera_threshold_deg()
        return change is not None and threshold is not None and change > threshold

    def _shift(self, first: FrameSample, frame: FrameSample) -> float:
        """Phase correlation is the costly part: each pair of frames is compared once."""
        key = (first.t, frame.t)
        if key not in self._shifts:
            if len(self._shifts) > 4 * (self._frames.maxlen or 1):
                self._shifts.clear()
            self._shifts[key] = camera_shift_deg(first.image, frame.image)
        return self._shifts[key]
