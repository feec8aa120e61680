"""Evidence of motion besides the LiDAR: an IMU, odometry and the camera's own images.

The capture's stillness gate judges the sweeps alone (:mod:`.stills`). A stretch it holds is not kept when one of
these says the rig moved inside it:

- ``--imu-topic`` (sensor_msgs/Imu): the angular velocity's norm above ``imu_rate_deg_s``, or the linear
  acceleration's norm off gravity by more than ``imu_accel_m_s2``;
- ``--odom-topic`` (nav_msgs/Odometry): the twist's linear speed above ``odom_speed_m_s`` or its angular rate above
  ``odom_rate_deg_s``;
- the image topic: the mean absolute difference of two consecutive images, grey and reduced to
  ``image_width_px`` px wide, above ``image_change_grey`` grey levels (0-255), stamped midway between them.

Each message is one sample at its header stamp; :func:`moving_intervals` gives each source's moving time
intervals (runs of moving samples), :meth:`MotionSamples.strongest` the sample that speaks loudest inside a stretch.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from rigd.importers.bag.errors import BagError

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]
GRAVITY_M_S2 = 9.80665


class MotionSource(Enum):
    """Where a sample of motion comes from (its name in the report)."""

    IMU = "imu"
    ODOMETRY = "odometry"
    IMAGE = "image"


class Quantity(Enum):
    """What a sample measures: its source and unit."""

    IMU_RATE = (MotionSource.IMU, "deg/s")
    IMU_ACCELERATION = (MotionSource.IMU, "m/s^2 off gravity")
    ODOM_SPEED = (MotionSource.ODOMETRY, "m/s")
    ODOM_RATE = (MotionSource.ODOMETRY, "deg/s")
    IMAGE_CHANGE = (MotionSource.IMAGE, "grey levels of change")

    @property
    def source(self) -> MotionSource:
        return self.value[0]

    @property
    def unit(self) -> str:
        return self.value[1]


@dataclass(frozen=True)
class MotionThresholds:
    """Above these a sample says the rig was moving (module doc). ``image_change_grey`` 0 (the default): the
    images are not consulted. A still rig's images change too where something moves in view (traffic past a
    street stop changes a 64 px panorama by several grey levels on average), so image motion is asked for,
    not assumed."""

    imu_rate_deg_s: float = 0.5
    imu_accel_m_s2: float = 0.5
    odom_speed_m_s: float = 0.01
    odom_rate_deg_s: float = 0.5
    image_change_grey: float = 0.0
    image_width_px: int = 64

    def limit(self, quantity: Quantity) -> float:
        """The threshold of ``quantity``."""
        return {Quantity.IMU_RATE: self.imu_rate_deg_s, Quantity.IMU_ACCELERATION: self.imu_accel_m_s2,
                Quantity.ODOM_SPEED: self.odom_speed_m_s, Quantity.ODOM_RATE: self.odom_rate_deg_s,
                Quantity.IMAGE_CHANGE: self.image_change_grey}[quantity]

    @property
    def images(self) -> bool:
        """Whether the images are consulted."""
        return self.image_change_grey > 0


@dataclass(frozen=True)
class MovingSample:
    """The loudest moving sample inside a stretch: what it measured, when (s on the header clock) and how much."""

    quantity: Quantity
    t_s: float
    value: float

    def describe(self, *, origin_s: float) -> str:
        """E.g. "imu: 3.2 deg/s at 12.40 s", the time from ``origin_s``."""
        return f"{self.quantity.source.value}: {self.value:.2f} {self.quantity.unit} at {self.t_s - origin_s:.2f} s"


@dataclass(frozen=True)
class MovingInterval:
    """A run of moving samples of one quantity, ``t_start_s`` .. ``t_end_s`` s (the first and last of them)."""

    quantity: Quantity
    t_start_s: float
    t_end_s: float
    peak: float


def _norm(vector: Any) -> float:
    return math.sqrt(float(vector.x) ** 2 + float(vector.y) ** 2 + float(vector.z) ** 2)


def _finite(value: float, *, what: str, where: str) -> float:
    if not math.isfinite(value):
        raise BagError(f"{where}: {what} is not a number ({value})")
    return value


def small_grey(image: U8, *, width_px: int) -> U8:
    """``image`` (grey or BGR) in grey, reduced to ``width_px`` px wide (area average)."""
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    height = max(1, round(grey.shape[0] * width_px / grey.shape[1]))
    return np.asarray(cv2.resize(grey, (width_px, height), interpolation=cv2.INTER_AREA), dtype=np.uint8)


def jpeg_small_grey(data: Any, *, width_px: int) -> U8 | None:
    """A compressed image's grey ``width_px`` px wide, decoded at an eighth of its size (fast for JPEG); None when
    it does not decode so (the full decode then says why)."""
    decoded = cv2.imdecode(np.asarray(data, dtype=np.uint8), cv2.IMREAD_REDUCED_GRAYSCALE_8)
    if decoded is None or decoded.size == 0 or decoded.shape[1] < width_px:
        return None
    return small_grey(np.asarray(decoded, dtype=np.uint8), width_px=width_px)


@dataclass
class MotionSamples:
    """Every sample of every source, as the bag is read (``add_*`` in bag order)."""

    times: dict[Quantity, list[float]] = field(default_factory=lambda: defaultdict(list))
    values: dict[Quantity, list[float]] = field(default_factory=lambda: defaultdict(list))
    _last_image: tuple[float, U8] | None = None

    def _add(self, quantity: Quantity, t_s: float, value: float) -> None:
        self.times[quantity].append(t_s)
        self.values[quantity].append(value)

    def add_imu(self, *, t_s: float, body: Any, where: str) -> None:
        """A sensor_msgs/Imu: its angular rate deg/s and its acceleration's departure from gravity m/s^2."""
        rate = math.degrees(_finite(_norm(body.angular_velocity), what="angular_velocity", where=where))
        accel = _finite(_norm(body.linear_acceleration), what="linear_acceleration", where=where)
        self._add(Quantity.IMU_RATE, t_s, rate)
        self._add(Quantity.IMU_ACCELERATION, t_s, abs(accel - GRAVITY_M_S2))

    def add_odometry(self, *, t_s: float, body: Any, where: str) -> None:
        """A nav_msgs/Odometry: its twist's speed m/s and angular rate deg/s."""
        twist = body.twist.twist
        self._add(Quantity.ODOM_SPEED, t_s, _finite(_norm(twist.linear), what="twist.linear", where=where))
        rate = math.degrees(_finite(_norm(twist.angular), what="twist.angular", where=where))
        self._add(Quantity.ODOM_RATE, t_s, rate)

    def add_image(self, *, t_s: float, grey: U8) -> None:
        """A reduced grey image (:func:`small_grey`): its mean absolute difference from the previous one."""
        if self._last_image is not None and self._last_image[1].shape == grey.shape:
            previous_t, previous = self._last_image
            change = float(np.mean(cv2.absdiff(previous, grey)))
            self._add(Quantity.IMAGE_CHANGE, 0.5 * (previous_t + t_s), change)
        self._last_image = (t_s, grey)

    @property
    def sources(self) -> set[MotionSource]:
        """The sources that gave a sample."""
        return {quantity.source for quantity in self.times}

    def arrays(self, quantity: Quantity) -> tuple[F64, F64]:
        """(N,) times s and (N,) values of ``quantity``, in time order."""
        t = np.asarray(self.times.get(quantity, []), dtype=np.float64)
        v = np.asarray(self.values.get(quantity, []), dtype=np.float64)
        order = np.argsort(t, kind="stable")
        return t[order], v[order]

    def strongest(self, *, t_start_s: float, t_end_s: float, thresholds: MotionThresholds) -> MovingSample | None:
        """The moving sample inside ``t_start_s`` .. ``t_end_s`` farthest above its threshold; None: none moved."""
        best: tuple[float, MovingSample] | None = None
        for quantity in self.times:
            limit = thresholds.limit(quantity)
            if quantity is Quantity.IMAGE_CHANGE and not thresholds.images:
                continue
            t, v = self.arrays(quantity)
            inside = (t >= t_start_s) & (t <= t_end_s) & (v > limit)
            if not inside.any():
                continue
            k = int(np.flatnonzero(inside)[np.argmax(v[inside])])
            ratio = v[k] / limit if limit > 0 else math.inf
            if best is None or ratio > best[0]:
                best = (ratio, MovingSample(quantity, float(t[k]), float(v[k])))
        return None if best is None else best[1]


