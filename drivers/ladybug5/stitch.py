"""Equirectangular panorama from the six camera images by precomputed ``cv2.remap`` maps.

Model (docs/ladybug5.md, "Stitching"): every panorama pixel is a ray from the head centre; the scene is
assumed to lie on a sphere of ``radius_m`` around it, so the pixel's 3-D point is ``radius_m * ray``
(head frame). Each camera sees that point at its own pixel (pinhole + distortion); cameras that see it
are blended with feathered weights (distance to the camera image's border), normalised to sum to 1.
Scene points nearer or farther than the sphere are seen from ~4.5 cm apart by neighbouring cameras and
appear doubled in the overlaps (parallax); ``radius_m = inf`` stitches by direction only.

Panorama convention (docs/conventions.md): x forward, y left, z up; ``theta = atan2(y, x)``,
``phi = acos(z / r)``, ``u = w (pi - theta) / (2 pi)``, ``v = h phi / pi``; pixel (row i, column j) is
``(u, v) = (j, i)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import Ladybug5Error
from drivers.ladybug5.rig import RigCamera, RigCameras

F64 = NDArray[np.float64]
PANORAMA_SIZES = ((2048, 1024), (1024, 512))
DEFAULT_RADIUS_M = 20.0  # street scale; indoors 3-5 m fits better (docs/ladybug5.md, parallax)


@dataclass(frozen=True)
class PanoramaSpec:
    """Output size in px and the stitching sphere's radius in m (``math.inf``: direction only)."""

    width: int = PANORAMA_SIZES[0][0]
    height: int = PANORAMA_SIZES[0][1]
    radius_m: float = DEFAULT_RADIUS_M

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0 or not self.radius_m > 0:
            raise Ladybug5Error(f"bad panorama spec {self}: size and radius must be positive")


def panorama_rays(width: int, height: int) -> F64:
    """Unit rays (H, W, 3) in the panorama frame of every pixel centre (project convention)."""
    u = np.arange(width, dtype=np.float64)
    v = np.arange(height, dtype=np.float64)
    theta = np.pi - 2.0 * np.pi * u / width
    phi = np.pi * v / height
    sin_phi = np.sin(phi)[:, None]
    return np.stack(
        np.broadcast_arrays(sin_phi * np.cos(theta)[None, :], sin_phi * np.sin(theta)[None, :], np.cos(phi)[:, None]),
        axis=-1,
    )


def _column_runs(columns: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """[start, stop) runs of True in a 1-D mask."""
    padded = np.concatenate([[False], columns, [False]])
    edges = np.flatnonzero(padded[1:] != padded[:-1])
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist(), strict=True))


@dataclass(frozen=True)
class _Tile:
    """One camera's contribution to a panorama block: fixed-point remap maps and float32 weights."""

    camera: int
    rows: slice
    cols: slice
    map1: NDArray[np.int16]
    map2: NDArray[np.uint16]
    weight: NDArray[np.float32]  # (h, w, 1), already divided by the sum over cameras


