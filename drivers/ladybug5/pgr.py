"""Ladybug stream files (.pgr) without the SDK: frame index, times, JPEG extraction, Bayer reassembly.

FLIR does not document the .pgr layout. What is read here is what is publicly known and checkable: the
16-byte signature ``PGRLADYBUGSTREAM``, a head-info block with the calibration after it, then frame blocks
whose (big-endian) header carries the ``0xCAFEBABE`` fingerprint, the frame size, time (seconds and
microseconds), sequence id, per-camera gain and shutter registers and a table of the 24 JPEG images
(6 cameras x 4 Bayer channels). Offsets are in :class:`PgrLayout`; its defaults follow the field order of
the SDK's image-info structure and open-source readers of earlier Ladybug models and are checked on
every frame (fingerprint, sizes, JPEG markers), so a file that disagrees fails loudly, never silently.
Not read (SDK only): the calibration (kept as opaque bytes), GPS/PPS flags and NMEA data, 12-bit JPEGs.
"""

from __future__ import annotations

import mmap
import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import CorruptFrameError, StreamFormatError
from drivers.ladybug5.frames import Exposure

SIGNATURE = b"PGRLADYBUGSTREAM"
FINGERPRINT = 0xCAFEBABE
NUM_CAMERAS = 6
JPEGS_PER_CAMERA = 4
_JPEG_SOI = b"\xff\xd8"
_JPEG_EOI = b"\xff\xd9"
BAYER_TO_BGR = {
    "RGGB": cv2.COLOR_BayerRGGB2BGR,
    "BGGR": cv2.COLOR_BayerBGGR2BGR,
    "GRBG": cv2.COLOR_BayerGRBG2BGR,
    "GBRG": cv2.COLOR_BayerGBRG2BGR,
}


@dataclass(frozen=True)
class PgrLayout:
    """Byte offsets of a .pgr file. Head info: little-endian u32 after the signature; frame blocks:
    big-endian u32 relative to the block start. JPEG entry (offset, size) of camera c, slot k is at
    ``jpeg_table + c * 32 + k * 8``; slot k holds the Bayer cell ``slot_cells[k]`` (row, col) of a
    ``bayer_pattern`` mosaic."""

    head_version: int = 0x00
    head_config_size: int = 0x84
    head_frame_count: int = 0x88
    head_data_offset: int = 0x94
    head_info_size: int = 0xBF0  # the calibration follows the head info
    frame_size: int = 0x08
    fingerprint: int = 0x10
    seconds: int = 0x18
    microseconds: int = 0x1C
    sequence_id: int = 0x20
    gain: int = 0x28  # 6 x u32 registers
    shutter: int = 0x58  # 6 x u32 registers
    jpeg_table: int = 0x340
    bayer_pattern: str = "BGGR"
    slot_cells: tuple[tuple[int, int], ...] = ((1, 1), (1, 0), (0, 1), (0, 0))

    @property
    def frame_header_size(self) -> int:
        return self.jpeg_table + NUM_CAMERAS * JPEGS_PER_CAMERA * 8


DEFAULT_LAYOUT = PgrLayout()


@dataclass(frozen=True)
class PgrHeader:
    version: int
    frame_count: int  # as the head info says; the index below is what the file really holds
    data_offset: int
    calibration: bytes  # opaque: the SDK's format


@dataclass(frozen=True)
class PgrFrameEntry:
    """Where frame ``index`` sits in the file and its header fields."""

    index: int
    offset: int
    size: int
    device_time_s: float
    sequence_id: int
    exposure: Exposure


@dataclass(frozen=True)
class PgrFrameData:
    """What the writer stores for one frame: times, registers and the 6 x 4 JPEG channel images."""

    seconds: int
    microseconds: int
    sequence_id: int
    jpegs: Sequence[Sequence[bytes]]
    gain_raw: tuple[int, ...] = (0,) * NUM_CAMERAS
    shutter_raw: tuple[int, ...] = (0,) * NUM_CAMERAS


def _u32be(buf: bytes | mmap.mmap, at: int) -> int:
    return int(struct.unpack_from(">I", buf, at)[0])


