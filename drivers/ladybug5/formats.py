"""Names of the Ladybug's data formats and Bayer patterns, and the numbers a .pgr stream file stores for them.

The SDK binding never uses a number from here: it takes the SDK's enum values from the installed ladybug.h
(layout_probe.c). A .pgr file is read without the SDK, so the numbers the SDK wrote into its head info are
listed here, as the enums of the Ladybug SDK header of 2017 (the same order as the SDK 1.10 C# interface):
data format RAW8 = 1 ... HALF_HEIGHT_RAW12 = 12, stippled format BGGR = 0, GBRG, GRBG, RGGB, DEFAULT = 4,
resolution 2448x2048 = 9, 2464x2048 = 12. Streams of older SDKs (Ladybug2 era) numbered formats differently;
their codes are reported as unknown, never guessed.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import Enum

import cv2

from drivers.ladybug5.errors import UnsupportedFormatError


class BayerPattern(Enum):
    """The colours of the top-left 2x2 pixels of a mosaic, row by row (``RGGB``: row 0 R G, row 1 G B)."""

    BGGR = "BGGR"
    GBRG = "GBRG"
    GRBG = "GRBG"
    RGGB = "RGGB"

    @property
    def to_bgr(self) -> int:
        """The OpenCV conversion code: a (H, W) mosaic of this pattern -> (H, W, 3) BGR."""
        return _TO_BGR[self]

    def colour_at(self, row: int, col: int) -> str:
        """``B``, ``G`` or ``R`` at pixel (row, col) of a mosaic of this pattern."""
        return self.value[2 * (row % 2) + col % 2]

    def shifted(self, rows: int, cols: int) -> BayerPattern:
        """The pattern of the mosaic cut ``rows`` rows and ``cols`` columns in from the top left (a border crop)."""
        cells = [self.colour_at(rows + r, cols + c) for r in (0, 1) for c in (0, 1)]
        return BayerPattern("".join(cells))


_TO_BGR = {
    # OpenCV's own names (BayerRG...) count from the second row; these aliases name the top-left 2x2 cells.
    BayerPattern.BGGR: cv2.COLOR_BayerBGGR2BGR,
    BayerPattern.GBRG: cv2.COLOR_BayerGBRG2BGR,
    BayerPattern.GRBG: cv2.COLOR_BayerGRBG2BGR,
    BayerPattern.RGGB: cv2.COLOR_BayerRGGB2BGR,
}


class DataFormat(Enum):
    """The SDK's data formats (``LADYBUG_DATAFORMAT_<value>``). rigd decodes RAW8, RAW12, RAW16, COLOR_SEP_JPEG8 and
    COLOR_SEP_JPEG12 (:mod:`drivers.ladybug5.raw`, :mod:`drivers.ladybug5.channels`); the others are named, not
    guessed at."""

    RAW8 = "RAW8"  # six Bayer mosaics, one after the other, 8 bits a pixel
    JPEG8 = "JPEG8"
    COLOR_SEP_RAW8 = "COLOR_SEP_RAW8"
    COLOR_SEP_JPEG8 = "COLOR_SEP_JPEG8"  # per camera 4 JPEGs, one per Bayer channel (a .pgr frame block)
    HALF_HEIGHT_RAW8 = "HALF_HEIGHT_RAW8"
    COLOR_SEP_HALF_HEIGHT_JPEG8 = "COLOR_SEP_HALF_HEIGHT_JPEG8"
    RAW16 = "RAW16"  # six Bayer mosaics, 16-bit little-endian words (where the 12 bits sit: raw.Raw16Bits)
    COLOR_SEP_JPEG12 = "COLOR_SEP_JPEG12"  # as COLOR_SEP_JPEG8, each channel a 12-bit-precision JPEG
    HALF_HEIGHT_RAW16 = "HALF_HEIGHT_RAW16"
    COLOR_SEP_HALF_HEIGHT_JPEG12 = "COLOR_SEP_HALF_HEIGHT_JPEG12"
    RAW12 = "RAW12"  # six Bayer mosaics, 2 pixels in 3 bytes (ladybug.h: P1 high 8, P2 high 8, the low nibbles)
    HALF_HEIGHT_RAW12 = "HALF_HEIGHT_RAW12"

    @property
    def decoded(self) -> bool:
        """Whether rigd decodes this format itself."""
        return self.raw_bits > 0 or self.jpeg_bits > 0

    @property
    def raw_bits(self) -> int:
        """Bits a pixel of a RAW mosaic occupies in the buffer (8, 12 packed, 16); 0 for the other formats."""
        return {DataFormat.RAW8: 8, DataFormat.RAW12: 12, DataFormat.RAW16: 16}.get(self, 0)

    @property
    def jpeg_bits(self) -> int:
        """Sample precision of a colour-separated JPEG format's channels (8 or 12); 0 for the other formats."""
        return {DataFormat.COLOR_SEP_JPEG8: 8, DataFormat.COLOR_SEP_JPEG12: 12}.get(self, 0)


DECODED_FORMATS = tuple(f for f in DataFormat if f.decoded)


def require_decoded(fmt: DataFormat, where: str) -> DataFormat:
    """``fmt`` if rigd decodes it, else an :class:`UnsupportedFormatError` naming it and what to use instead."""
    if fmt.decoded:
        return fmt
    why = "half-height frames' row layout is not public" if "HALF_HEIGHT" in fmt.value else \
        "rigd has no decoder for it"
    raise UnsupportedFormatError(
        f"{where}: data format {fmt.value} is not supported ({why}); record or start the camera in "
        f"{', '.join(f.value for f in DECODED_FORMATS)}"
    )


# What a .pgr head info stores (the SDK's enum values when it wrote the file; module docstring).
STREAM_FORMAT_CODES: dict[int, DataFormat] = {code: fmt for code, fmt in enumerate(DataFormat, start=1)}
STREAM_BAYER_CODES: dict[int, BayerPattern | None] = {
    0: BayerPattern.BGGR, 1: BayerPattern.GBRG, 2: BayerPattern.GRBG, 3: BayerPattern.RGGB, 4: None,  # camera default
}
STREAM_RESOLUTIONS: dict[int, tuple[int, int]] = {4: (1024, 768), 8: (1616, 1232), 9: (2448, 2048), 12: (2464, 2048)}


def stream_code(table: Mapping[int, object], value: object) -> int:
    """The stream file's number for ``value`` (the inverse of one of the tables above)."""
    return next(code for code, v in table.items() if v == value)
