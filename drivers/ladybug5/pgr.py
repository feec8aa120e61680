"""Ladybug stream files (.pgr) without the SDK: head info, frame index, times, and the six sensor images.

FLIR does not document the .pgr layout. What is read here is what is publicly known and checkable: the
16-byte signature ``PGRLADYBUGSTREAM``, the head info (``LadybugStreamHeadInfo``: data format, Bayer pattern,
resolution, per-frame header size; :mod:`drivers.ladybug5.pgr_layout`) with the camera's configuration after
it, then the frames. A frame is an optional per-frame header (head info 0xA0 bytes; newer streams) and the
data: a COLOR_SEP_JPEG8 block (big-endian image info with the ``0xCAFEBABE`` fingerprint, size, times,
registers, and a table of the 24 JPEGs: 6 cameras x 4 Bayer channels, 8- or 12-bit), or six RAW8/RAW12/RAW16
mosaics. Every frame is checked (fingerprint, sizes); each channel JPEG by its start marker and the decoder
(:mod:`drivers.ladybug5.channels`): a bad channel loses its camera, not the frame, and is reported by name. Data
formats rigd does not decode (half height, ...) are named as unsupported. Not read (SDK only): the configuration
(kept as opaque bytes; :mod:`drivers.ladybug5.sdk_head` hands it to the SDK), GPS/NMEA data.
"""

from __future__ import annotations

import mmap
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

from numpy.typing import NDArray

from drivers.ladybug5.channels import CameraSet, assemble_mosaic, block_jpegs, frame_mosaics
from drivers.ladybug5.errors import StreamFormatError
from drivers.ladybug5.formats import (
    STREAM_BAYER_CODES,
    STREAM_FORMAT_CODES,
    STREAM_RESOLUTIONS,
    BayerPattern,
    DataFormat,
    require_decoded,
)
from drivers.ladybug5.frames import Exposure
from drivers.ladybug5.pgr_layout import (
    DEFAULT_LAYOUT,
    FINGERPRINT,
    NUM_CAMERAS,
    SIGNATURE,
    FrameHeaderStyle,
    PgrLayout,
    u32be,
    u32le,
)
from drivers.ladybug5.pgr_write import PgrFrameData, PgrWriteOptions, bayer_planes, jpeg_block, write_pgr
from drivers.ladybug5.raw import SensorGeometry, decode_raw, demosaic

__all__ = [
    "DEFAULT_LAYOUT", "FINGERPRINT", "NUM_CAMERAS", "SIGNATURE", "CameraSet", "FrameHeaderStyle", "PgrFrameData",
    "PgrFrameEntry", "PgrHeader", "PgrLayout", "PgrStream", "PgrWriteOptions", "assemble_mosaic", "bayer_planes",
    "jpeg_block", "write_pgr",
]


@dataclass(frozen=True)
class PgrHeader:
    """The head info. ``data_format`` / ``bayer`` / ``resolution`` are None when the stored code is not one rigd
    knows (``bayer`` also for 'camera default'); the codes themselves are kept for the messages."""

    version: int
    serial: int
    frame_count: int  # as the head info says; the index is what the file really holds
    data_offset: int
    calibration: bytes  # opaque: the SDK's configuration format
    format_code: int
    data_format: DataFormat | None
    bayer_code: int
    bayer: BayerPattern | None
    resolution_code: int
    resolution: tuple[int, int] | None  # per-sensor (cols, rows)
    frame_header_size: int
    padding_size: int


@dataclass(frozen=True)
class PgrFrameEntry:
    """Frame ``index``: it spans ``size`` bytes from ``offset``; its image info is at ``info_offset`` and its data
    (JPEG block or mosaics) from ``payload_offset`` to the frame's end."""

    index: int
    offset: int
    size: int
    info_offset: int
    payload_offset: int
    device_time_s: float
    sequence_id: int
    exposure: Exposure

    @property
    def end(self) -> int:
        return self.offset + self.size


