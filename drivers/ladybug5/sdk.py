"""Thin ctypes binding to FLIR's Ladybug SDK (libladybug), the only documented way to stream a Ladybug5.

The SDK is proprietary and not redistributable: rigd neither ships nor downloads it. With it installed,
this module opens the camera (ladybugCreateContext, ladybugInitializeFromIndex, ladybugLoadConfig,
ladybugStart), grabs frames (ladybugGrabImage) and closes it (ladybugStop, ladybugDestroyContext).

Every number this needs from the SDK's header -- the LadybugImage layout, error codes, data-format and
property values -- differs between SDK versions, so none is written here: ``layout_probe.c`` is compiled
against the installed ladybug.h (:func:`probe_layout`, ``rigd camera sdk-layout``) and its YAML output is
the :class:`SdkLayout` the binding uses. Grabbed RAW8 and COLOR_SEP_JPEG8 buffers are decoded here (no
SDK image processing); other formats need the SDK's own conversion and are refused.
"""

from __future__ import annotations

import ctypes
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray

from drivers.ladybug5.clock import ClockSync
from drivers.ladybug5.errors import (
    CameraNotFoundError,
    CorruptFrameError,
    InterfaceSpeedError,
    Ladybug5Error,
    LibraryMissingError,
    MissingPowerError,
    SdkError,
)
from drivers.ladybug5.frames import Exposure, PanoramaFrame, SkipCounter, TimeBase
from drivers.ladybug5.pgr import BAYER_TO_BGR, DEFAULT_LAYOUT, NUM_CAMERAS, PgrLayout, frame_block_images
from drivers.ladybug5.stitch import Stitcher

DEFAULT_LIBRARY = "libladybug.so"
PROBE_SOURCE = Path(__file__).with_name("layout_probe.c")
CYCLE_PERIOD_S = 128.0  # the cycle-time seconds counter has 7 bits
CYCLES_PER_SECOND = 8000  # 125 us cycle ticks
_FUNCTIONS = (
    "ladybugCreateContext",
    "ladybugBusEnumerateCameras",
    "ladybugInitializeFromIndex",
    "ladybugLoadConfig",
    "ladybugStart",
    "ladybugGrabImage",
    "ladybugGetAbsProperty",
    "ladybugStop",
    "ladybugDestroyContext",
    "ladybugErrorToString",
)
_CORRUPT_FRAME_ERRORS = (
    "IMAGE_TOO_SMALL",
    "JPEG_ERROR",
    "JPEG_HEADER_ERROR",
    "JPEG_INCOMPLETE_COMPRESSION",
    "JPEG_NO_IMAGE",
    "CORRUPTED_IMAGE_DATA",
)


class DataFormat(Enum):
    RAW8 = "RAW8"  # six Bayer images, one after the other
    COLOR_SEP_JPEG8 = "COLOR_SEP_JPEG8"  # a frame block with 24 JPEGs, as in a .pgr file


class DeviceTimeField(Enum):
    """Which stamp is the frame's device time: the cycle time (wraps every 128 s) or the image header's
    embedded seconds/microseconds (GPS time when a Ladybug5+ is PPS-locked)."""

    CYCLE = "cycle"
    EMBEDDED = "embedded"


@dataclass(frozen=True)
class SdkLayout:
    """What layout_probe.c measured in ladybug.h; fields map name -> (offset, size) in bytes."""

    image_size: int
    image_fields: dict[str, tuple[int, int]]
    camera_info_size: int
    camera_info_fields: dict[str, tuple[int, int]]
    errors: dict[str, int]
    formats: dict[str, int]
    properties: dict[str, int]

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> SdkLayout:
        try:
            return cls(
                int(data["image_size"]),
                {str(k): (int(v[0]), int(v[1])) for k, v in data["image_fields"].items()},
                int(data["camera_info_size"]),
                {str(k): (int(v[0]), int(v[1])) for k, v in data["camera_info_fields"].items()},
                {str(k): int(v) for k, v in data["errors"].items()},
                {str(k): int(v) for k, v in data["formats"].items()},
                {str(k): int(v) for k, v in data["properties"].items()},
            )
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise Ladybug5Error(f"{where}: not a Ladybug SDK layout from layout_probe.c ({exc!r})") from exc

    @classmethod
    def load(cls, path: Path) -> SdkLayout:
        try:
            return cls.from_yaml(yaml.safe_load(Path(path).read_text()), str(path))
        except (OSError, yaml.YAMLError) as exc:
            raise Ladybug5Error(f"cannot read SDK layout file {path}: {exc}") from exc


