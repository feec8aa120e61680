"""Panorama frames and the frame-source interface shared by the sdk, replay and sim backends."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass, field
from enum import Enum
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import CorruptFrameError

log = logging.getLogger(__name__)


class TimeBase(Enum):
    """What a frame's device time counts: the camera's own clock, or GPS time (PPS-locked Ladybug5+)."""

    CAMERA = "camera"
    GPS = "gps"


@dataclass(frozen=True)
class Exposure:
    """Exposure of a frame: physical values where the source knows them, else raw register values."""

    shutter_s: float | None = None
    gain_db: float | None = None
    shutter_raw: tuple[int, ...] = ()  # per camera, as stored in a .pgr frame header
    gain_raw: tuple[int, ...] = ()


@dataclass(frozen=True)
class PanoramaFrame:
    """One stitched frame.

    ``image`` (H, W, 3) uint8 BGR equirectangular (project convention); ``device_time_s`` the camera's
    (unwrapped) time in s; ``host_time_s`` the same instant on the host clock (None when the source cannot
    know it, e.g. a .pgr file); ``sequence_id`` the camera's frame counter.
    """

    image: NDArray[np.uint8]
    device_time_s: float
    host_time_s: float | None
    sequence_id: int
    exposure: Exposure
    time_base: TimeBase = TimeBase.CAMERA


class FrameSource(Protocol):
    """A stream of panorama frames; bad frames are skipped and counted in ``skipped``."""

    skipped: SkipCounter

    def frames(self) -> Iterator[PanoramaFrame]: ...

    def close(self) -> None: ...


@dataclass
class SkipCounter:
    """Counts frames dropped as corrupt and keeps the latest reasons (for status reports)."""

    count: int = 0
    reasons: list[str] = field(default_factory=list)
    keep: int = 20

    def record(self, error: CorruptFrameError) -> None:
        self.count += 1
        self.reasons = [*self.reasons, str(error)][-self.keep :]
        log.warning("skipped frame: %s", error)
