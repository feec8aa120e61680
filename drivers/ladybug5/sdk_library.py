"""The loaded Ladybug SDK library (``libladybug``): one typed ctypes entry per C function rigd calls, the SDK's
error codes mapped to named errors, and the fields rigd reads out of ``LadybugImage`` / ``LadybugCameraInfo``.

Needs FLIR's proprietary SDK (not on PyPI; rigd neither ships nor downloads it). Signatures follow the SDK's
ladybug.h, ladybuggeom.h and ladybugrenderer.h of 2017; every struct offset and enum value comes from the
installed headers through :class:`drivers.ladybug5.sdk_layout.SdkLayout`.
"""

from __future__ import annotations

import ctypes
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import (
    CorruptFrameError,
    HeadCalibrationError,
    InterfaceSpeedError,
    LibraryMissingError,
    MissingPowerError,
    SdkError,
)
from drivers.ladybug5.raw import Border
from drivers.ladybug5.sdk_layout import SdkLayout

DEFAULT_LIBRARY = "libladybug.so"
CYCLES_PER_SECOND = 8000  # 125 us cycle ticks
_CTX = ctypes.c_void_p
_P_DOUBLE = ctypes.POINTER(ctypes.c_double)
_PIXEL_MAP = [_CTX, ctypes.c_uint, ctypes.c_double, ctypes.c_double, _P_DOUBLE, _P_DOUBLE]
_BUFFERS = ctypes.POINTER(ctypes.c_void_p)  # unsigned char ** (one buffer per camera)
# name -> argument types; every one returns a LadybugError (an int-sized enum).
FUNCTIONS: dict[str, list[Any]] = {
    "ladybugCreateContext": [ctypes.POINTER(_CTX)],
    "ladybugDestroyContext": [ctypes.POINTER(_CTX)],
    "ladybugBusEnumerateCameras": [_CTX, ctypes.c_void_p, ctypes.POINTER(ctypes.c_uint)],
    "ladybugInitializeFromIndex": [_CTX, ctypes.c_uint],
    "ladybugInitializeFromSerialNumber": [_CTX, ctypes.c_uint],
    "ladybugLoadConfig": [_CTX, ctypes.c_char_p],
    "ladybugGetColorTileFormat": [_CTX, ctypes.POINTER(ctypes.c_int)],
    "ladybugSetGrabTimeout": [_CTX, ctypes.c_uint],
    "ladybugStart": [_CTX, ctypes.c_int],
    "ladybugGrabImage": [_CTX, ctypes.c_void_p],
    "ladybugGetAbsProperty": [_CTX, ctypes.c_int, ctypes.POINTER(ctypes.c_float)],
    "ladybugStop": [_CTX],
    "ladybugSetOffScreenImageSize": [_CTX, ctypes.c_int, ctypes.c_uint, ctypes.c_uint],
    "ladybugGetCameraUnitFocalLength": [_CTX, ctypes.c_uint, _P_DOUBLE],
    "ladybugGetCameraUnitImageCenter": [_CTX, ctypes.c_uint, _P_DOUBLE, _P_DOUBLE],
    "ladybugGetCameraUnitExtrinsics": [_CTX, ctypes.c_uint, _P_DOUBLE],
    "ladybugRectifyPixel": _PIXEL_MAP,
    "ladybugUnrectifyPixel": _PIXEL_MAP,
    # the 3D mapping of raw pixels onto the stitching sphere (ladybuggeom.h): no rendering context involved
    "ladybugGet3dMap": [_CTX, ctypes.c_uint, ctypes.c_uint, ctypes.c_uint, ctypes.c_uint, ctypes.c_uint,
                        ctypes.c_bool, ctypes.POINTER(ctypes.c_void_p)],
    "ladybugGet3dMapSphereSize": [_CTX, _P_DOUBLE],
    "ladybugSet3dMapSphereSize": [_CTX, ctypes.c_double],
    "ladybugGet3dMapRotation": [_CTX, _P_DOUBLE, _P_DOUBLE, _P_DOUBLE],
    "ladybugSet3dMapRotation": [_CTX, ctypes.c_double, ctypes.c_double, ctypes.c_double],
    # the SDK's panorama renderer (ladybug.h, ladybugrenderer.h): enum arguments are int-sized
    "ladybugSetColorProcessingMethod": [_CTX, ctypes.c_int],
    "ladybugConfigureOutputImages": [_CTX, ctypes.c_uint],
    "ladybugConvertImage": [_CTX, ctypes.c_void_p, _BUFFERS, ctypes.c_int],
    "ladybugUpdateTextures": [_CTX, ctypes.c_uint, _BUFFERS, ctypes.c_int],
    "ladybugRenderOffScreenImage": [_CTX, ctypes.c_int, ctypes.c_int, ctypes.c_void_p],
}
POINT_AXES = ("x", "y", "z")  # LadybugPoint3d's fX, fY, fZ (float)
_CORRUPT_FRAME_ERRORS = ("IMAGE_TOO_SMALL", "JPEG_ERROR", "JPEG_HEADER_ERROR", "JPEG_INCOMPLETE_COMPRESSION",
                         "JPEG_NO_IMAGE", "CORRUPTED_IMAGE_DATA")


