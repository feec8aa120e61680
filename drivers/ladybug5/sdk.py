"""Thin ctypes binding to FLIR's Ladybug SDK (libladybug), the only documented way to stream a Ladybug5.

The SDK is proprietary and not redistributable: rigd neither ships nor downloads it. With it installed,
:class:`SdkCamera` finds the cameras on the bus (``ladybugBusEnumerateCameras``, before initialising, as FLIR's
examples do), opens the one asked for (``ladybugInitializeFromSerialNumber``, or ``...FromIndex`` when there is
only one), loads its configuration (``ladybugLoadConfig``), reads its Bayer tile format
(``ladybugGetColorTileFormat``), sets a grab timeout (``ladybugSetGrabTimeout``) and starts it
(``ladybugStart``); it grabs (``ladybugGrabImage``), reads exposure (``ladybugGetAbsProperty``) and the factory
head calibration (:mod:`drivers.ladybug5.sdk_head`), and stops and destroys the context.

Every number the binding needs from the SDK's headers comes from ``layout_probe.c`` (:mod:`sdk_layout`).
Grabbed RAW8, RAW12, RAW16, COLOR_SEP_JPEG8 and COLOR_SEP_JPEG12 buffers are decoded here (slicing by the full
sensor size, border crop, the SDK's Bayer pattern); other formats are named as unsupported. The frame sources are in
:mod:`drivers.ladybug5.sdk_source`.
"""

from __future__ import annotations

import ctypes
import logging
import time
from enum import Enum
from pathlib import Path
from typing import Any, cast

from drivers.ladybug5.errors import (
    CameraNotFoundError,
    CorruptFrameError,
    HeadCalibrationError,
    Ladybug5Error,
    SdkError,
)
from drivers.ladybug5.formats import BayerPattern, DataFormat, require_decoded
from drivers.ladybug5.frames import Exposure
from drivers.ladybug5.head import HeadCalibration
from drivers.ladybug5.pgr import DEFAULT_LAYOUT, CameraSet, PgrLayout, frame_block_mosaics
from drivers.ladybug5.raw import NUM_SENSORS, SensorGeometry, decode_raw, demosaic, fit_mosaic
from drivers.ladybug5.sdk_head import DEFAULT_MAP_STEP_PX, LensSource, read_head
from drivers.ladybug5.sdk_layout import PROBE_SOURCE, SdkLayout, probe_layout
from drivers.ladybug5.sdk_library import (
    DEFAULT_LIBRARY,
    CameraInfo,
    GrabbedImage,
    LadybugLibrary,
    sdk_status,
)

__all__ = [
    "DEFAULT_GRAB_TIMEOUT_MS", "DEFAULT_LIBRARY", "PROBE_SOURCE", "CameraInfo", "DataFormat", "DeviceTimeField",
    "GrabbedImage", "LadybugLibrary", "SdkCamera", "SdkLayout", "decode_grab", "decode_grab_cameras",
    "enumerate_cameras", "frame_pattern",
    "probe_layout", "read_camera_head", "sdk_status",
]

log = logging.getLogger(__name__)
CYCLE_PERIOD_S = 128.0  # the cycle-time seconds counter has 7 bits
DEFAULT_GRAB_TIMEOUT_MS = 2000  # a Ladybug5 sends 10-30 frames/s: 2 s without one is a stalled camera
_MAX_CAMERAS = 16
_SIZE_GRABS = 10  # frames tried to learn the sensor size


class DeviceTimeField(Enum):
    """Which stamp is the frame's device time: the cycle time (wraps every 128 s) or the image header's
    embedded seconds/microseconds (GPS time when a Ladybug5+ is PPS-locked)."""

    CYCLE = "cycle"
    EMBEDDED = "embedded"


def _enumerate(lib: LadybugLibrary, context: ctypes.c_void_p) -> list[CameraInfo]:
    buf = ctypes.create_string_buffer(lib.layout.camera_info_size * _MAX_CAMERAS)
    size = ctypes.c_uint(_MAX_CAMERAS)
    lib.call("ladybugBusEnumerateCameras", context, buf, ctypes.byref(size))
    return lib.read_camera_infos(buf, min(size.value, _MAX_CAMERAS))


def enumerate_cameras(lib: LadybugLibrary) -> list[CameraInfo]:
    """The Ladybug cameras the SDK sees on the bus (serial, model), through a context of its own."""
    context = ctypes.c_void_p()
    lib.call("ladybugCreateContext", ctypes.byref(context))
    try:
        return _enumerate(lib, context)
    finally:
        lib.call("ladybugDestroyContext", ctypes.byref(context))


