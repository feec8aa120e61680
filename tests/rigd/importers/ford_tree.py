"""A tiny tree in the Ford Campus sample's layout, written by the tests (the real sample may not be copied)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import yaml

LASER_ELEVATIONS_DEG = (-8.0, 1.5, -7.5, 2.0, -22.0, -21.5)  # an HDL-64E's order: not sorted by elevation
HEAD_YAML = {
    "head_lidar_reference": {
        "pose": [0.25, 0.01, -0.45, 0.004, -0.002, -1.5708],  # made-up values in the sample's form
        "covariance_order": ["x", "y", "z", "roll", "pitch", "heading"],
        "covariance": (np.diag([0.0004, 0.0009, 0.0016, 1.0e-5, 2.0e-5, 3.0e-5])).tolist(),
    },
    "initial_guess_head_lidar": [0.3, 0.0, -0.4, 0.0, 0.0, -90.0],
    "image_size": [48, 20],
    "cameras": {
        "cam0": {"focal_length": 20.0, "cx": 23.5, "cy": 9.5, "scale_x": 1, "scale_y": 0.5,
                 "X_hc": [0.04, 0.0, 0.0, 170.0, 89.5, 170.0]},
        "cam1": {"focal_length": 20.0, "cx": 23.0, "cy": 9.0, "scale_x": 1, "scale_y": 0.5,
                 "X_hc": [0.01, -0.04, 0.0, 30.0, 89.5, -42.0]},
    },
}


def laser_by_laser_cloud(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(N,3) float32 m, laser after laser, each turning clockwise from azimuth ~86 deg once round (its start a
    few degrees off the others'), with near objects and missing returns; and each point's laser (N,)."""
    rng = np.random.default_rng(seed)
    points, lasers = [], []
    for laser, elevation in enumerate(LASER_ELEVATIONS_DEG):
        start = 86.0 + rng.uniform(-6.0, 6.0)
        step = 0.45 if elevation < -20 else 0.18
        azimuth = start - np.arange(0.0, 360.0 + rng.uniform(-2.0, 2.0), step)
        keep = rng.random(len(azimuth)) > 0.1  # dropouts
        azimuth = azimuth[keep]
        rng_m = np.where(np.abs(((azimuth + 180) % 360) - 180 - 30.0) < 5.0, 4.0, 20.0)  # a near pole at 30 deg
        e, a = np.radians(elevation), np.radians(azimuth)
        xyz = np.stack([rng_m * np.cos(e) * np.cos(a), rng_m * np.cos(e) * np.sin(a), rng_m * np.sin(e)], axis=1)
        xyz[:, 2] += 0.1 if elevation > -20 else -0.1  # the laser blocks sit off the origin: near elevations shift
        points.append(xyz)
        lasers.append(np.full(len(xyz), laser))
    return np.concatenate(points).astype(np.float32), np.concatenate(lasers)


def write_pcd(path: Path, points: np.ndarray, intensity: np.ndarray) -> None:
    """Binary PCD with x y z (float32) and intensity (uint8), as the sample's scans."""
    header = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 1\nTYPE F F F U\nCOUNT 1 1 1 1\n"
              f"WIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(points)}\nDATA binary\n")
    rec = np.zeros(len(points), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("i", "u1")])
    rec["x"], rec["y"], rec["z"], rec["i"] = points[:, 0], points[:, 1], points[:, 2], intensity
    path.write_bytes(header.encode("ascii") + rec.tobytes())


def write_ford_tree(root: Path, scans: tuple[int, ...] = (1, 2)) -> Path:
    root.mkdir(parents=True)
    (root / "head.yaml").write_text(yaml.safe_dump(HEAD_YAML))
    (root / "masks").mkdir()
    (root / "scans").mkdir()
    rng = np.random.default_rng(1)
    for name in HEAD_YAML["cameras"]:
        (root / name).mkdir()
        mask = np.full((20, 48, 4), 200, np.uint8)
        mask[:, :6] = 0
        cv2.imwrite(str(root / "masks" / f"{name}.png"), mask)
        for scan in scans:
            cv2.imwrite(str(root / name / f"image{scan:04d}.jpg"), rng.integers(0, 255, (20, 48, 3), dtype=np.uint8))
    for scan in scans:
        points, _ = laser_by_laser_cloud(scan)
        write_pcd(root / "scans" / f"scan{scan:04d}.pcd", points, rng.integers(0, 255, len(points)).astype(np.uint8))
    return root
