"""Six Bayer mosaics -> six BGR sensor images: slicing by the full sensor size, border crop, demosaicing.

A Ladybug5 frame (``LadybugImage``) holds each sensor's *full* image, ``uiFullCols`` x ``uiFullRows``,
one after the other; the useful image is ``uiCols`` x ``uiRows`` inside a border of masked pixels
(``imageBorder``: top, bottom, left, right). Slicing by ``uiCols * uiRows`` would shift cameras 1-5 and shear
their rows as soon as there is a border. The mosaic is cut to the useful image *before* demosaicing, so the
masked pixels never bleed into the edge; the Bayer pattern (which the SDK reports for the full image's top-left
pixel) is shifted by the cut.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import CorruptFrameError
from drivers.ladybug5.formats import BayerPattern, DataFormat, require_decoded

NUM_SENSORS = 6


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


def decode_raw(data: bytes | memoryview, fmt: DataFormat, geometry: SensorGeometry, pattern: BayerPattern,
               where: str) -> list[NDArray[Any]]:
    """Six (rows, cols, 3) BGR images, uint8 (RAW8) or uint16 (RAW16, as sent: 16-bit little-endian words), from
    a buffer of six full mosaics one after the other. Bytes past the six mosaics (padding) are ignored."""
    bpp = require_decoded(fmt, where).raw_bytes_per_pixel
    if bpp == 0:
        raise CorruptFrameError(f"{where}: {fmt.value} is not a RAW format")
    per_sensor = geometry.full_cols * geometry.full_rows
    needed = NUM_SENSORS * per_sensor * bpp
    if len(data) < needed:
        raise CorruptFrameError(
            f"{where}: {fmt.value} buffer has {len(data)} bytes; six {geometry.full_cols}x{geometry.full_rows} "
            f"sensor images need {needed}"
        )
    dtype = np.dtype(np.uint8) if bpp == 1 else np.dtype("<u2")
    mosaics = np.frombuffer(data, dtype, NUM_SENSORS * per_sensor).reshape(
        NUM_SENSORS, geometry.full_rows, geometry.full_cols
    )
    out = []
    for mosaic in mosaics:
        useful, shifted = crop_mosaic(mosaic.astype(np.uint16) if bpp == 2 else mosaic, geometry, pattern)
        out.append(demosaic(useful, shifted))
    return out


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


def to_uint8(image: NDArray[Any]) -> NDArray[np.uint8]:
    """8-bit view of a decoded image: uint16 (RAW16) keeps its top 8 bits."""
    if image.dtype == np.uint8:
        return cast(NDArray[np.uint8], image)
    return (image >> 8).astype(np.uint8)
