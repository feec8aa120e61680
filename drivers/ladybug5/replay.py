"""Replay frame sources: a directory of panoramas or of six camera images per frame, and .pgr streams.

Directory layout (docs/ladybug5.md, "Replay")::

    DIR/timestamps.csv     image,device_time_s,host_time_s,sequence_id[,shutter_s,gain_db]
    DIR/<image>            a panorama (2:1), or a directory holding the six camera images, or the start of
                           the six camera images' names in DIR (a flat export folder)

Camera images (:mod:`drivers.ladybug5.exports`) are rigd's cam0..cam5 or FLIR's exports named with the camera's
number, in sensor orientation or upright, raw or rectified; 1-channel images are Bayer mosaics when a pattern is
given, grey otherwise; 16-bit images keep their top 8 significant bits. ``host_time_s``, ``sequence_id``,
``shutter_s`` and ``gain_db`` may be empty; the sequence id then is the row number. Six-image frames go with a head
(a rig camera or head calibration file; rectified images with its rectified pinholes): they are stitched with it,
and ``frames_with_sensors()`` gives each panorama with its six sensor images and that head, as the live camera does.
What a directory holds is said once per kind (``layouts``, and the log when it is not rigd's own).
"""

from __future__ import annotations

import csv
import logging
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.clock import unwrap_times
from drivers.ladybug5.errors import CorruptFrameError, HeadCalibrationError, Ladybug5Error, StreamFormatError
from drivers.ladybug5.exports import ImageKind, find_camera_files, rectified_head, to_sensor_orientation
from drivers.ladybug5.formats import BayerPattern
from drivers.ladybug5.frames import Exposure, PanoramaFrame, SensorFrame, SkipCounter, TimeBase
from drivers.ladybug5.head import HeadCalibration, HeadSource
from drivers.ladybug5.pgr import DEFAULT_LAYOUT, PgrLayout, PgrStream
from drivers.ladybug5.raw import to_uint8
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher

TIMESTAMPS_FILE = "timestamps.csv"
log = logging.getLogger(__name__)
PARTIAL_FRAME_CAMERAS = 5  # a frame that lost one camera still makes a panorama (its view left to the overlaps)


@dataclass(frozen=True)
class _Row:
    line: int
    image: Path
    device_time_s: float
    host_time_s: float | None
    sequence_id: int
    exposure: Exposure


def _optional_float(value: str | None) -> float | None:
    return float(value) if value not in (None, "") else None


def read_timestamps(directory: Path) -> list[_Row]:
    """Parse ``DIR/timestamps.csv``; errors name the file and line."""
    path = Path(directory) / TIMESTAMPS_FILE
    try:
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            missing = {"image", "device_time_s"} - set(reader.fieldnames or ())
            if missing:
                raise StreamFormatError(f"{path}: missing column(s) {sorted(missing)}")
            rows = []
            for i, rec in enumerate(reader):
                try:
                    seq = rec.get("sequence_id")
                    rows.append(
                        _Row(
                            reader.line_num,
                            Path(directory) / rec["image"],
                            float(rec["device_time_s"]),
                            _optional_float(rec.get("host_time_s")),
                            int(seq) if seq not in (None, "") else i,
                            Exposure(_optional_float(rec.get("shutter_s")), _optional_float(rec.get("gain_db"))),
                        )
                    )
                except (TypeError, ValueError) as exc:
                    raise StreamFormatError(f"{path}: line {reader.line_num}: {exc}") from exc
    except OSError as exc:
        raise StreamFormatError(f"cannot read {path}: {exc}") from exc
    return rows


def _to_bgr8(image: NDArray[Any], bayer_pattern: BayerPattern | None, where: str) -> NDArray[np.uint8]:
    if image.dtype == np.uint16:
        image = to_uint8(image)
    if image.dtype != np.uint8:
        raise CorruptFrameError(f"{where}: unsupported pixel type {image.dtype}")
    if image.ndim == 2:
        return cast(NDArray[np.uint8],
                    cv2.cvtColor(image, bayer_pattern.to_bgr if bayer_pattern else cv2.COLOR_GRAY2BGR))
    if image.ndim == 3 and image.shape[2] == 3:
        return image
    raise CorruptFrameError(f"{where}: expected a 1- or 3-channel image, got shape {image.shape}")