def probe_layout(include_dir: Path, compiler: str = "c++", out: Path | None = None) -> SdkLayout:
    """Compile and run layout_probe.c against ``include_dir``/ladybug.h; optionally save the YAML."""
    with tempfile.TemporaryDirectory() as tmp:
        exe = Path(tmp) / "ladybug_layout_probe"
        cmd = [compiler, "-I", str(include_dir), "-o", str(exe), str(PROBE_SOURCE)]
        try:
            build = subprocess.run(cmd, capture_output=True, text=True, check=False)
        except OSError as exc:
            raise Ladybug5Error(f"cannot run compiler {compiler!r}: {exc}") from exc
        if build.returncode != 0:
            raise Ladybug5Error(
                f"layout_probe.c does not compile against {include_dir}/ladybug.h "
                f"(is that the Ladybug SDK's include directory?):\n{build.stderr[-2000:]}"
            )
        text = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout
    if out is not None:
        Path(out).write_text(text)
    return SdkLayout.from_yaml(yaml.safe_load(text), f"output of {PROBE_SOURCE.name}")


@dataclass(frozen=True)
class GrabbedImage:
    """The fields rigd reads from a LadybugImage, with the pixel buffer copied out of the SDK."""

    cols: int
    rows: int
    cycle_time_s: float
    embedded_time_s: float
    sequence_id: int
    data_format: int
    data: bytes
    host_receive_s: float  # host clock right after ladybugGrabImage returned (before copying the pixels)


def _read_uint(buf: ctypes.Array[ctypes.c_char], field: tuple[int, int]) -> int:
    offset, size = field
    return int.from_bytes(buf.raw[offset : offset + size], sys.byteorder)


class LadybugLibrary:
    """The loaded SDK library: one checked Python method per C function used."""

    def __init__(self, layout: SdkLayout, library: str | Path = DEFAULT_LIBRARY) -> None:
        self.layout = layout
        self.name = str(library)
        try:
            self._lib = ctypes.CDLL(self.name)
        except OSError as exc:
            raise LibraryMissingError(
                f"cannot load the Ladybug SDK library {self.name!r} ({exc}); it comes only with FLIR's "
                "Ladybug SDK (not on PyPI): install the SDK, or set its path (--sdk-library)"
            ) from exc
        missing = [f for f in _FUNCTIONS if not hasattr(self._lib, f)]
        if missing:
            raise LibraryMissingError(f"{self.name} lacks {', '.join(missing)}: not a Ladybug SDK library")
        self._lib.ladybugErrorToString.restype = ctypes.c_char_p
        for name in _FUNCTIONS[:-1]:
            getattr(self._lib, name).restype = ctypes.c_int

    def error_text(self, code: int) -> str:
        text = self._lib.ladybugErrorToString(ctypes.c_int(code))
        return text.decode(errors="replace") if text else "no description"

    def check(self, function: str, code: int) -> None:
        """Raise the named error for an SDK error code (codes come from the probed layout)."""
        if code == self.layout.errors["OK"]:
            return
        text = self.error_text(code)
        errors = self.layout.errors
        if code == errors.get("BAD_VOLTAGE"):
            raise MissingPowerError(
                f"{function}: the camera reports bad voltage ({text}); a Ladybug5+ needs 12-24 V on its GPIO connector"
            )
        if code == errors.get("BAD_INTERFACE"):
            raise InterfaceSpeedError(f"{function}: the camera is not on a USB 3 SuperSpeed link ({text})")
        if code in {errors[name] for name in _CORRUPT_FRAME_ERRORS if name in errors}:
            raise CorruptFrameError(f"{function}: {text} (Ladybug error {code})")
        raise SdkError(function, code, text)

    def call(self, function: str, *args: Any) -> None:
        self.check(function, getattr(self._lib, function)(*args))

    def new_image_buffer(self) -> ctypes.Array[ctypes.c_char]:
        return ctypes.create_string_buffer(self.layout.image_size)

    def read_image(self, buf: ctypes.Array[ctypes.c_char], host_receive_s: float) -> GrabbedImage:
        fields = self.layout.image_fields

        def field(name: str) -> int:
            return _read_uint(buf, fields[name])

        size = field("data_size")
        pointer = field("data")
        if not pointer:
            raise CorruptFrameError("ladybugGrabImage returned an image without pixel data")
        return GrabbedImage(
            cols=field("cols"),
            rows=field("rows"),
            cycle_time_s=field("cycle_seconds") + field("cycle_count") / CYCLES_PER_SECOND,
            embedded_time_s=field("embedded_seconds") + field("embedded_microseconds") * 1e-6,
            sequence_id=field("sequence_id"),
            data_format=field("data_format"),
            data=ctypes.string_at(pointer, size),
            host_receive_s=host_receive_s,
        )