class PgrStream:
    """A memory-mapped .pgr file with its frame index (built by walking the frames)."""

    def __init__(self, path: Path, layout: PgrLayout = DEFAULT_LAYOUT) -> None:
        self.path = Path(path)
        self.layout = layout
        try:
            with open(self.path, "rb") as f:
                self._buf = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError) as exc:
            raise StreamFormatError(f"cannot open stream file {self.path}: {exc}") from exc
        try:
            if self._buf[: len(SIGNATURE)] != SIGNATURE:
                raise StreamFormatError(f"{self.path}: not a Ladybug stream (no {SIGNATURE.decode()} signature)")
            self.header = self._read_header()
            self.damaged: list[str] = []
            self.style = self._detect_style()
            self.index = self._walk_frames()
        except StreamFormatError:
            self._buf.close()
            raise

    def close(self) -> None:
        self._buf.close()

    def _read_header(self) -> PgrHeader:
        lay, base = self.layout, len(SIGNATURE)
        if len(self._buf) < base + lay.head_info_size:
            raise StreamFormatError(f"{self.path}: truncated head info ({len(self._buf)} bytes)")

        def head(at: int) -> int:
            return u32le(self._buf, base + at)

        config_size, fmt, bayer, res = (head(lay.head_config_size), head(lay.head_data_format), head(lay.head_bayer),
                                        head(lay.head_resolution))
        cal_start = base + lay.head_info_size
        calibration = bytes(self._buf[cal_start : cal_start + config_size]) if cal_start + config_size <= len(
            self._buf) else b""
        return PgrHeader(head(lay.head_version), head(lay.head_serial), head(lay.head_frame_count),
                         head(lay.head_data_offset), calibration, fmt, STREAM_FORMAT_CODES.get(fmt), bayer,
                         STREAM_BAYER_CODES.get(bayer), res, STREAM_RESOLUTIONS.get(res),
                         head(lay.head_frame_header_size), head(lay.head_padding_size))

    # -- finding frames -------------------------------------------------------------------------------------

    @property
    def _is_raw(self) -> bool:
        fmt = self.header.data_format
        return fmt is not None and fmt.raw_bits > 0

    @property
    def _info_shift(self) -> int:
        """Where a frame's image info is, from the frame's start."""
        return self.header.frame_header_size if self.style is FrameHeaderStyle.OPAQUE else 0

    @property
    def _payload_shift(self) -> int:
        return 0 if self.style is FrameHeaderStyle.NONE else self.header.frame_header_size

    def _fingerprint_at(self, info: int) -> bool:
        lay = self.layout
        return 0 <= info and info + lay.info_size <= len(self._buf) and u32be(self._buf, info + lay.fingerprint) == \
            FINGERPRINT

    def _detect_style(self) -> FrameHeaderStyle:
        """No frame header, one that starts with the image info (INFO), or an opaque one before a JPEG block."""
        h = self.header.frame_header_size
        if h == 0 and self._is_raw:
            raise StreamFormatError(f"{self.path}: RAW frames without a per-frame header (head info "
                                    f"{self.layout.head_frame_header_size:#x} is 0): rigd cannot find their times")
        if h == 0:
            return FrameHeaderStyle.NONE
        first = self.header.data_offset
        if not (self._fingerprint_at(first) or self._fingerprint_at(first + h)):  # a wrong data offset
            hit = self._buf.find(FINGERPRINT.to_bytes(4, "big"), len(SIGNATURE) + self.layout.head_info_size)
            first = hit - self.layout.fingerprint if hit >= 0 else first
        if self._fingerprint_at(first) and (self._is_raw or self._fingerprint_at(first + h)):
            return FrameHeaderStyle.INFO
        if self._is_raw:
            raise StreamFormatError(f"{self.path}: RAW frames without an image info (0x{FINGERPRINT:X}) in their "
                                    f"{h}-byte frame header: rigd cannot find their times (docs/ladybug5.md)")
        return FrameHeaderStyle.OPAQUE

    def _frame_end(self, offset: int) -> int:
        info = offset + self._info_shift
        return info + u32be(self._buf, info + self.layout.frame_size)

    def _is_frame_at(self, offset: int) -> bool:
        return self._fingerprint_at(offset + self._info_shift)

    def _next_frame(self, start: int) -> int | None:
        """Offset of the first frame whose fingerprint lies at or after ``start``'s."""
        shift = self._info_shift + self.layout.fingerprint
        at = start + shift
        while (hit := self._buf.find(FINGERPRINT.to_bytes(4, "big"), at)) >= 0:
            if self._is_frame_at(hit - shift):
                return hit - shift
            at = hit + 1
        return None

    def _fits(self, offset: int, end: int) -> bool:
        """Whether a frame from ``offset`` to ``end`` holds its header, info and (for JPEG) the JPEG table."""
        lay = self.layout
        least = max(self._info_shift + lay.info_size, self._payload_shift + (0 if self._is_raw else
                                                                             lay.frame_header_size))
        return offset + least <= end <= len(self._buf)

    def _following(self, end: int) -> int | None:
        """The frame after one ending at ``end``: there, or after the head info's padding, or found by search (the
        bytes in between are recorded as damage)."""
        for candidate in (end, end + self.header.padding_size):
            if self._is_frame_at(candidate):
                return candidate
        nxt = self._next_frame(end)
        if nxt is not None:
            self.damaged.append(f"{self.path}: bytes {end}..{nxt} are not a frame block")
        return nxt

    def _walk_frames(self) -> list[PgrFrameEntry]:
        """Follow frame sizes frame to frame; damaged stretches are skipped (listed in ``damaged``) by searching
        for the next fingerprint, so one bad block does not lose the rest of a recording."""
        entries: list[PgrFrameEntry] = []
        data = self.header.data_offset
        offset = data if self._is_frame_at(data) else self._next_frame(len(SIGNATURE))
        if offset is None:
            raise StreamFormatError(f"{self.path}: no frame block (0x{FINGERPRINT:X} fingerprint) found")
        while offset is not None:
            end = self._frame_end(offset)
            if self._fits(offset, end):
                entries.append(self._entry(len(entries), offset, end))
                offset = self._following(end)
            else:
                left = len(self._buf) - offset
                self.damaged.append(f"{self.path}: frame at byte {offset} claims {end - offset} bytes ({left} left)")
                offset = self._next_frame(offset + 1)
        return entries

    def _entry(self, index: int, offset: int, end: int) -> PgrFrameEntry:
        lay, info = self.layout, offset + self._info_shift
        seconds = u32be(self._buf, info + lay.seconds)
        micro = u32be(self._buf, info + lay.microseconds)
        gain = struct.unpack_from(">6I", self._buf, info + lay.gain)
        shutter = struct.unpack_from(">6I", self._buf, info + lay.shutter)
        exposure = Exposure(shutter_raw=tuple(shutter), gain_raw=tuple(gain))
        return PgrFrameEntry(index, offset, end - offset, info, offset + self._payload_shift, seconds + micro * 1e-6,
                             u32be(self._buf, info + lay.sequence_id), exposure)

    # -- decoding ---------------------------------------------------------------------------------------------

    def data_format(self) -> DataFormat:
        """The stream's data format if rigd decodes it; else :class:`UnsupportedFormatError` naming it."""
        fmt = self.header.data_format
        if fmt is None:
            raise StreamFormatError(f"{self.path}: unknown data format code {self.header.format_code} in the head "
                                    "info (rigd knows the Ladybug SDK 1.10+ numbering, RAW8 = 1 ... RAW12 = 11)")
        return require_decoded(fmt, str(self.path))

    def bayer_pattern(self) -> BayerPattern:
        """The layout's override, else the head info's pattern; an error naming the code when neither says."""
        pattern = self.layout.bayer_pattern or self.header.bayer
        if pattern is None:
            raise StreamFormatError(
                f"{self.path}: the head info gives no Bayer pattern (stippled format code {self.header.bayer_code},"
                " 'camera default' or unknown); give one (PgrLayout.bayer_pattern)")
        return pattern

    def jpegs(self, index: int) -> list[list[bytes]]:
        """The 6 x 4 JPEG channel images of frame ``index``; a CorruptFrameError naming every bad table entry."""
        entry = self.index[index]
        where = f"{self.path}: frame {index} (sequence {entry.sequence_id})"
        size = entry.end - entry.payload_offset
        return block_jpegs(self._buf, entry.payload_offset, size, self.layout, where).complete(where)

    def frame_images(self, index: int, min_cameras: int = NUM_CAMERAS) -> CameraSet:
        """The demosaiced BGR images (raw sensor orientation) of frame ``index``: (H, W, 3) uint8, or uint16 with the
        significant bits at the top (RAW12, RAW16, 12-bit JPEG); a camera whose channel JPEGs do not decode is None
        (its faults listed). Fewer than ``min_cameras`` cameras: CorruptFrameError naming the faults."""
        fmt, pattern = self.data_format(), self.bayer_pattern()
        entry = self.index[index]
        where = f"{self.path}: frame {index} (sequence {entry.sequence_id})"
        if fmt.jpeg_bits:
            block = block_jpegs(self._buf, entry.payload_offset, entry.end - entry.payload_offset, self.layout, where)
            mosaics = frame_mosaics(block, self.layout, fmt.jpeg_bits).require(min_cameras, where)
            return mosaics.map(lambda m: demosaic(m, pattern))
        if self.header.resolution is None:
            raise StreamFormatError(f"{self.path}: unknown resolution code {self.header.resolution_code}: the size of"
                                    " a RAW sensor image is not known")
        payload = bytes(self._buf[entry.payload_offset : entry.end])  # a copy: the mmap can close under it
        geometry = SensorGeometry(*self.header.resolution)
        return CameraSet(tuple(decode_raw(payload, fmt, geometry, pattern, where, self.layout.raw16_bits)))

    def camera_images(self, index: int) -> list[NDArray[Any]]:
        """All six images of frame ``index`` (:meth:`frame_images`); a camera missing is a CorruptFrameError."""
        return [cast(NDArray[Any], image) for image in self.frame_images(index).arrays]


def frame_block_mosaics(block: bytes, layout: PgrLayout, where: str, bits: int = 8,
                        min_cameras: int = NUM_CAMERAS) -> CameraSet:
    """The cameras' Bayer mosaics of one JPEG frame block (a .pgr frame's, or an SDK COLOR_SEP_JPEG buffer)."""
    jpegs = block_jpegs(block, 0, len(block), layout, where)
    return frame_mosaics(jpegs, layout, bits).require(min_cameras, where)