def _read_image(path: Path, flags: int) -> NDArray[Any]:
    image = cv2.imread(str(path), flags)
    if image is None:
        raise CorruptFrameError(f"{path}: missing, unreadable or corrupt image")
    return image


class DirectoryFrameSource:
    """Frames from a replay directory (see the module docstring).

    ``stitcher``: a ready :class:`Stitcher`, whose rig is the head of six-image frames unless ``head`` is given; or
    a :class:`PanoramaSpec` (None: the default one), at which six-image frames are stitched from ``head`` (the
    stitcher is built at the first of them). ``head``: the calibration six-image frames go with (their sensors'
    sizes are checked against it). Panorama frames need neither.
    """

    def __init__(self, directory: Path, stitcher: Stitcher | PanoramaSpec | None = None,
                 bayer_pattern: BayerPattern | str | None = None, head: HeadCalibration | None = None) -> None:
        self.directory = Path(directory)
        self.stitcher: Stitcher | None = stitcher if isinstance(stitcher, Stitcher) else None
        self.spec = stitcher.spec if isinstance(stitcher, Stitcher) else stitcher or PanoramaSpec()
        if head is None and self.stitcher is not None:  # the stitcher's rig file is the head, as for a live camera
            head = HeadCalibration.from_rig(self.stitcher.rig, HeadSource.FILE, self.stitcher.rig.model)
        self.head = head
        self.bayer_pattern = BayerPattern(bayer_pattern) if isinstance(bayer_pattern, str) else bayer_pattern
        self.rows = read_timestamps(self.directory)
        self.skipped = SkipCounter()
        self.layouts: list[str] = []  # what the frames turned out to be, in the order met
        self._stitchers: dict[str, Stitcher] = {}

    def _say(self, layout: str) -> None:
        """Record what the directory holds, once per kind; a layout that is not rigd's own is also logged."""
        if layout not in self.layouts:
            self.layouts.append(layout)
            if "rigd's names" not in layout or "upright" in layout or "rectified" in layout:
                log.warning("replay %s: %s", self.directory, layout)

    def _panorama(self, row: _Row) -> NDArray[np.uint8]:
        image = _read_image(row.image, cv2.IMREAD_COLOR)
        if image.shape[1] != 2 * image.shape[0]:
            raise CorruptFrameError(f"{row.image}: a panorama must be 2:1, got {image.shape[1]}x{image.shape[0]}")
        self._say("panoramas (2:1 equirectangular, taken in rigd's convention: camera 0 at the centre column, "
                  "up at the top; docs/ladybug5.md)")
        return image

    def _sensor_images(self, row: _Row, head: HeadCalibration) -> tuple[list[NDArray[np.uint8]], HeadCalibration]:
        """A six-image frame's (H, W, 3) BGR uint8 images in sensor orientation and the head they go with (``head``,
        or its rectified pinholes for rectified images); sizes not the head's are a HeadCalibrationError."""
        files = find_camera_files(row.image)
        images, turned = [], set()
        for path, size in zip(files.paths, head.sizes, strict=True):
            image = _to_bgr8(_read_image(path, cv2.IMREAD_UNCHANGED), self.bayer_pattern, str(path))
            image, orientation = to_sensor_orientation(image, size, files.kind)
            images.append(image)
            turned.add(orientation)
        if files.kind is ImageKind.RECTIFIED:
            head = rectified_head(head, (images[0].shape[1], images[0].shape[0]))
        sizes = [(im.shape[1], im.shape[0]) for im in images]
        if sizes != list(head.sizes):  # every frame would fail alike: an error, not a skipped frame
            raise HeadCalibrationError(f"{row.image}: the head ({head.description}) is for sensors "
                                       f"{list(head.sizes)}, the images are {sizes}")
        way = "/".join(sorted(o.value for o in turned))
        self._say(f"six-image frames: {files.describe()}, {way} orientation; head: {head.summary()}")
        return images, head

    def _stitcher_for(self, head: HeadCalibration) -> Stitcher:
        if head is self.head and self.stitcher is not None:
            return self.stitcher
        if head.description not in self._stitchers:
            self._stitchers[head.description] = Stitcher(head.to_rig(), self.spec)
        return self._stitchers[head.description]

    def _frame(self, row: _Row) -> tuple[PanoramaFrame, SensorFrame | None]:
        times = (row.device_time_s, row.host_time_s, row.sequence_id, row.exposure)
        if row.image.is_file() or not (row.image.is_dir() or any(row.image.parent.glob(f"{row.image.name}*"))):
            return PanoramaFrame(self._panorama(row), *times), None
        if self.head is None:
            raise StreamFormatError(f"{row.image}: six-camera frames need the head they go with (a rig camera file "
                                    "or head calibration file) to stitch them")
        images, head = self._sensor_images(row, self.head)
        if head is self.head and self.stitcher is None:
            self.stitcher = Stitcher(self.head.to_rig(), self.spec)
        pano = PanoramaFrame(self._stitcher_for(head).stitch(images), *times)
        return pano, SensorFrame(tuple(images), head, *times)

    def frames_with_sensors(self) -> Iterator[tuple[PanoramaFrame, SensorFrame | None]]:
        """Each panorama with, for a six-image frame, its sensor images and head (the head dataset's images);
        None beside a panorama frame."""
        for row in self.rows:
            try:
                frame = self._frame(row)
            except CorruptFrameError as exc:
                self.skipped.record(exc)
                continue
            yield frame

    def frames(self) -> Iterator[PanoramaFrame]:
        for pano, _ in self.frames_with_sensors():
            yield pano

    def close(self) -> None:
        """Nothing is held open between frames."""


