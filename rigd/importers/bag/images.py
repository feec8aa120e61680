"""sensor_msgs/Image and CompressedImage as the dataset's images: (H,W) grey or (H,W,3) BGR uint8.

Raw encodings: mono8, mono16 (scaled to 8 bits by its maximum, as rigd reads 16-bit files), rgb8, bgr8, rgba8,
bgra8 and the 8-bit Bayer mosaics (demosaiced by OpenCV; ROS names a mosaic by its first row, OpenCV by its
second, so ``bayer_rggb8`` is OpenCV's BayerBG, as cv_bridge maps it). Rows may be padded (``step``), and 16-bit
data may be big-endian. Compressed: JPEG and PNG (``format`` is "jpeg", "png", or image_transport's
"rgb8; jpeg compressed bgr8", whose data is BGR as OpenCV decodes it); compressedDepth is refused.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from rigd.importers.bag.errors import BagError

U8 = NDArray[np.uint8]

CHANNELS = {"mono8": 1, "mono16": 1, "8UC1": 1, "16UC1": 1, "rgb8": 3, "bgr8": 3, "8UC3": 3, "rgba8": 4,
            "bgra8": 4}
BAYER = {"bayer_rggb8": cv2.COLOR_BayerBG2BGR, "bayer_bggr8": cv2.COLOR_BayerRG2BGR,
         "bayer_gbrg8": cv2.COLOR_BayerGR2BGR, "bayer_grbg8": cv2.COLOR_BayerGB2BGR}
TO_BGR = {"rgb8": cv2.COLOR_RGB2BGR, "rgba8": cv2.COLOR_RGBA2BGR, "bgra8": cv2.COLOR_BGRA2BGR}
SIXTEEN_BIT = ("mono16", "16UC1")
ENCODINGS = (*CHANNELS, *BAYER)


def _rows(message: Any, bytes_per_pixel: int, where: str) -> NDArray[np.uint8]:
    """(H, W * bytes_per_pixel) uint8: the image's rows without their padding."""
    height, width, step = int(message.height), int(message.width), int(message.step)
    data = np.asarray(message.data, dtype=np.uint8)
    row_bytes = width * bytes_per_pixel
    if height <= 0 or width <= 0 or step < row_bytes or data.size < step * (height - 1) + row_bytes:
        raise BagError(f"{where}: image data of {data.size} bytes does not hold {width}x{height} {message.encoding} "
                       f"with a row step of {step} bytes")
    padded = np.resize(data, step * height) if data.size < step * height else data[: step * height]
    return np.ascontiguousarray(padded.reshape(height, step)[:, :row_bytes])


def scaled_to_8bit(image: NDArray[np.integer[Any]]) -> U8:
    """A 16-bit image scaled to 8 bits by its maximum (rigd.dataset.store.read_image does the same)."""
    return np.asarray(cv2.convertScaleAbs(image, alpha=255.0 / max(float(image.max()), 1.0)), dtype=np.uint8)


def decode_image(message: Any, *, where: str) -> U8:
    """A sensor_msgs/Image as (H,W) grey or (H,W,3) BGR uint8; ``where`` names it in errors (topic and time)."""
    encoding = str(message.encoding)
    height, width = int(message.height), int(message.width)
    if encoding in BAYER:
        return np.asarray(cv2.cvtColor(_rows(message, 1, where), BAYER[encoding]), dtype=np.uint8)
    if encoding not in CHANNELS:
        raise BagError(f"{where}: unknown image encoding {encoding!r}; rigd reads {', '.join(ENCODINGS)}")
    channels = CHANNELS[encoding]
    if encoding in SIXTEEN_BIT:
        rows = _rows(message, 2, where)
        order = ">" if int(message.is_bigendian) else "<"
        return scaled_to_8bit(rows.view(f"{order}u2").astype(np.uint16).reshape(height, width))
    rows = _rows(message, channels, where)
    image = rows.reshape(height, width, channels) if channels > 1 else rows
    if encoding in TO_BGR:
        return np.ascontiguousarray(cv2.cvtColor(image, TO_BGR[encoding]), dtype=np.uint8)
    return np.ascontiguousarray(image, dtype=np.uint8)


def decode_compressed(message: Any, *, where: str) -> U8:
    """A sensor_msgs/CompressedImage (JPEG or PNG) as (H,W) grey or (H,W,3) BGR uint8."""
    fmt = str(message.format).lower()
    if "compresseddepth" in fmt:
        raise BagError(f"{where}: compressed depth images ({message.format!r}) are not camera images")
    if not any(name in fmt for name in ("jpeg", "jpg", "png")):
        raise BagError(f"{where}: unknown compressed image format {message.format!r}; rigd reads jpeg and png")
    decoded = cv2.imdecode(np.asarray(message.data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if decoded is None or decoded.size == 0:
        raise BagError(f"{where}: compressed image ({message.format!r}, {len(message.data)} bytes) does not decode")
    image = scaled_to_8bit(np.asarray(decoded, dtype=np.uint16)) if decoded.dtype == np.uint16 else \
        np.asarray(decoded, dtype=np.uint8)
    if image.ndim == 3 and image.shape[2] == 4:
        image = np.asarray(cv2.cvtColor(image, cv2.COLOR_BGRA2BGR), dtype=np.uint8)
    return np.ascontiguousarray(image, dtype=np.uint8)