class PgrStream:
    """A memory-mapped .pgr file with its frame index (built by walking the frame blocks)."""

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
        version, config_size, count, data_offset = (
            int(struct.unpack_from("<I", self._buf, base + at)[0])
            for at in (lay.head_version, lay.head_config_size, lay.head_frame_count, lay.head_data_offset)
        )
        cal_start = base + lay.head_info_size
        calibration = (
            bytes(self._buf[cal_start : cal_start + config_size]) if cal_start + config_size <= len(self._buf) else b""
        )
        return PgrHeader(version, count, data_offset, calibration)

    def _is_frame_at(self, offset: int) -> bool:
        lay = self.layout
        return (
            offset + lay.frame_header_size <= len(self._buf)
            and _u32be(self._buf, offset + lay.fingerprint) == FINGERPRINT
        )

    def _next_frame(self, start: int) -> int | None:
        """Offset of the first frame block whose fingerprint lies at or after ``start + fingerprint``."""
        at = start + self.layout.fingerprint
        while (hit := self._buf.find(FINGERPRINT.to_bytes(4, "big"), at)) >= 0:
            if self._is_frame_at(hit - self.layout.fingerprint):
                return hit - self.layout.fingerprint
            at = hit + 1
        return None

    def _walk_frames(self) -> list[PgrFrameEntry]:
        """Follow frame sizes block to block; damaged stretches are skipped (listed in ``damaged``) by
        searching for the next fingerprint, so one bad block does not lose the rest of a recording."""
        self.damaged: list[str] = []
        entries: list[PgrFrameEntry] = []
        data = self.header.data_offset
        offset = data if self._is_frame_at(data) else self._next_frame(len(SIGNATURE))
        if offset is None:
            raise StreamFormatError(f"{self.path}: no frame block (0xCAFEBABE fingerprint) found")
        while offset is not None:
            size = _u32be(self._buf, offset + self.layout.frame_size)
            if self.layout.frame_header_size <= size <= len(self._buf) - offset:
                entries.append(self._entry(len(entries), offset, size))
                nxt = offset + size if self._is_frame_at(offset + size) else self._next_frame(offset + size)
                if nxt is not None and nxt != offset + size:
                    self.damaged.append(f"{self.path}: bytes {offset + size}..{nxt} are not a frame block")
            else:
                nxt = self._next_frame(offset + 1)
                left = len(self._buf) - offset
                self.damaged.append(f"{self.path}: frame block at byte {offset} claims {size} bytes ({left} left)")
            offset = nxt
        return entries

    def _entry(self, index: int, offset: int, size: int) -> PgrFrameEntry:
        lay = self.layout
        seconds = _u32be(self._buf, offset + lay.seconds)
        micro = _u32be(self._buf, offset + lay.microseconds)
        gain = struct.unpack_from(">6I", self._buf, offset + lay.gain)
        shutter = struct.unpack_from(">6I", self._buf, offset + lay.shutter)
        exposure = Exposure(shutter_raw=tuple(shutter), gain_raw=tuple(gain))
        return PgrFrameEntry(
            index, offset, size, seconds + micro * 1e-6, _u32be(self._buf, offset + lay.sequence_id), exposure
        )

    def jpegs(self, index: int) -> list[list[bytes]]:
        """The 6 x 4 JPEG channel images of frame ``index``; raises CorruptFrameError on a bad table entry."""
        entry = self.index[index]
        where = f"{self.path}: frame {index} (sequence {entry.sequence_id})"
        return frame_jpegs(self._buf, entry.offset, entry.size, self.layout, where)

    def camera_images(self, index: int) -> list[NDArray[np.uint8]]:
        """The six demosaiced BGR images (raw sensor orientation) of frame ``index``."""
        where = f"{self.path}: frame {index}"
        return [assemble_bayer(p, self.layout, f"{where} camera {c}") for c, p in enumerate(self.jpegs(index))]


def frame_jpegs(buf: bytes | mmap.mmap, offset: int, size: int, layout: PgrLayout, where: str) -> list[list[bytes]]:
    """The 6 x 4 JPEG channel images of the frame block at ``buf[offset : offset + size]``."""
    if size < layout.frame_header_size or _u32be(buf, offset + layout.fingerprint) != FINGERPRINT:
        raise CorruptFrameError(f"{where}: not a frame block (size {size}, no 0xCAFEBABE fingerprint)")
    out = []
    for cam in range(NUM_CAMERAS):
        row = []
        for slot in range(JPEGS_PER_CAMERA):
            at, length = struct.unpack_from(">2I", buf, offset + layout.jpeg_table + cam * 32 + slot * 8)
            data = bytes(buf[offset + at : offset + at + length])
            if at + length > size or not (data.startswith(_JPEG_SOI) and data.endswith(_JPEG_EOI)):
                raise CorruptFrameError(f"{where} camera {cam} channel {slot}: no JPEG at offset {at} size {length}")
            row.append(data)
        out.append(row)
    return out


