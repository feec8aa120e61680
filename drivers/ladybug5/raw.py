"""Six Bayer mosaics -> six BGR sensor images: slicing by the full sensor size, border crop, demosaicing.

A Ladybug5 frame (``LadybugImage``) holds each sensor's *full* image, ``uiFullCols`` x ``uiFullRows``,
one after the other; the useful image is ``uiCols`` x ``uiRows`` inside a border of masked pixels
(``imageBorder``: top, bottom, left, right). Slicing by ``uiCols * uiRows`` would shift cameras 1-5 and shear
their rows as soon as there is a border. The mosaic is cut to the useful image *before* demosaicing, so the
masked pixels never bleed into the edge; the Bayer pattern (which the SDK reports for the full image's top-left
pixel) is shifted by the cut.

Bit depths: an image wider than 8 bits is uint16 with its significant bits at the top (full scale 65535), whatever
the format sent, so that every user (the 8-bit view, a 16-bit dataset image) reads it alike. RAW12 is unpacked by
ladybug.h's layout (:func:`unpack_raw12`); COLOR_SEP_JPEG12 channels are 12-bit JPEGs (:mod:`channels`); RAW16 is
"16 bpp" in ladybug.h, with no word on where a 12-bit sensor's bits sit, so :class:`Raw16Bits` says, or tells them
from the data (:func:`raw16_bits`).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import CorruptFrameError
from drivers.ladybug5.formats import BayerPattern, DataFormat, require_decoded

NUM_SENSORS = 6
LOW12_MAX = 0x0FFF  # the largest 12-bit value


class Raw16Bits(Enum):
    """Where a RAW16 (or 16-bit image file) word holds its data."""

    AUTO = "auto"  # per frame: LOW12 when no word exceeds 0x0FFF and some use the low nibble, else HIGH
    HIGH = "high"  # as sent: full-scale 16-bit words, or 12 bits at the top (low nibble 0)
    LOW12 = "low12"  # 12 bits in the low bits (an unpacked RAW12): shifted up by 4


def raw16_bits(words: NDArray[np.uint16], choice: Raw16Bits = Raw16Bits.AUTO) -> Raw16Bits:
    """``choice`` resolved for these words. Data with 12 bits at the top has a zero low nibble; data in the low
    bits never exceeds 0x0FFF and uses its low nibble: only a frame of 16-bit data darker than 1/16 of full scale
    everywhere could be taken for LOW12 (give HIGH for such a camera)."""
    if choice is not Raw16Bits.AUTO:
        return choice
    low12 = words.size > 0 and int(words.max()) <= LOW12_MAX and bool(np.any(words & 0x000F))
    return Raw16Bits.LOW12 if low12 else Raw16Bits.HIGH


def high_aligned(words: NDArray[np.uint16], choice: Raw16Bits = Raw16Bits.AUTO) -> NDArray[np.uint16]:
    """16-bit words with their significant bits at the top."""
    if raw16_bits(words, choice) is Raw16Bits.LOW12:
        return cast(NDArray[np.uint16], (words << 4).astype(np.uint16))
    return words


def unpack_raw12(data: bytes | memoryview, pixels: int) -> NDArray[np.uint16]:
    """(pixels,) uint16 with 12 bits at the top from RAW12: per ladybug.h, two pixels in three bytes, P1's high 8
    bits, P2's high 8 bits, then their low 4 bits (P1's in the high nibble, read in the header's order)."""
    packed = np.frombuffer(data, np.uint8, pixels * 3 // 2).reshape(-1, 3).astype(np.uint16)
    out = np.empty(pixels, np.uint16)
    out[0::2] = (packed[:, 0] << 8) | (packed[:, 2] & 0xF0)
    out[1::2] = (packed[:, 1] << 8) | ((packed[:, 2] & 0x0F) << 4)
    return out


@dataclass(frozen=True)
class Border:
    """Masked pixels around the useful image, in px."""

    top: int = 0
    bottom: int = 0
    left: int = 0
    right: int = 0


@dataclass(frozen=True)
class SensorGeometry:
    """One sensor's image as the camera sends it: the useful ``cols`` x ``rows`` inside ``border``."""

    cols: int
    rows: int
    border: Border = Border()

    @property
    def full_cols(self) -> int:
        return self.cols + self.border.left + self.border.right

    @property
    def full_rows(self) -> int:
        return self.rows + self.border.top + self.border.bottom

    @classmethod
    def from_full(cls, full_cols: int, full_rows: int, border: Border, where: str) -> SensorGeometry:
        """From the full size and the border; an error when the border does not fit inside."""
        cols = full_cols - border.left - border.right
        rows = full_rows - border.top - border.bottom
        if cols <= 0 or rows <= 0:
            raise CorruptFrameError(f"{where}: border {border} does not fit a {full_cols}x{full_rows} sensor image")
        return cls(cols, rows, border)


def crop_mosaic(mosaic: NDArray[Any], geometry: SensorGeometry, pattern: BayerPattern) -> tuple[NDArray[Any],
                                                                                              BayerPattern]:
    """The useful part of a full (full_rows, full_cols) mosaic and its Bayer pattern."""
    b = geometry.border
    useful = mosaic[b.top : b.top + geometry.rows, b.left : b.left + geometry.cols]
    return np.ascontiguousarray(useful), pattern.shifted(b.top, b.left)


def demosaic(mosaic: NDArray[Any], pattern: BayerPattern) -> NDArray[Any]:
    """(H, W) uint8/uint16 Bayer mosaic -> (H, W, 3) BGR of the same dtype (OpenCV bilinear)."""
    return cast(NDArray[Any], cv2.cvtColor(mosaic, pattern.to_bgr))


def _raw_mosaics(data: bytes | memoryview, fmt: DataFormat, pixels: int, raw16: Raw16Bits) -> NDArray[Any]:
    """All six mosaics' pixels (uint8 for RAW8, uint16 with the bits at the top otherwise)."""
    if fmt is DataFormat.RAW8:
        return np.frombuffer(data, np.uint8, pixels)
    if fmt is DataFormat.RAW12:
        return unpack_raw12(data, pixels)
    return high_aligned(np.frombuffer(data, np.dtype("<u2"), pixels).astype(np.uint16), raw16)


def decode_raw(data: bytes | memoryview, fmt: DataFormat, geometry: SensorGeometry, pattern: BayerPattern,
               where: str, raw16: Raw16Bits = Raw16Bits.AUTO) -> list[NDArray[Any]]:
    """Six (rows, cols, 3) BGR images from a buffer of six full mosaics one after the other: uint8 (RAW8) or uint16
    with the significant bits at the top (RAW12, RAW16 as ``raw16`` says). Bytes past the six mosaics (padding) are
    ignored."""
    bits = require_decoded(fmt, where).raw_bits
    if bits == 0:
        raise CorruptFrameError(f"{where}: {fmt.value} is not a RAW format")
    per_sensor = geometry.full_cols * geometry.full_rows
    needed = NUM_SENSORS * per_sensor * bits // 8
    if len(data) < needed:
        raise CorruptFrameError(
            f"{where}: {fmt.value} buffer has {len(data)} bytes; six {geometry.full_cols}x{geometry.full_rows} "
            f"sensor images need {needed}"
        )
    mosaics = _raw_mosaics(data, fmt, NUM_SENSORS * per_sensor, raw16).reshape(
        NUM_SENSORS, geometry.full_rows, geometry.full_cols
    )
    return [demosaic(*crop_mosaic(mosaic, geometry, pattern)) for mosaic in mosaics]


def fit_mosaic(mosaic: NDArray[Any], geometry: SensorGeometry, pattern: BayerPattern,
               where: str) -> tuple[NDArray[Any], BayerPattern]:
    """A mosaic of unknown extent (a JPEG frame's) cut to the useful size: one of the full size loses the
    border, one already of the useful size is kept; any other size is an error naming both."""
    size = mosaic.shape[:2]
    if size == (geometry.rows, geometry.cols):
        return mosaic, pattern
    if size == (geometry.full_rows, geometry.full_cols):
        return crop_mosaic(mosaic, geometry, pattern)
    raise CorruptFrameError(
        f"{where}: mosaic is {size[1]}x{size[0]}, the frame says {geometry.cols}x{geometry.rows} inside "
        f"{geometry.full_cols}x{geometry.full_rows}"
    )


def to_uint8(image: NDArray[Any], raw16: Raw16Bits = Raw16Bits.AUTO) -> NDArray[np.uint8]:
    """8-bit view of a decoded image: uint16 keeps its top 8 significant bits (:func:`raw16_bits` says where they
    are when the image did not come from rigd's decoders, e.g. a 16-bit image file)."""
    if image.dtype == np.uint8:
        return cast(NDArray[np.uint8], image)
    return (high_aligned(image.astype(np.uint16, copy=False), raw16) >> 8).astype(np.uint8)