def sdk_status(library: str | Path = DEFAULT_LIBRARY) -> str:
    """One line for ``rigd camera info``: whether the SDK library loads (no layout needed to tell)."""
    try:
        lib = ctypes.CDLL(str(library))
    except OSError as exc:
        return f"not available ({exc}); streaming needs FLIR's Ladybug SDK, replay and stitching do not"
    missing = [f for f in _FUNCTIONS if not hasattr(lib, f)]
    return f"{library} loads but lacks {', '.join(missing)}" if missing else f"{library} loads"


class SdkCamera:
    """One camera's SDK lifecycle: open() = create, initialise, load config, start; close() = stop, destroy."""

    def __init__(
        self,
        library: LadybugLibrary,
        index: int = 0,
        config_path: Path | None = None,
        data_format: DataFormat = DataFormat.COLOR_SEP_JPEG8,
    ) -> None:
        self.lib = library
        self.index = index
        self.config_path = config_path
        self.data_format = data_format
        self._context = ctypes.c_void_p()
        self._started = False
        self._image = library.new_image_buffer()

    def enumerate_serials(self) -> list[int]:
        """Head serial numbers of the cameras the SDK sees on the bus (needs an open camera)."""
        self._require_started("enumerate_serials")
        info = self.lib.layout
        capacity = 16
        buf = ctypes.create_string_buffer(info.camera_info_size * capacity)
        size = ctypes.c_uint(capacity)
        self.lib.call("ladybugBusEnumerateCameras", self._context, buf, ctypes.byref(size))
        serial = info.camera_info_fields["serial_head"]
        return [
            int.from_bytes(buf.raw[i * info.camera_info_size + serial[0] :][: serial[1]], sys.byteorder)
            for i in range(min(size.value, capacity))
        ]

    def open(self) -> SdkCamera:
        self.lib.call("ladybugCreateContext", ctypes.byref(self._context))
        try:
            try:
                self.lib.call("ladybugInitializeFromIndex", self._context, ctypes.c_uint(self.index))
            except SdkError as exc:
                raise CameraNotFoundError(f"the Ladybug SDK cannot open camera {self.index}: {exc}") from exc
            config = str(self.config_path).encode() if self.config_path else None
            self.lib.call("ladybugLoadConfig", self._context, ctypes.c_char_p(config))
            fmt = self.lib.layout.formats[self.data_format.value]
            self.lib.call("ladybugStart", self._context, ctypes.c_int(fmt))
            self._started = True
        except Ladybug5Error:
            self.close()
            raise
        return self

    def _require_started(self, what: str) -> None:
        if not self._started:  # never hand the SDK a null context
            raise Ladybug5Error(f"{what}: camera {self.index} is not open (call open() first)")

    def grab(self) -> GrabbedImage:
        self._require_started("grab")
        self.lib.call("ladybugGrabImage", self._context, self._image)
        return self.lib.read_image(self._image, time.time())

    def exposure(self) -> Exposure:
        """Shutter (the SDK reports ms) and gain (dB) from ladybugGetAbsProperty."""
        self._require_started("exposure")
        values = []
        for name in ("SHUTTER", "GAIN"):
            value = ctypes.c_float()
            prop = ctypes.c_int(self.lib.layout.properties[name])
            self.lib.call("ladybugGetAbsProperty", self._context, prop, ctypes.byref(value))
            values.append(float(value.value))
        return Exposure(shutter_s=values[0] * 1e-3, gain_db=values[1])

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