def _select(cameras: list[CameraInfo], serial: int | None) -> CameraInfo:
    """The camera to open: the one with ``serial``, or the only one."""
    serials = ", ".join(str(c.serial) for c in cameras) or "none"
    if not cameras:
        raise CameraNotFoundError("the Ladybug SDK sees no camera on the bus (ladybugBusEnumerateCameras): check "
                                  "the USB 3 cable and the 12-24 V power; rigd camera info")
    if serial is not None:
        match = [c for c in cameras if c.serial == serial]
        if not match:
            raise CameraNotFoundError(f"Ladybug camera {serial} is not on the bus; the SDK sees {serials}")
        return match[0]
    if len(cameras) > 1:
        raise CameraNotFoundError(f"the Ladybug SDK sees {len(cameras)} cameras ({serials}): choose one (--serial)")
    return cameras[0]


class SdkCamera:
    """One camera's SDK lifecycle: open() = create, enumerate, initialise, load config, read the Bayer tile
    format, set the grab timeout, start; close() = stop, destroy. ``serial`` None opens the only camera;
    ``config_path`` None loads the configuration from the head; ``grab_timeout_ms`` bounds every grab."""

    def __init__(self, library: LadybugLibrary, serial: int | None = None, config_path: Path | None = None,
                 data_format: DataFormat = DataFormat.COLOR_SEP_JPEG8,
                 grab_timeout_ms: int = DEFAULT_GRAB_TIMEOUT_MS) -> None:
        self.lib = library
        self.serial = serial
        self.config_path = config_path
        self.data_format = require_decoded(data_format, "SdkCamera")
        self.grab_timeout_ms = grab_timeout_ms
        self.info: CameraInfo | None = None
        self.tile_pattern: BayerPattern | None = None
        self.last: GrabbedImage | None = None  # the latest grab (its LadybugImage is still in the image buffer)
        self._context = ctypes.c_void_p()
        self._started = False
        self._image = library.new_image_buffer()

    @property
    def describe(self) -> str:
        return f"camera {self.info.serial} ({self.info.model})" if self.info else f"camera {self.serial or '?'}"

    def open(self) -> SdkCamera:
        self.lib.call("ladybugCreateContext", ctypes.byref(self._context))
        try:
            self.info = _select(_enumerate(self.lib, self._context), self.serial)
            self._initialise(self.info)
            config = str(self.config_path).encode() if self.config_path else None
            self.lib.call("ladybugLoadConfig", self._context, config)
            self.tile_pattern = self._read_tile_pattern()
            self.lib.call("ladybugSetGrabTimeout", self._context, self.grab_timeout_ms)  # before start (SDK docs)
            self.lib.call("ladybugStart", self._context, self.lib.layout.formats[self.data_format.value])
            self._started = True
        except Ladybug5Error:
            self.close()
            raise
        return self

    def _initialise(self, info: CameraInfo) -> None:
        try:
            if self.serial is not None:
                self.lib.call("ladybugInitializeFromSerialNumber", self._context, info.serial)
            else:
                self.lib.call("ladybugInitializeFromIndex", self._context, 0)  # the only camera on the bus
        except SdkError as exc:
            raise CameraNotFoundError(f"the Ladybug SDK cannot open camera {info.serial} ({info.model}): {exc}") \
                from exc

    def _read_tile_pattern(self) -> BayerPattern | None:
        """The camera's Bayer pattern (ladybugGetColorTileFormat); None when the SDK does not say."""
        value = ctypes.c_int()
        try:
            self.lib.call("ladybugGetColorTileFormat", self._context, ctypes.byref(value))
        except SdkError as exc:  # the pattern is also in every LadybugImage: not a reason to refuse the camera
            log.warning("%s: no colour tile format: %s", self.describe, exc)
            return None
        return _pattern_of(self.lib, value.value)

    def _require_started(self, what: str) -> None:
        if not self._started:  # never hand the SDK a null context
            raise Ladybug5Error(f"{what}: {self.describe} is not open (call open() first)")

    def grab(self) -> GrabbedImage:
        self._require_started("grab")
        self.last = None
        self.lib.call("ladybugGrabImage", self._context, self._image)
        self.last = self.lib.read_image(self._image, time.time())
        return self.last

    def sdk_handles(self, what: str) -> tuple[ctypes.c_void_p, ctypes.Array[ctypes.c_char]]:
        """The open context and the LadybugImage of the latest grab, for SDK calls made outside this class (the
        panorama renderer, :mod:`drivers.ladybug5.sdk_render`)."""
        self._require_started(what)
        return self._context, self._image

    def exposure(self) -> Exposure:
        """Shutter (the SDK reports ms) and gain (dB) from ladybugGetAbsProperty; raises SdkError on a failure."""
        self._require_started("exposure")
        values = []
        for name in ("SHUTTER", "GAIN"):
            value = ctypes.c_float()
            self.lib.call("ladybugGetAbsProperty", self._context, self.lib.layout.properties[name],
                          ctypes.byref(value))
            values.append(float(value.value))
        return Exposure(shutter_s=values[0] * 1e-3, gain_db=values[1])

    def sensor_size(self) -> tuple[int, int]:
        """The sensors' useful (width, height) px, from the first of ``_SIZE_GRABS`` frames that arrives."""
        last: Ladybug5Error | None = None
        for _ in range(_SIZE_GRABS):
            try:
                image = self.grab()
            except (CorruptFrameError, SdkError) as exc:  # a bad frame or a timeout: try the next one
                last = exc
                continue
            return image.cols, image.rows
        raise HeadCalibrationError(f"{self.describe}: no frame in {_SIZE_GRABS} grabs to learn the sensor size "
                                   f"({last})")

    def read_head(self, size_px: tuple[int, int], step_px: int = DEFAULT_MAP_STEP_PX,
                  lens: LensSource = LensSource.AUTO) -> HeadCalibration:
        """The factory calibration the SDK loaded for this camera; ``size_px`` the sensors' raw (width, height)."""
        self._require_started("read_head")
        where = "from the head" if self.config_path is None else f"from {self.config_path}"
        serial = self.info.serial if self.info else None
        return read_head(self.lib, self._context, size_px, f"{self.describe}, ladybugLoadConfig {where}", serial,
                         step_px, lens)

    def close(self) -> None:
        """Stop and destroy, in that order, whatever was set up; safe to call twice."""
        try:
            if self._started:
                self._started = False
                self.lib.call("ladybugStop", self._context)
        finally:
            if self._context.value:
                self.lib.call("ladybugDestroyContext", ctypes.byref(self._context))
                self._context = ctypes.c_void_p()

    def __enter__(self) -> SdkCamera:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_camera_head(lib: LadybugLibrary, serial: int | None = None, size_px: tuple[int, int] | None = None,
                     step_px: int = DEFAULT_MAP_STEP_PX, lens: LensSource = LensSource.AUTO) -> HeadCalibration:
    """Open a camera (``serial``, or the only one; RAW8: nothing to decode), learn its sensor size from a frame
    unless given, read its factory head calibration, close it."""
    with SdkCamera(lib, serial=serial, data_format=DataFormat.RAW8) as camera:
        return camera.read_head(size_px or camera.sensor_size(), step_px, lens)


