"""Shared helpers of the Ladybug5 tests: a scaled-down rig and images of a field that depends on direction."""

from __future__ import annotations

import cv2
import numpy as np

from drivers.ladybug5.rig import RigCamera, RigCameras
from drivers.ladybug5.stitch import panorama_rays


def scaled_rig(rig: RigCameras, scale: float) -> RigCameras:
    """The same head with images ``scale`` times the size (K scaled about the pixel-centre convention)."""
    cameras = []
    for c in rig.cameras:
        k = c.K.copy()
        k[:2] *= scale
        k[0, 2] = (c.K[0, 2] + 0.5) * scale - 0.5
        k[1, 2] = (c.K[1, 2] + 0.5) * scale - 0.5
        w, h = round(c.width * scale), round(c.height * scale)
        cameras.append(RigCamera(c.name, w, h, k, c.D, c.R_head_camera, c.t_head_camera_m))
    return RigCameras(rig.model, tuple(cameras))


def pixel_rays_head(camera: RigCamera) -> np.ndarray:
    """Head-frame unit rays (H*W,3) of every pixel, by OpenCV's own (iterative) undistortion."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    uv = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)
    xy = cv2.undistortPoints(uv, camera.K, camera.D, None, None, None, criteria).reshape(-1, 2)
    rays = np.column_stack([xy, np.ones(len(xy))])
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    return rays @ camera.R_head_camera.T


def smooth_field(rays: np.ndarray) -> np.ndarray:
    """A smooth brightness as a function of direction only (so any correct stitch reproduces it)."""
    return 127.0 + 60.0 * np.sin(3.0 * rays[..., 0]) + 50.0 * np.cos(2.0 * rays[..., 1] + rays[..., 2])


# The colour of each of a camera's four channel JPEGs, per stippled format, as public Ladybug code has it (a
# Ladybug5 driver's colour offsets: BGGR blue 0 / red 3, GBRG blue 1 / red 2, GRBG red 1 / blue 2, RGGB red 0 /
# blue 3; Ladybug2 stream readers: channel 0 blue, 3 red). Written out here, not derived from rigd's table.
DOCUMENTED_CHANNELS = {"BGGR": "BGGR", "GBRG": "GBRG", "GRBG": "GRBG", "RGGB": "RGGB"}
BLUE, RED, GREEN_TOP, GREEN_BOTTOM = 200, 40, 110, 130  # the greens of a tile's first and second row differ


def documented_mosaic(pattern: str, rows: int, cols: int) -> np.ndarray:
    """A (rows, cols) uint8 mosaic of ``pattern`` (its top-left 2x2 cells row by row): blue cells BLUE, red cells
    RED, green cells GREEN_TOP in a tile's first row and GREEN_BOTTOM in its second."""
    mosaic = np.empty((rows, cols), np.uint8)
    for r in (0, 1):
        for c in (0, 1):
            colour = pattern[2 * r + c]
            mosaic[r::2, c::2] = {"B": BLUE, "R": RED}.get(colour, GREEN_TOP if r == 0 else GREEN_BOTTOM)
    return mosaic


def documented_channel_jpegs(pattern: str, rows: int, cols: int) -> list[bytes]:
    """The four channel JPEGs of ``documented_mosaic``, built by hand in the documented order: channel k a flat
    (rows/2, cols/2) image of the colour DOCUMENTED_CHANNELS gives it (its first green the top row's)."""
    planes, greens = [], [GREEN_TOP, GREEN_BOTTOM]
    for colour in DOCUMENTED_CHANNELS[pattern]:
        value = {"B": BLUE, "R": RED}.get(colour) or greens.pop(0)
        ok, data = cv2.imencode(".jpg", np.full((rows // 2, cols // 2), value, np.uint8),
                                [cv2.IMWRITE_JPEG_QUALITY, 100])
        assert ok
        planes.append(data.tobytes())
    return planes


def scene(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """A known, asymmetric scene as a function of direction (theta azimuth, phi from up; rad): a wall brightening
    from 0 to 60 deg and ending there, a lamp at (-100 deg, 30 deg from up), a band below the horizon at 120-170 deg."""
    t, p = np.degrees(theta), np.degrees(phi)

    def inside(x: np.ndarray, low: float, high: float) -> np.ndarray:  # 0..1 with 1-degree soft edges: no aliasing
        return 1 / (1 + np.exp(-(x - low))) / (1 + np.exp(x - high))

    wall = 3 * t * inside(t, 0, 60) * inside(p, 50, 999)
    lamp = 220 * np.exp(-((t + 100) ** 2 + (p - 30) ** 2) / 18)
    band = 120 * inside(p, 95, 110) * inside(t, 120, 170)
    return np.clip(30 + wall + lamp + band, 0, 255).astype(np.uint8)


def render_scene(width: int, yaw_deg: float = 0.0, mirrored: bool = False, upside_down: bool = False) -> np.ndarray:
    """The scene as a panorama whose centre column looks at ``yaw_deg`` (rigd's theta), theta running the other way
    when ``mirrored`` and phi when ``upside_down``."""
    rays = panorama_rays(width, width // 2)
    theta, phi = np.arctan2(rays[..., 1], rays[..., 0]), np.arccos(np.clip(rays[..., 2], -1, 1))
    theta = np.angle(np.exp(1j * (np.radians(yaw_deg) + (-theta if mirrored else theta))))  # in (-pi, pi]
    return scene(theta, np.pi - phi if upside_down else phi)