class Stitcher:
    """Precomputes remap maps for one rig and panorama spec; ``stitch`` then costs 6 remaps and a sum.
    ``masks``: per camera, (H,W) bool True where its image shows the scene (None: all of it); a masked pixel
    (the vehicle's body, a rectified image's black surround) gives no weight to the panorama."""

    def __init__(self, rig: RigCameras, spec: PanoramaSpec = PanoramaSpec(),
                 masks: Sequence[NDArray[np.bool_] | None] | None = None) -> None:
        self.rig = rig
        self.spec = spec
        rays = panorama_rays(spec.width, spec.height).reshape(-1, 3)
        points_head = rays if math.isinf(spec.radius_m) else rays * spec.radius_m
        masks = list(masks) if masks is not None else [None] * len(rig.cameras)
        if len(masks) != len(rig.cameras):
            raise Ladybug5Error(f"stitch needs one mask (or None) per camera, got {len(masks)} for {len(rig.cameras)}")
        maps, weights = zip(*(self._camera_map(c, points_head, m) for c, m in zip(rig.cameras, masks, strict=True)),
                            strict=True)
        total = np.sum(weights, axis=0)
        self.coverage = (total > 0).reshape(spec.height, spec.width)  # (H, W) seen by some camera
        seen_by = np.sum([w > 0 for w in weights], axis=0).reshape(spec.height, spec.width)
        self.overlap = seen_by >= 2  # (H, W) blended from two or more cameras: where seams and parallax are
        normalised = [w / np.where(total > 0, total, 1.0) for w in weights]
        self._tiles = [tile for i in range(len(rig.cameras)) for tile in self._tiles_for(i, maps[i], normalised[i])]

    def _camera_map(self, camera: RigCamera, points_head: F64, mask: NDArray[np.bool_] | None) -> tuple[F64, F64]:
        """Raw-image uv (N,2) of every panorama pixel and its feather weight (N,) (0 where not seen)."""
        if math.isinf(self.spec.radius_m):
            points_cam = points_head @ camera.R_head_camera  # R^T d, translation is irrelevant at infinity
        else:
            points_cam = (points_head - camera.t_head_camera_m) @ camera.R_head_camera
        uv, valid = camera.project(points_cam)
        border_px = np.minimum.reduce(
            [uv[:, 0], camera.width - 1.0 - uv[:, 0], uv[:, 1], camera.height - 1.0 - uv[:, 1]]
        )
        # Distance to the image border ramps the weight down to 0 at the edge: seams blend smoothly.
        weight = np.where(valid, np.maximum(border_px, 0.0) + 1e-3, 0.0)
        if mask is not None:
            if mask.shape != (camera.height, camera.width):
                raise Ladybug5Error(f"{camera.name}: mask is {mask.shape[1]}x{mask.shape[0]}, the camera "
                                    f"{camera.width}x{camera.height}")
            px = np.clip(np.rint(uv).astype(np.int64), 0, [camera.width - 1, camera.height - 1])
            weight = np.where(mask[px[:, 1], px[:, 0]], weight, 0.0)
        return uv, weight

    def _tiles_for(self, index: int, uv: F64, weight: F64) -> list[_Tile]:
        h, w = self.spec.height, self.spec.width
        weight_img = weight.reshape(h, w)
        seen = weight_img > 0
        rows = np.flatnonzero(seen.any(axis=1))
        if rows.size == 0:
            return []
        row_slice = slice(int(rows[0]), int(rows[-1]) + 1)
        uv_img = uv.reshape(h, w, 2).astype(np.float32)
        tiles = []
        for c0, c1 in _column_runs(cast(NDArray[np.bool_], seen.any(axis=0))):
            block = (row_slice, slice(c0, c1))
            map1, map2 = cv2.convertMaps(uv_img[block][..., 0], uv_img[block][..., 1], cv2.CV_16SC2)
            tiles.append(
                _Tile(index, row_slice, slice(c0, c1), cast(NDArray[np.int16], map1), cast(NDArray[np.uint16], map2),
                      weight_img[block][..., None].astype(np.float32))
            )
        return tiles

    def _check(self, images: Sequence[NDArray[Any] | None]) -> NDArray[Any]:
        """The first image there is, after checking every image's size against its camera."""
        if len(images) != len(self.rig.cameras):
            raise Ladybug5Error(f"stitch needs {len(self.rig.cameras)} images, got {len(images)}")
        for image, camera in zip(images, self.rig.cameras, strict=True):
            if image is not None and image.shape[:2] != (camera.height, camera.width):
                raise Ladybug5Error(
                    f"{camera.name}: image is {image.shape[1]}x{image.shape[0]}, rig file says "
                    f"{camera.width}x{camera.height}"
                )
        first = next((im for im in images if im is not None), None)
        if first is None:
            raise Ladybug5Error("stitch needs at least one camera's image, got none")
        return first

    def stitch(self, images: Sequence[NDArray[Any] | None]) -> NDArray[Any]:
        """Panorama (H, W[, C]) in the images' dtype from one image per rig camera (raw orientation); None for a
        camera missing from the frame: its neighbours' weights fill its overlaps, the rest of its view is 0.

        Pixels no camera sees (below the head) are 0; see ``coverage``.
        """
        first = self._check(images)
        channels = first.shape[2:]
        out = np.zeros((self.spec.height, self.spec.width, *channels), dtype=np.float32)
        missing = any(im is None for im in images)
        total = np.zeros((self.spec.height, self.spec.width, 1), np.float32) if missing else None
        for tile in self._tiles:
            image = images[tile.camera]
            if image is None:
                continue
            warped = cv2.remap(image, tile.map1, tile.map2, cv2.INTER_LINEAR)
            weight = tile.weight if channels else tile.weight[..., 0]
            out[tile.rows, tile.cols] += warped * weight
            if total is not None:
                total[tile.rows, tile.cols] += tile.weight
        if total is not None:  # the weights were normalised over all cameras: over those present instead
            norm = np.where(total > 0, total, 1.0)
            out /= norm if channels else norm[..., 0]
        if np.issubdtype(first.dtype, np.integer):
            info = np.iinfo(first.dtype)
            return np.clip(np.rint(out), info.min, info.max).astype(first.dtype)
        return out.astype(first.dtype)
