"""Writing .pgr streams in the layout :class:`drivers.ladybug5.pgr.PgrStream` reads: synthetic streams for the
tests and the benchmark, in each data format, with or without the newer per-frame header."""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import StreamFormatError
from drivers.ladybug5.formats import (
    STREAM_BAYER_CODES,
    STREAM_FORMAT_CODES,
    STREAM_RESOLUTIONS,
    BayerPattern,
    DataFormat,
    stream_code,
)
from drivers.ladybug5.pgr_layout import (
    DEFAULT_LAYOUT,
    FINGERPRINT,
    JPEGS_PER_CAMERA,
    NUM_CAMERAS,
    SIGNATURE,
    FrameHeaderStyle,
    PgrLayout,
)

_CHANNEL = {"B": 0, "G": 1, "R": 2}


@dataclass(frozen=True)
class PgrFrameData:
    """One frame to write: times, registers, and either the 6 x 4 JPEG channel images (COLOR_SEP_JPEG8) or
    ``raw``, six full (rows, cols) Bayer mosaics (uint8 for RAW8, uint16 for RAW16, packed uint8 bytes for RAW12)."""

    seconds: int
    microseconds: int
    sequence_id: int
    jpegs: Sequence[Sequence[bytes]] = ()
    gain_raw: tuple[int, ...] = (0,) * NUM_CAMERAS
    shutter_raw: tuple[int, ...] = (0,) * NUM_CAMERAS
    raw: Sequence[NDArray[Any]] = ()


@dataclass(frozen=True)
class PgrWriteOptions:
    """The head info's data format, Bayer pattern (None: 'camera default'), per-sensor resolution and serial;
    the per-frame header (``frame_header_size`` bytes, 0 for none, of ``frame_header_style``) and
    ``padding_size`` zero bytes after each frame (not counted in its size, as the head info's padding)."""

    data_format: DataFormat = DataFormat.COLOR_SEP_JPEG8
    bayer: BayerPattern | None = BayerPattern.RGGB
    resolution: tuple[int, int] = (2448, 2048)
    serial: int = 17092345
    frame_header_size: int = 0
    frame_header_style: FrameHeaderStyle = FrameHeaderStyle.INFO
    padding_size: int = 0
    extra: dict[int, int] = field(default_factory=dict)  # more head-info u32s by offset (tests)


def mosaic_from_bgr(image_bgr: NDArray[Any], pattern: BayerPattern) -> NDArray[Any]:
    """(H, W, 3) BGR -> (H, W) Bayer mosaic of ``pattern`` (each pixel keeps the channel its cell samples)."""
    out = np.empty(image_bgr.shape[:2], image_bgr.dtype)
    for r in (0, 1):
        for c in (0, 1):
            out[r::2, c::2] = image_bgr[r::2, c::2, _CHANNEL[pattern.colour_at(r, c)]]
    return out


def bayer_planes(image_bgr: NDArray[np.uint8], layout: PgrLayout = DEFAULT_LAYOUT, quality: int = 95,
                 pattern: BayerPattern | None = None) -> list[bytes]:
    """Four JPEG Bayer-channel images (slot order of ``layout``) of a BGR image mosaiced with ``pattern``
    (default: the layout's, else RGGB): the inverse of the reader's reassembly up to demosaicing."""
    mosaic = mosaic_from_bgr(image_bgr, pattern or layout.bayer_pattern or BayerPattern.RGGB)
    out = []
    for r, c in layout.slot_cells:
        ok, data = cv2.imencode(".jpg", np.ascontiguousarray(mosaic[r::2, c::2]), [cv2.IMWRITE_JPEG_QUALITY, quality])
        if not ok:
            raise StreamFormatError("JPEG encoding of a Bayer channel failed")
        out.append(data.tobytes())
    return out


def _info_into(buf: bytearray, at: int, frame: PgrFrameData, size: int, layout: PgrLayout) -> None:
    """The big-endian image info (size, fingerprint, times, registers) at ``buf[at:]``."""
    struct.pack_into(">I", buf, at + layout.frame_size, size)
    struct.pack_into(">I", buf, at + layout.fingerprint, FINGERPRINT)
    struct.pack_into(">3I", buf, at + layout.seconds, frame.seconds, frame.microseconds, frame.sequence_id)
    struct.pack_into(">6I", buf, at + layout.gain, *frame.gain_raw)
    struct.pack_into(">6I", buf, at + layout.shutter, *frame.shutter_raw)


