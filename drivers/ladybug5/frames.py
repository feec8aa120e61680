"""Frames and the frame-source interfaces shared by the sdk, replay and sim backends: stitched panoramas
(:class:`PanoramaFrame`) and the six raw sensor images with the head calibration (:class:`SensorFrame`)."""

from __future__ import annotations

import logging
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import Ladybug5Error
from drivers.ladybug5.head import HeadCalibration

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


@dataclass(frozen=True)
class SensorFrame:
    """One frame as the six sensors saw it, for the head dataset format (docs/dataset.md).

    ``images``: six (H, W, 3) BGR images in raw sensor orientation, border-cropped, uint8 (uint16 from a RAW16
    camera), in the SDK's order (0-4 around, 5 up); ``head``: the calibration they go with (check
    ``head.source``: a factory calibration, or rigd's nominal head). Times as in :class:`PanoramaFrame`.
    ``missing_cameras``: cameras whose channel JPEGs did not decode (their images zero); only from a source asked
    for such frames to make panoramas, never from one that feeds a head dataset.
    """

    images: tuple[NDArray[Any], ...]
    head: HeadCalibration
    device_time_s: float
    host_time_s: float | None
    sequence_id: int
    exposure: Exposure
    time_base: TimeBase = TimeBase.CAMERA
    missing_cameras: tuple[int, ...] = ()


class SensorFrameSource(Protocol):
    """A stream of :class:`SensorFrame`; frames that fail are skipped and counted in ``skipped``."""

    skipped: SkipCounter

    def frames(self) -> Iterator[SensorFrame]: ...

    def close(self) -> None: ...


class FrameSource(Protocol):
    """A stream of panorama frames; bad frames are skipped and counted in ``skipped``."""

    skipped: SkipCounter

    def frames(self) -> Iterator[PanoramaFrame]: ...

    def close(self) -> None: ...


@dataclass
class SkipCounter:
    """Counts frames dropped (corrupt, a failed grab, a failed stitch; or, as ``exposure_errors`` of the SDK
    sources, failed exposure reads) and keeps the latest reasons (for status reports). ``partial`` counts frames
    kept without some camera and ``channels`` the channel JPEGs dropped in them (:meth:`record_partial`)."""

    count: int = 0
    reasons: list[str] = field(default_factory=list)
    keep: int = 20
    partial: int = 0
    channels: int = 0

    def record(self, error: Ladybug5Error) -> None:
        self.count += 1
        self._reason(str(error))
        log.warning("skipped frame: %s", error)

    def record_partial(self, where: str, faults: Sequence[object]) -> None:
        """A frame kept although ``faults`` (each naming a camera's channel) lost it a camera."""
        self.partial += 1
        self.channels += len(faults)
        reason = f"{where}: kept without a camera: " + "; ".join(str(f) for f in faults)
        self._reason(reason)
        log.warning("%s", reason)

    def _reason(self, reason: str) -> None:
        self.reasons = [*self.reasons, reason][-self.keep :]