def _pattern_of(lib: LadybugLibrary, value: int) -> BayerPattern | None:
    """The Bayer pattern of an SDK stippled-format value; None for LADYBUG_DEFAULT or an unknown value."""
    name = next((n for n, v in lib.layout.stippled.items() if v == value), None)
    return BayerPattern(name) if name in BayerPattern.__members__ else None


def frame_pattern(image: GrabbedImage, lib: LadybugLibrary, tile: BayerPattern | None,
                  override: BayerPattern | None = None) -> BayerPattern:
    """The Bayer pattern of a grabbed frame: an explicit override, else the image's ``stippledFormat``, else the
    camera's colour tile format; an error naming the values when none says."""
    pattern = override or _pattern_of(lib, image.stippled_format) or tile
    if pattern is None:
        raise Ladybug5Error(f"grabbed frame {image.sequence_id}: the SDK reports no Bayer pattern (stippledFormat "
                            f"{image.stippled_format}, no colour tile format); give one (bayer_pattern)")
    return pattern


def decode_grab_cameras(image: GrabbedImage, layout: SdkLayout, pattern: BayerPattern,
                        pgr_layout: PgrLayout = DEFAULT_LAYOUT, min_cameras: int = NUM_SENSORS) -> CameraSet:
    """The six (rows, cols, 3) BGR images of a grab (raw sensor orientation, border-cropped; uint8, or uint16 with the
    significant bits at the top for RAW12, RAW16 and COLOR_SEP_JPEG12); a camera whose channel JPEGs do not decode
    is None with its faults named. Fewer than ``min_cameras`` cameras: a CorruptFrameError naming the faults."""
    where = f"grabbed frame {image.sequence_id}"
    name = layout.format_name(image.data_format)
    if name is None or name not in DataFormat.__members__:
        raise CorruptFrameError(f"{where}: data format value {image.data_format} is none of the SDK's formats")
    fmt = require_decoded(DataFormat(name), where)
    geometry = SensorGeometry.from_full(image.full_cols, image.full_rows, image.border, where)
    if (geometry.cols, geometry.rows) != (image.cols, image.rows):
        raise CorruptFrameError(f"{where}: {image.full_cols}x{image.full_rows} minus border {image.border} is not "
                                f"the {image.cols}x{image.rows} the frame says")
    if not fmt.jpeg_bits:
        return CameraSet(tuple(decode_raw(image.data, fmt, geometry, pattern, where, pgr_layout.raw16_bits)))
    mosaics = frame_block_mosaics(image.data, pgr_layout, where, fmt.jpeg_bits, min_cameras)
    return CameraSet(tuple(None if m is None else demosaic(*fit_mosaic(m, geometry, pattern, f"{where} camera {c}"))
                           for c, m in enumerate(mosaics.arrays)), mosaics.faults)


def decode_grab(image: GrabbedImage, layout: SdkLayout, pattern: BayerPattern,
                pgr_layout: PgrLayout = DEFAULT_LAYOUT) -> list[Any]:
    """All six images of a grab (:func:`decode_grab_cameras`); a camera missing is a CorruptFrameError."""
    return [cast(Any, im) for im in decode_grab_cameras(image, layout, pattern, pgr_layout).arrays]