def jpeg_block(frame: PgrFrameData, layout: PgrLayout = DEFAULT_LAYOUT) -> bytes:
    """A COLOR_SEP_JPEG8 frame block: image info, the JPEG table, the 24 JPEGs (offsets from its start)."""
    header = bytearray(layout.frame_header_size)
    payload = bytearray()
    for cam in range(NUM_CAMERAS):
        for slot in range(JPEGS_PER_CAMERA):
            data = frame.jpegs[cam][slot]
            at = layout.jpeg_table + cam * 32 + slot * 8
            struct.pack_into(">2I", header, at, len(header) + len(payload), len(data))
            payload += data
    _info_into(header, 0, frame, len(header) + len(payload), layout)
    return bytes(header + payload)


def _raw_payload(frame: PgrFrameData, fmt: DataFormat) -> bytes:
    """The six mosaics as the format stores them; RAW12 mosaics are given packed (uint8, 3 bytes per 2 pixels)."""
    dtype = np.dtype(np.uint8) if fmt in (DataFormat.RAW8, DataFormat.RAW12) else np.dtype("<u2")
    if len(frame.raw) != NUM_CAMERAS:
        raise StreamFormatError(f"a {fmt.value} frame needs {NUM_CAMERAS} mosaics, got {len(frame.raw)}")
    return b"".join(np.ascontiguousarray(m, dtype).tobytes() for m in frame.raw)


def _frame_bytes(frame: PgrFrameData, layout: PgrLayout, options: PgrWriteOptions) -> bytes:
    size, style = options.frame_header_size, options.frame_header_style
    raw = options.data_format.raw_bits > 0
    if raw and (size == 0 or style is not FrameHeaderStyle.INFO):
        raise StreamFormatError("RAW frames carry their times in an INFO frame header: give frame_header_size")
    payload = _raw_payload(frame, options.data_format) if raw else jpeg_block(frame, layout)
    if size == 0:
        return payload + bytes(options.padding_size)
    header = bytearray(size)
    if style is FrameHeaderStyle.INFO:
        _info_into(header, 0, frame, size + len(payload), layout)
    else:
        header[:] = b"\x5a" * size  # bytes rigd must not interpret
    return bytes(header) + payload + bytes(options.padding_size)


def _head_info(layout: PgrLayout, options: PgrWriteOptions, version: int, calibration: bytes, count: int,
               data_offset: int) -> bytes:
    head = bytearray(layout.head_info_size)
    values = {
        layout.head_version: version,
        layout.head_serial: options.serial,
        layout.head_padding_size: options.padding_size,
        layout.head_data_format: stream_code(STREAM_FORMAT_CODES, options.data_format),
        layout.head_resolution: stream_code(STREAM_RESOLUTIONS, options.resolution),
        layout.head_bayer: stream_code(STREAM_BAYER_CODES, options.bayer),
        layout.head_config_size: len(calibration),
        layout.head_frame_count: count,
        layout.head_data_offset: data_offset,
        layout.head_frame_header_size: options.frame_header_size,
        **options.extra,
    }
    for at, value in values.items():
        struct.pack_into("<I", head, at, value)
    return bytes(head)


def write_pgr(path: Path, frames: Iterable[PgrFrameData], calibration: bytes = b"", layout: PgrLayout = DEFAULT_LAYOUT,
              version: int = 7, options: PgrWriteOptions = PgrWriteOptions()) -> int:
    """Write a stream in the layout :class:`PgrStream` reads (synthetic data, tests); returns the frame count."""
    blocks = [_frame_bytes(f, layout, options) for f in frames]
    base = len(SIGNATURE)
    data_offset = -(-(base + layout.head_info_size + len(calibration)) // 512) * 512  # 512-byte aligned
    head = _head_info(layout, options, version, calibration, len(blocks), data_offset)
    prefix = SIGNATURE + head + calibration
    Path(path).write_bytes(prefix + bytes(data_offset - len(prefix)) + b"".join(blocks))
    return len(blocks)
