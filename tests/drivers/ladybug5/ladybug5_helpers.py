"""Shared helpers of the Ladybug5 tests: a scaled-down rig and images of a field that depends on direction."""

from __future__ import annotations

import cv2
import numpy as np

from drivers.ladybug5.rig import RigCamera, RigCameras


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