@dataclass(frozen=True)
class GrabbedImage:
    """The fields rigd reads from a LadybugImage, with the pixel buffer copied out of the SDK. Sizes in px
    (``cols`` x ``rows`` the useful image, ``full_*`` with the border); SDK enum values for the format and
    Bayer (stippled) format; times in s."""

    cols: int
    rows: int
    full_cols: int
    full_rows: int
    border: Border
    data_format: int
    stippled_format: int
    cycle_time_s: float
    embedded_time_s: float
    sequence_id: int
    data: bytes
    host_receive_s: float  # host clock right after ladybugGrabImage returned (before copying the pixels)


@dataclass(frozen=True)
class ProcessedImage:
    """The fields rigd reads from a LadybugProcessedImage, the pixels copied out of the SDK's buffer: ``cols`` x
    ``rows`` px, ``pixel_format`` the SDK's value, ``data`` ``rows * cols * 3`` bytes for BGR."""

    cols: int
    rows: int
    pixel_format: int
    data: bytes


@dataclass(frozen=True)
class CameraInfo:
    """A camera the SDK sees on the bus (``LadybugCameraInfo``)."""

    serial: int
    model: str


def _read_uint(raw: bytes, field: tuple[int, int], base: int = 0) -> int:
    offset, size = field
    return int.from_bytes(raw[base + offset : base + offset + size], sys.byteorder)