class PgrFrameSource:
    """Frames of a .pgr stream, stitched; device time from the frame headers, host time unknown (None).

    ``wrap_period_s`` unwraps a device clock that wraps (e.g. 128 s cycle time); ``time_base`` says
    whether the camera was PPS-locked (GPS time) when the stream was recorded. A frame with at least
    ``min_cameras`` cameras whose channel JPEGs decode is stitched from those (counted in ``skipped.partial``, its
    bad channels in ``skipped.channels``); one with fewer is skipped.
    """

    def __init__(
        self,
        path: Path,
        stitcher: Stitcher,
        layout: PgrLayout = DEFAULT_LAYOUT,
        wrap_period_s: float | None = None,
        time_base: TimeBase = TimeBase.CAMERA,
        min_cameras: int = PARTIAL_FRAME_CAMERAS,
    ) -> None:
        self.stream = PgrStream(path, layout)
        self.min_cameras = min_cameras
        try:  # a format rigd cannot decode, or no Bayer pattern, is said now rather than at every frame
            self.stream.data_format()
            self.stream.bayer_pattern()
        except Ladybug5Error:
            self.stream.close()
            raise
        self.stitcher = stitcher
        self.time_base = time_base
        raw = np.array([e.device_time_s for e in self.stream.index])
        self.device_times_s = unwrap_times(raw, wrap_period_s) if wrap_period_s else raw
        self.skipped = SkipCounter()

    def frames(self) -> Iterator[PanoramaFrame]:
        for damage in self.stream.damaged:
            self.skipped.record(CorruptFrameError(damage))
        for entry, device_s in zip(self.stream.index, self.device_times_s, strict=True):
            try:
                cameras = self.stream.frame_images(entry.index, self.min_cameras)
            except CorruptFrameError as exc:
                self.skipped.record(exc)
                continue
            if cameras.faults:
                self.skipped.record_partial(f"{self.stream.path}: frame {entry.index}", cameras.faults)
            pano = self.stitcher.stitch([None if im is None else to_uint8(im) for im in cameras.arrays])
            yield PanoramaFrame(pano, float(device_s), None, entry.sequence_id, entry.exposure, self.time_base)

    def close(self) -> None:
        self.stream.close()
