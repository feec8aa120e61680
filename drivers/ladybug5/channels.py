"""A JPEG frame block's 24 channel JPEGs (6 cameras x 4 Bayer channels), judged one by one as the SDK and public
readers judge them: by the table entry, the JPEG start marker and the decoder.

The block's table gives each channel's (offset, size). Point Grey's own frame parser reads a size of 0 as "the
compressor did not finish" (offset 0) or "the JPEG buffer was too small" (offset not 0), checks the fingerprint and
reads the JPEG's own size; no public reader checks that a JPEG ends in ``FF D9`` (a camera may pad lengths). So here:
an entry that gives no bytes, bytes that do not start with ``FF D8``, or a JPEG the decoder refuses (OpenCV refuses a
truncated 8-bit JPEG) is a :class:`ChannelFault` of that channel; bytes after the end-of-image marker are padding.
A camera with a faulty channel is missing from the frame; a frame keeps its other cameras (:class:`CameraSet`),
and its users decide how many they need (a panorama: five; a head frame: all six).

8-bit channels decode with OpenCV; 12-bit channels (COLOR_SEP_JPEG12, standard 12-bit-precision JPEGs, as a public
Ladybug5+ stream viewer decodes them) with imagecodecs, whose libjpeg-turbo reads 12-bit JPEG (OpenCV's does not).
imagecodecs fills a truncated JPEG instead of refusing it, so a 12-bit channel must also hold its end marker.
"""

from __future__ import annotations

import mmap
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import CorruptFrameError
from drivers.ladybug5.pgr_layout import FINGERPRINT, JPEG_EOI, JPEG_SOI, JPEGS_PER_CAMERA, NUM_CAMERAS, PgrLayout, u32be

HIGH_BITS_SHIFT = {8: 0, 12: 4}  # a decoded channel's shift to put its bits at the top of a uint16 (12-bit)


@dataclass(frozen=True)
class ChannelFault:
    """Why channel JPEG ``channel`` (0-3) of ``camera`` (0-5) was not used."""

    camera: int
    channel: int
    reason: str

    def __str__(self) -> str:
        return f"camera {self.camera} channel {self.channel}: {self.reason}"


@dataclass(frozen=True)
class BlockJpegs:
    """The 6 x 4 channel JPEGs of one frame block: ``jpegs[c][k]`` the bytes (None where the table gives none that
    start a JPEG) and the ``faults`` found in the table."""

    jpegs: tuple[tuple[bytes | None, ...], ...]
    faults: tuple[ChannelFault, ...]

    def complete(self, where: str) -> list[list[bytes]]:
        """All 24 JPEGs; a :class:`CorruptFrameError` naming every faulty channel otherwise."""
        if self.faults:
            raise CorruptFrameError(f"{where}: " + "; ".join(str(f) for f in self.faults))
        return [[cast(bytes, j) for j in row] for row in self.jpegs]


@dataclass(frozen=True)
class CameraSet:
    """One frame's six cameras: ``arrays[c]`` camera c's mosaic or image (uint8, or uint16 with its significant
    bits at the top), None for a camera with a faulty channel; every fault found."""

    arrays: tuple[NDArray[Any] | None, ...]
    faults: tuple[ChannelFault, ...] = ()

    @property
    def missing(self) -> tuple[int, ...]:
        return tuple(c for c, m in enumerate(self.arrays) if m is None)

    def map(self, function: Callable[[NDArray[Any]], NDArray[Any]]) -> CameraSet:
        """``function`` applied to every camera there is (e.g. demosaicing), the faults kept."""
        return CameraSet(tuple(None if a is None else function(a) for a in self.arrays), self.faults)

    def require(self, min_cameras: int, where: str) -> CameraSet:
        """This frame if at least ``min_cameras`` cameras decoded; else a :class:`CorruptFrameError` naming the
        faults (a frame with fewer is not kept)."""
        good = NUM_CAMERAS - len(self.missing)
        if good < min_cameras:
            raise CorruptFrameError(f"{where}: {good} of {NUM_CAMERAS} cameras decode ({min_cameras} needed): "
                                    + "; ".join(str(f) for f in self.faults))
        return self


def _entry(buf: bytes | mmap.mmap, offset: int, size: int, camera: int, channel: int,
           layout: PgrLayout) -> bytes | ChannelFault:
    """Channel JPEG bytes as far as the block holds them, or why there are none."""
    at, length = struct.unpack_from(">2I", buf, offset + layout.jpeg_table + camera * 32 + channel * 8)
    if length == 0:
        why = "the camera's JPEG compression did not finish" if at == 0 else "the camera's JPEG buffer was too small"
        return ChannelFault(camera, channel, f"no data (size 0: {why})")
    if not layout.frame_header_size <= at < size:
        return ChannelFault(camera, channel, f"offset {at} is outside the {size}-byte frame block")
    data = bytes(buf[offset + at : offset + min(at + length, size)])  # a length past the block: the decoder judges
    if not data.startswith(JPEG_SOI):
        return ChannelFault(camera, channel, f"no JPEG start marker (FF D8) at offset {at}")
    return data


