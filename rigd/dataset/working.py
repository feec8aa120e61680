"""The working resolution: images wider than ``max_width`` are halved on load, their camera with them.

The paper calibrates on 1024×512 panoramas; a Ladybug5 can stitch 8000×4000. The edges the cost needs are
no finer than the LiDAR's angular spacing (a VLP-16 samples every 0.2° in azimuth, 2° in elevation: 3.5 mrad,
or 1.1 px of a 2048-wide panorama), so pixels beyond that add time (the L0 smoothing and the edge maps grow
with the pixel count) and memory, not accuracy. rigd therefore works at most ``WORKING_WIDTH_PX`` wide.

Halving is ``cv2.pyrDown`` (a 5-tap Gaussian, then every other pixel): working pixel (i, j) is the blurred
source pixel (2i, 2j). With pixel centres at integer coordinates (docs/conventions.md) that is exact for both
camera models: a pinhole's ``K`` halves (``u' = u / 2``), and an equirectangular panorama of even size keeps
``u = w (pi - theta) / (2 pi)``, ``v = h phi / pi`` with w and h halved. Panoramas wrap in u, so their left
and right borders are blurred across the seam.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
from numpy.typing import NDArray

from rigd.dataset.records import CameraConfig, CameraKind, HeadConfig

WORKING_WIDTH_PX = 2048
_PAD = 2  # the 5-tap kernel's reach, in source pixels


def halvings(camera: CameraConfig | HeadConfig, max_width: int | None) -> int:
    """How many times ``camera``'s images are halved to be at most ``max_width`` px wide (None or 0: none; a
    head's widest sensor decides for all). A panorama is halved only while its width and height are even
    (else ``u = w (pi - theta) / (2 pi)`` would not hold at the half size)."""
    n, width, height = 0, camera.width, camera.height
    while max_width and width > max_width:
        if camera.kind is CameraKind.EQUIRECTANGULAR and (width % 2 or height % 2):
            break
        width, height, n = (width + 1) // 2, (height + 1) // 2, n + 1
    return n


def halve_camera(camera: CameraConfig) -> CameraConfig:
    """``camera`` at half resolution: the size of :func:`halve_image`'s output, and a pinhole's ``K`` halved
    (focal lengths, skew and principal point; the distortion acts on normalised coordinates and stays)."""
    width, height = (camera.width + 1) // 2, (camera.height + 1) // 2
    if camera.K is None:
        return dataclasses.replace(camera, width=width, height=height)
    K_half = np.asarray(camera.K, dtype=np.float64).copy()
    K_half[:2, :] /= 2.0
    return dataclasses.replace(camera, K=K_half, width=width, height=height)


def halve_image(image: NDArray[np.uint8], wrap_u: bool) -> NDArray[np.uint8]:
    """``image`` (H,W[,3]) uint8 halved to ((H+1)//2, (W+1)//2): pixel (i, j) is the Gaussian-blurred (2i, 2j).
    ``wrap_u``: the columns are a panorama's azimuths, so the blur reaches across the seam."""
    if not wrap_u:
        return np.asarray(cv2.pyrDown(image), dtype=np.uint8)
    padded = np.concatenate([image[:, -_PAD:], image, image[:, :_PAD]], axis=1)
    # padded column 2j + _PAD is source column 2j: the output's column j + _PAD // 2
    half = cv2.pyrDown(padded)[:, _PAD // 2: _PAD // 2 + (image.shape[1] + 1) // 2]
    return np.ascontiguousarray(half, dtype=np.uint8)


def working_camera(camera: CameraConfig | HeadConfig, n_halvings: int) -> CameraConfig | HeadConfig:
    """``camera`` (every sensor of a head) halved ``n_halvings`` times."""
    if isinstance(camera, HeadConfig):
        return HeadConfig(tuple(dataclasses.replace(s, camera=_halved(s.camera, n_halvings)) for s in camera.sensors))
    return _halved(camera, n_halvings)


def _halved(camera: CameraConfig, n_halvings: int) -> CameraConfig:
    for _ in range(n_halvings):
        camera = halve_camera(camera)
    return camera


def working_image(image: NDArray[np.uint8], camera: CameraConfig | HeadConfig, n_halvings: int) -> NDArray[np.uint8]:
    """``image`` of ``camera`` (its source size; any sensor of a head) halved ``n_halvings`` times."""
    wrap_u = camera.kind is CameraKind.EQUIRECTANGULAR
    for _ in range(n_halvings):
        image = halve_image(image, wrap_u)
    return image


def working_mask(mask: NDArray[np.bool_], n_halvings: int) -> NDArray[np.bool_]:
    """A sensor's mask (H,W) bool halved as its images are: a working pixel shows the scene when every source
    pixel its blur reaches does (the halved image is blurred across the mask's border)."""
    for _ in range(n_halvings):
        blurred = cv2.pyrDown(np.where(mask, 255, 0).astype(np.uint8))
        mask = np.asarray(blurred >= 255)
    return mask