def frame_block_images(block: bytes, layout: PgrLayout, where: str) -> list[NDArray[np.uint8]]:
    """Six demosaiced BGR images from one frame block (a .pgr frame, or an SDK COLOR_SEP_JPEG8 buffer)."""
    jpegs = frame_jpegs(block, 0, len(block), layout, where)
    return [assemble_bayer(p, layout, f"{where} camera {c}") for c, p in enumerate(jpegs)]


def assemble_bayer(planes: Sequence[bytes], layout: PgrLayout, where: str) -> NDArray[np.uint8]:
    """Four JPEG Bayer-channel images -> one demosaiced BGR image (2h, 2w, 3) uint8."""
    maybe = [cv2.imdecode(np.frombuffer(p, np.uint8), cv2.IMREAD_GRAYSCALE) for p in planes]
    decoded = [d for d in maybe if d is not None]
    if len(decoded) != len(maybe) or len({d.shape for d in decoded}) != 1:
        raise CorruptFrameError(f"{where}: a Bayer channel JPEG does not decode or sizes differ")
    h, w = decoded[0].shape
    mosaic = np.empty((2 * h, 2 * w), np.uint8)
    for (r, c), plane in zip(layout.slot_cells, decoded, strict=True):
        mosaic[r::2, c::2] = plane
    return cast(NDArray[np.uint8], cv2.cvtColor(mosaic, BAYER_TO_BGR[layout.bayer_pattern]))


def bayer_planes(image_bgr: NDArray[np.uint8], layout: PgrLayout, quality: int = 95) -> list[bytes]:
    """The inverse of :func:`assemble_bayer` up to demosaicing: mosaic a BGR image, JPEG each channel."""
    channel_of = {"B": 0, "G": 1, "R": 2}
    pattern = layout.bayer_pattern
    out = []
    for r, c in layout.slot_cells:
        plane = np.ascontiguousarray(image_bgr[r::2, c::2, channel_of[pattern[2 * r + c]]])
        ok, data = cv2.imencode(".jpg", plane, [cv2.IMWRITE_JPEG_QUALITY, quality])
        if not ok:
            raise StreamFormatError("JPEG encoding of a Bayer channel failed")
        out.append(data.tobytes())
    return out


def _frame_block(frame: PgrFrameData, layout: PgrLayout) -> bytes:
    header = bytearray(layout.frame_header_size)
    payload = bytearray()
    for cam in range(NUM_CAMERAS):
        for slot in range(JPEGS_PER_CAMERA):
            data = frame.jpegs[cam][slot]
            struct.pack_into(
                ">2I", header, layout.jpeg_table + cam * 32 + slot * 8, len(header) + len(payload), len(data)
            )
            payload += data
    size = len(header) + len(payload)
    struct.pack_into(">I", header, layout.frame_size, size)
    struct.pack_into(">I", header, layout.fingerprint, FINGERPRINT)
    struct.pack_into(">3I", header, layout.seconds, frame.seconds, frame.microseconds, frame.sequence_id)
    struct.pack_into(">6I", header, layout.gain, *frame.gain_raw)
    struct.pack_into(">6I", header, layout.shutter, *frame.shutter_raw)
    return bytes(header + payload)


def write_pgr(
    path: Path,
    frames: Iterable[PgrFrameData],
    calibration: bytes = b"",
    layout: PgrLayout = DEFAULT_LAYOUT,
    version: int = 7,
) -> int:
    """Write a stream in the layout :class:`PgrStream` reads (synthetic data, tests); returns frame count."""
    blocks = [_frame_block(f, layout) for f in frames]
    base = len(SIGNATURE)
    data_offset = -(-(base + layout.head_info_size + len(calibration)) // 512) * 512  # 512-byte aligned
    head = bytearray(layout.head_info_size)
    for at, value in (
        (layout.head_version, version),
        (layout.head_config_size, len(calibration)),
        (layout.head_frame_count, len(blocks)),
        (layout.head_data_offset, data_offset),
    ):
        struct.pack_into("<I", head, at, value)
    prefix = SIGNATURE + bytes(head) + calibration
    Path(path).write_bytes(prefix + bytes(data_offset - len(prefix)) + b"".join(blocks))
    return len(blocks)