def block_jpegs(buf: bytes | mmap.mmap, offset: int, size: int, layout: PgrLayout, where: str) -> BlockJpegs:
    """The channel JPEGs of the JPEG frame block at ``buf[offset : offset + size]``; a block without its header or
    fingerprint is a :class:`CorruptFrameError` (nothing in it can be trusted)."""
    if size < layout.frame_header_size or u32be(buf, offset + layout.fingerprint) != FINGERPRINT:
        raise CorruptFrameError(f"{where}: not a frame block (size {size}, no 0x{FINGERPRINT:X} fingerprint)")
    rows, faults = [], []
    for camera in range(NUM_CAMERAS):
        row: list[bytes | None] = []
        for channel in range(JPEGS_PER_CAMERA):
            got = _entry(buf, offset, size, camera, channel, layout)
            faults.extend([got] if isinstance(got, ChannelFault) else [])
            row.append(None if isinstance(got, ChannelFault) else got)
        rows.append(tuple(row))
    return BlockJpegs(tuple(rows), tuple(faults))


def decode_channel(data: bytes, bits: int) -> NDArray[Any] | str:
    """One channel JPEG: (h, w) uint8 (8-bit) or uint16 with its 12 bits at the top (12-bit); else why not."""
    refused = "the JPEG decoder refuses it (truncated or corrupt)"
    if bits == 8:
        plane = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
        return refused if plane is None else cast(NDArray[np.uint8], plane)
    if JPEG_EOI not in data[2:]:  # imagecodecs would fill a truncated JPEG rather than refuse it
        return "no JPEG end marker (FF D9): truncated"
    import imagecodecs  # only 12-bit streams need it

    try:
        decoded = np.asarray(imagecodecs.jpeg8_decode(data))
    except imagecodecs.Jpeg8Error:
        return refused
    if decoded.ndim != 2 or decoded.dtype != np.uint16:
        return f"a {decoded.dtype.itemsize * 8}-bit JPEG in a 12-bit stream"
    return cast(NDArray[np.uint16], decoded << HIGH_BITS_SHIFT[bits])


def camera_mosaic(planes: Sequence[bytes | None], layout: PgrLayout, camera: int,
                  bits: int) -> NDArray[Any] | list[ChannelFault]:
    """Four channel JPEGs (h, w) -> one (2h, 2w) mosaic (channel k to cell ``slot_cells[k]``), or the faults."""
    decoded = [None if p is None else decode_channel(p, bits) for p in planes]
    faults = [ChannelFault(camera, k, d) for k, d in enumerate(decoded) if isinstance(d, str)]
    good = [d for d in decoded if d is not None and not isinstance(d, str)]
    if faults or len(good) != len(planes):
        return faults
    if len({d.shape for d in good}) != 1:
        sizes = ", ".join(f"{d.shape[1]}x{d.shape[0]}" for d in good)
        return [ChannelFault(camera, k, f"channel sizes differ ({sizes})") for k in range(len(planes))]
    h, w = good[0].shape
    mosaic = np.empty((2 * h, 2 * w), good[0].dtype)
    for (r, c), plane in zip(layout.slot_cells, good, strict=True):
        mosaic[r::2, c::2] = plane
    return mosaic


def frame_mosaics(block: BlockJpegs, layout: PgrLayout, bits: int = 8) -> CameraSet:
    """Each camera's mosaic, None for a camera with a faulty channel (all faults kept)."""
    mosaics: list[NDArray[Any] | None] = []
    faults = list(block.faults)
    for camera, planes in enumerate(block.jpegs):
        if any(p is None for p in planes):  # its table fault is already listed
            mosaics.append(None)
            continue
        got = camera_mosaic(planes, layout, camera, bits)
        faults.extend(got if isinstance(got, list) else [])
        mosaics.append(None if isinstance(got, list) else got)
    return CameraSet(tuple(mosaics), tuple(faults))


def assemble_mosaic(planes: Sequence[bytes], layout: PgrLayout, where: str, bits: int = 8) -> NDArray[Any]:
    """Four channel JPEGs -> one mosaic; a :class:`CorruptFrameError` naming the faulty channels otherwise."""
    got = camera_mosaic(planes, layout, 0, bits)
    if isinstance(got, list):
        raise CorruptFrameError(f"{where}: " + "; ".join(f"channel {f.channel}: {f.reason}" for f in got))
    return got
