"""Pictures the API serves: overlays scaled down for a screen, and a captured pair's cloud seen from above."""

from __future__ import annotations

import pathlib
from enum import Enum
from typing import Annotated

import cv2
import numpy as np
from fastapi import Query
from fastapi.responses import FileResponse, Response
from numpy.typing import NDArray

from calib.geometry import Transform
from rigd.calibration.visuals import cloud_top_view
from rigd.dataset import Dataset
from rigd.errors import RigdError
from rigd.store import NotFoundError


class ImageFormat(Enum):
    """How an image is sent: PNG (lossless, as the files are) or JPEG (a screen's copy: a 1920 px overlay is
    about 0.8 MB as PNG and a third of that as JPEG at quality 90, encoded in ~10 ms; WebP took 20 times as
    long to encode per request for a little less)."""

    PNG = "png"
    JPEG = "jpeg"


FormatQuery = Annotated[ImageFormat | None, Query(
    description="png | jpeg: jpeg for a screen (a third of the bytes); absent: png, a file no wider sent as it is")]
JPEG_QUALITY = 90  # the dots' colours and dark rims stay distinct at this quality


def encoded(image: NDArray[np.uint8], name: str, fmt: ImageFormat) -> bytes:
    """``image`` as ``fmt`` bytes."""
    if fmt is ImageFormat.PNG:
        return png(image, name)
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise RigdError(f"{name} could not be encoded as JPEG")
    return data.tobytes()


def png(image: NDArray[np.uint8], name: str) -> bytes:
    """``image`` as PNG bytes (fast compression: these are made per request)."""
    ok, encoded = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:
        raise RigdError(f"{name} could not be encoded as PNG")
    return encoded.tobytes()


def narrowed(image: NDArray[np.uint8], width: int) -> NDArray[np.uint8]:
    """``image`` scaled down (area averaging) to ``width`` px if it is wider."""
    if image.shape[1] <= width:
        return image
    height = max(1, round(image.shape[0] * width / image.shape[1]))
    return np.asarray(cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA), np.uint8)


def png_width(path: pathlib.Path) -> int | None:
    """The width of the PNG file at ``path`` from its header, None if it is no PNG."""
    with path.open("rb") as fh:
        head = fh.read(24)
    if head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return int.from_bytes(head[16:20], "big")


def image_response(path: pathlib.Path, width: int | None, fmt: ImageFormat | None = None,
                   immutable: bool = False) -> Response:
    """The image file at ``path``, or, when it is wider than ``width`` or ``fmt`` asks for JPEG, a copy scaled
    down to ``width`` in ``fmt`` (PNG by default). A PNG file no wider is sent as it is (no decoding; the browser
    may keep it: ETag). ``immutable``: the file never changes (a version's overlays), so a copy may be kept."""
    wanted = fmt or ImageFormat.PNG
    as_it_is = wanted is ImageFormat.PNG or path.suffix.lower() in (".jpg", ".jpeg")
    if as_it_is and (width is None or (png_width(path) or width + 1) <= width):
        return FileResponse(path)
    headers = {"Cache-Control": "private, max-age=86400"} if immutable else None
    return Response(narrowed_image(path, width, wanted), media_type=f"image/{wanted.value}", headers=headers)


def narrowed_image(path: pathlib.Path, width: int | None, fmt: ImageFormat) -> bytes:
    """The image file at ``path`` as ``fmt``, scaled down to ``width`` px if it is wider (None: as wide)."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise NotFoundError(f"the image {path.name} cannot be read")
    pixels: NDArray[np.uint8] = np.asarray(image, np.uint8)
    return encoded(narrowed(pixels, width) if width else pixels, path.name, fmt)


def pair_cloud_from_above(dataset: Dataset, index: int, width: int | None) -> bytes:
    """Pair ``index``'s cloud seen from above as PNG, each point in the colour of the pixel it lands on with the
    dataset's initial guess (grey without one): a look at a pair before any calibration."""
    pair = dataset.load_pair(index)
    guess = dataset.rig.initial_guess
    views = list(zip(pair.images, dataset.rig.camera.models(), dataset.masks, strict=True)) if guess else []
    picture = cloud_top_view(views, guess or Transform.identity(), pair.cloud.points_lidar)
    return png(narrowed(picture, width) if width else picture, f"the cloud of pair {pair.index}")
