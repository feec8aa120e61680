"""Pictures people look at: LiDAR points over the image coloured by range, and a coloured point cloud."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from calib.camera import CameraModel
from calib.geometry import Transform
from calib.gmm import in_image


def project_visible(camera: CameraModel, T_camera_lidar: Transform, points_lidar: NDArray[np.float64]):
    """(indices of points that land in the image, their uv (K,2) px, camera range (K,) m)."""
    p_cam = T_camera_lidar.apply(points_lidar)
    uv, valid = camera.project(p_cam)
    inside = np.flatnonzero(in_image(camera, uv, valid))
    return inside, uv[inside], np.linalg.norm(p_cam[inside], axis=1)


def overlay(image: NDArray[np.uint8], camera: CameraModel, T_camera_lidar: Transform,
            points_lidar: NDArray[np.float64], max_range_m: float = 30.0) -> NDArray[np.uint8]:
    """The image (BGR) with every visible LiDAR point drawn as a dot coloured by range (turbo colormap)."""
    canvas = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    canvas = (canvas * 0.7).astype(np.uint8)
    _, uv, rng = project_visible(camera, T_camera_lidar, points_lidar)
    levels = np.clip(rng / max_range_m * 255.0, 0, 255).astype(np.uint8)
    colours = cv2.applyColorMap(levels.reshape(-1, 1), cv2.COLORMAP_TURBO).reshape(-1, 3)
    px = np.rint(uv).astype(np.int64)
    px[:, 0] = np.clip(px[:, 0], 0, canvas.shape[1] - 1)
    px[:, 1] = np.clip(px[:, 1], 0, canvas.shape[0] - 1)
    canvas[px[:, 1], px[:, 0]] = colours
    return canvas


def write_coloured_ply(path: Path, image: NDArray[np.uint8], camera: CameraModel, T_camera_lidar: Transform,
                       points_lidar: NDArray[np.float64]) -> int:
    """Binary little-endian PLY of the points that see the image, coloured from it (paper Fig. 15)."""
    idx, uv, _ = project_visible(camera, T_camera_lidar, points_lidar)
    colour_img = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    px = np.clip(np.rint(uv).astype(np.int64), 0, [colour_img.shape[1] - 1, colour_img.shape[0] - 1])
    bgr = colour_img[px[:, 1], px[:, 0]]
    rec = np.zeros(len(idx), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                                    ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    pts = points_lidar[idx]
    rec["x"], rec["y"], rec["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    rec["red"], rec["green"], rec["blue"] = bgr[:, 2], bgr[:, 1], bgr[:, 0]
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(rec)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    )
    with Path(path).open("wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(rec.tobytes())
    return len(rec)