def decode_grab(
    image: GrabbedImage, layout: SdkLayout, bayer_pattern: str, pgr_layout: PgrLayout
) -> list[NDArray[np.uint8]]:
    """Six BGR images (raw sensor orientation) from a grabbed buffer."""
    where = f"grabbed frame {image.sequence_id}"
    if image.data_format == layout.formats["RAW8"]:
        expected = NUM_CAMERAS * image.rows * image.cols
        if len(image.data) < expected:
            raise CorruptFrameError(f"{where}: RAW8 buffer has {len(image.data)} bytes, six images need {expected}")
        mosaics = np.frombuffer(image.data, np.uint8, expected).reshape(NUM_CAMERAS, image.rows, image.cols)
        return [cast(NDArray[np.uint8], cv2.cvtColor(m, BAYER_TO_BGR[bayer_pattern])) for m in mosaics]
    if image.data_format == layout.formats["COLOR_SEP_JPEG8"]:
        return frame_block_images(image.data, pgr_layout, where)
    raise Ladybug5Error(
        f"{where}: data format {image.data_format} needs the SDK's own image processing; start the camera in RAW8 "
        "or COLOR_SEP_JPEG8"
    )


class SdkFrameSource:
    """Live panoramas from the SDK: grab, decode, stitch, map camera time to host time.

    Corrupt frames (the SDK's JPEG/corruption errors, undecodable buffers) are skipped and counted;
    ``max_consecutive_failures`` failed grabs in a row (timeouts included) end the stream with the error.
    """

    def __init__(
        self,
        camera: SdkCamera,
        stitcher: Stitcher,
        bayer_pattern: str = "BGGR",
        pgr_layout: PgrLayout = DEFAULT_LAYOUT,
        time_field: DeviceTimeField = DeviceTimeField.CYCLE,
        max_consecutive_failures: int = 30,
    ) -> None:
        self.camera = camera
        self.stitcher = stitcher
        self.bayer_pattern = bayer_pattern
        self.pgr_layout = pgr_layout
        self.time_field = time_field
        self.max_failures = max_consecutive_failures
        cycle = time_field is DeviceTimeField.CYCLE
        self.clock = ClockSync(
            wrap_period_s=CYCLE_PERIOD_S if cycle else None, time_base=TimeBase.CAMERA if cycle else TimeBase.GPS
        )
        self.skipped = SkipCounter()

    def _grab_and_decode(self) -> tuple[GrabbedImage, list[NDArray[np.uint8]]]:
        image = self.camera.grab()
        return image, decode_grab(image, self.camera.lib.layout, self.bayer_pattern, self.pgr_layout)

    def frames(self) -> Iterator[PanoramaFrame]:
        failures = 0
        with self.camera:
            while True:
                try:
                    image, images = self._grab_and_decode()
                except (CorruptFrameError, SdkError) as exc:
                    failures += 1
                    if failures >= self.max_failures:
                        raise
                    if isinstance(exc, CorruptFrameError):
                        self.skipped.record(exc)
                    continue
                failures = 0
                raw = image.cycle_time_s if self.time_field is DeviceTimeField.CYCLE else image.embedded_time_s
                device_s = self.clock.add(raw, image.host_receive_s)
                pano = self.stitcher.stitch(images)
                yield PanoramaFrame(
                    pano,
                    device_s,
                    self.clock.to_host(device_s),
                    image.sequence_id,
                    self.camera.exposure(),
                    self.clock.time_base,
                )

    def close(self) -> None:
        self.camera.close()