class LadybugLibrary:
    """The loaded SDK library: typed functions, checked calls, struct reading."""

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
        missing = [f for f in (*FUNCTIONS, "ladybugErrorToString") if not hasattr(self._lib, f)]
        if missing:
            raise LibraryMissingError(f"{self.name} lacks {', '.join(missing)}: not a Ladybug SDK library (or one "
                                      "older than rigd needs)")
        for name, argtypes in FUNCTIONS.items():
            function = getattr(self._lib, name)
            function.argtypes, function.restype = argtypes, ctypes.c_int
        self._lib.ladybugErrorToString.argtypes = [ctypes.c_int]
        self._lib.ladybugErrorToString.restype = ctypes.c_char_p

    @property
    def ok(self) -> int:
        return self.layout.errors["OK"]

    def function(self, name: str) -> Any:
        """The raw ctypes function (for loops that check codes themselves, e.g. sampling a map)."""
        return getattr(self._lib, name)

    def error_text(self, code: int) -> str:
        text = self._lib.ladybugErrorToString(code)
        return text.decode(errors="replace") if text else "no description"

    def check(self, function: str, code: int) -> None:
        """Raise the named error for an SDK error code (codes come from the probed layout)."""
        if code == self.ok:
            return
        text, errors = self.error_text(code), self.layout.errors
        if code == errors.get("BAD_VOLTAGE"):
            raise MissingPowerError(
                f"{function}: the camera reports bad voltage ({text}); a Ladybug5+ needs 12-24 V on its GPIO connector"
            )
        if code == errors.get("BAD_INTERFACE"):
            raise InterfaceSpeedError(f"{function}: the camera is not on a USB 3 SuperSpeed link ({text})")
        if code == errors.get("CALIBRATION_FILE_NOT_FOUND"):
            raise HeadCalibrationError(f"{function}: no calibration file on the Ladybug head ({text})")
        if code in {errors[name] for name in _CORRUPT_FRAME_ERRORS if name in errors}:
            raise CorruptFrameError(f"{function}: {text} (Ladybug error {code})")
        raise SdkError(function, code, text)

    def call(self, function: str, *args: Any) -> None:
        self.check(function, getattr(self._lib, function)(*args))

    def new_image_buffer(self) -> ctypes.Array[ctypes.c_char]:
        return ctypes.create_string_buffer(self.layout.image_size)

    def read_image(self, buf: ctypes.Array[ctypes.c_char], host_receive_s: float) -> GrabbedImage:
        raw, fields = buf.raw, self.layout.image_fields

        def field(name: str) -> int:
            return _read_uint(raw, fields[name])

        pointer = field("data")
        if not pointer:
            raise CorruptFrameError("ladybugGrabImage returned an image without pixel data")
        border = Border(field("border_top"), field("border_bottom"), field("border_left"), field("border_right"))
        return GrabbedImage(
            cols=field("cols"), rows=field("rows"), full_cols=field("full_cols"), full_rows=field("full_rows"),
            border=border, data_format=field("data_format"), stippled_format=field("stippled_format"),
            cycle_time_s=field("cycle_seconds") + field("cycle_count") / CYCLES_PER_SECOND,
            embedded_time_s=field("embedded_seconds") + field("embedded_microseconds") * 1e-6,
            sequence_id=field("sequence_id"), data=ctypes.string_at(pointer, field("data_size")),
            host_receive_s=host_receive_s,
        )

    def new_processed_buffer(self) -> ctypes.Array[ctypes.c_char]:
        return ctypes.create_string_buffer(self.layout.processed_image_size)

    def read_processed(self, buf: ctypes.Array[ctypes.c_char], *, bytes_per_pixel: int) -> ProcessedImage:
        """The image ladybugRenderOffScreenImage wrote into ``buf`` (its pixels still in the SDK's buffer)."""
        raw, fields = buf.raw, self.layout.processed_image_fields
        cols, rows = _read_uint(raw, fields["cols"]), _read_uint(raw, fields["rows"])
        pointer = _read_uint(raw, fields["data"])
        if not pointer or not cols or not rows:
            raise CorruptFrameError(f"ladybugRenderOffScreenImage returned a {cols}x{rows} image without pixel data")
        data = ctypes.string_at(pointer, cols * rows * bytes_per_pixel)
        return ProcessedImage(cols, rows, _read_uint(raw, fields["pixel_format"]), data)

    def read_3d_map(self, pointer: int, where: str) -> NDArray[np.float64]:
        """(rows, cols, 3) x, y, z (m, Ladybug frame) of a ``LadybugImage3d`` the SDK returned (its memory)."""
        fields = self.layout.image3d_fields
        if not pointer:
            raise HeadCalibrationError(f"{where}: ladybugGet3dMap returned no 3D map")
        head = ctypes.string_at(pointer, max(offset + size for offset, size in fields.values()))
        rows, cols, points = (_read_uint(head, fields[name]) for name in ("rows", "cols", "points"))
        if not points or not rows or not cols:
            raise HeadCalibrationError(f"{where}: ladybugGet3dMap returned a {cols}x{rows} map without points")
        size, xyz = self.layout.point3d_size, self.layout.point3d_fields
        dtype = np.dtype({"names": list(POINT_AXES), "formats": ["<f4"] * 3,
                          "offsets": [xyz[a][0] for a in POINT_AXES], "itemsize": size})
        raw = np.frombuffer(ctypes.string_at(points, rows * cols * size), dtype)
        return np.stack([raw[a].astype(np.float64) for a in POINT_AXES], axis=-1).reshape(rows, cols, 3)

    def read_camera_infos(self, buf: ctypes.Array[ctypes.c_char], count: int) -> list[CameraInfo]:
        size, fields = self.layout.camera_info_size, self.layout.camera_info_fields
        raw, (name_at, name_len) = buf.raw, fields["model_name"]
        infos = []
        for i in range(count):
            name = raw[i * size + name_at : i * size + name_at + name_len].split(b"\0", 1)[0]
            infos.append(CameraInfo(_read_uint(raw, fields["serial_head"], i * size), name.decode(errors="replace")))
        return infos


def sdk_status(library: str | Path = DEFAULT_LIBRARY) -> str:
    """One line for ``rigd camera info``: whether the SDK library loads (no layout needed to tell)."""
    try:
        lib = ctypes.CDLL(str(library))
    except OSError as exc:
        return f"not available ({exc}); streaming needs FLIR's Ladybug SDK, replay and stitching do not"
    missing = [f for f in (*FUNCTIONS, "ladybugErrorToString") if not hasattr(lib, f)]
    return f"{library} loads but lacks {', '.join(missing)}" if missing else f"{library} loads"