def _runs(t: F64, v: F64, limit: float, quantity: Quantity) -> list[MovingInterval]:
    moving = v > limit
    edges = np.flatnonzero(np.diff(np.concatenate([[0], moving.astype(np.int8), [0]])))
    return [MovingInterval(quantity, float(t[a]), float(t[b - 1]), float(v[a:b].max()))
            for a, b in zip(edges[0::2], edges[1::2], strict=True)]


def moving_intervals(*, samples: MotionSamples,
                     thresholds: MotionThresholds) -> dict[MotionSource, list[MovingInterval]]:
    """Each source's moving time intervals (runs of samples above their threshold), in time order."""
    out: dict[MotionSource, list[MovingInterval]] = {}
    for quantity in Quantity:
        if quantity not in samples.times or (quantity is Quantity.IMAGE_CHANGE and not thresholds.images):
            continue
        t, v = samples.arrays(quantity)
        out.setdefault(quantity.source, []).extend(_runs(t, v, thresholds.limit(quantity), quantity))
    return {source: sorted(runs, key=lambda r: r.t_start_s) for source, runs in out.items()}


def intervals_yaml(intervals: dict[MotionSource, list[MovingInterval]]) -> dict[str, list[dict[str, Any]]]:
    """The moving intervals as bag.yaml records them."""
    return {source.value: [{"stamp_s": [r.t_start_s, r.t_end_s], "peak": r.peak, "unit": r.quantity.unit}
                           for r in runs] for source, runs in intervals.items()}


def describe_sources(samples: MotionSamples) -> list[str]:
    """"N imu samples" and the like, for the import's report."""
    counts = {q.source: len(times) for q, times in samples.times.items()}
    return [f"{n} {source.value} samples" for source, n in counts.items()]


@dataclass(frozen=True)
class MotionEvidence:
    """What :func:`rigd.importers.bag.stills.select_pairs` consults besides the LiDAR: the samples, their
    thresholds, and the recording's first stamp s (reasons give times from it)."""

    samples: MotionSamples
    thresholds: MotionThresholds
    origin_s: float = 0.0

    def moving_in(self, *, t_start_s: float, t_end_s: float) -> str | None:
        """Why ``t_start_s`` .. ``t_end_s`` was moving ("imu: 3.20 deg/s at 12.40 s"); None: no source says so."""
        sample = self.samples.strongest(t_start_s=t_start_s, t_end_s=t_end_s, thresholds=self.thresholds)
        return None if sample is None else sample.describe(origin_s=self.origin_s)
