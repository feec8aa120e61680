"""Checks of the ACFR VLP-16's own geometry and an independent tilt reference: a benchmark that prints numbers.

Run: .venv/bin/python benchmarks/acfr_lidar_checks.py ../shared/data/acfr_vlp16 [--extrinsics A.yaml B.yaml ...]

1. Vertical offsets: whether each cloud was decoded without the VLP-16's per-laser vertical offsets (every ring on
   its nominal cone through the origin, rigd.dataset.lasers).
2. The floor: a plane fitted (RANSAC, then robust least squares) to the floor points of the low rings of every
   cloud, with every beam raised by a common elevation offset (0 .. 0.75 deg), with and without the manual's vertical
   offsets: the rms distance from the plane for each. A common elevation error of the beams turns the flat floor into
   a cone around the sensor.
3. The lasers' range offsets: the board points' signed distance along their rays from the board plane that solvePnP
   gives (benchmarks/acfr_target.py), at the target-based estimate, mean per ring, for the even and the odd frames
   apart (a laser's own offset repeats in both; the part linear in the ring is absorbed by the pose).
4. Gravity: the floor's normal (LiDAR frame) against the vertical vanishing point of the images' upright edges
   (line segments of the undistorted images converging below the image), for the reference, the target-based
   estimate and each ``--extrinsics`` (a rigd extrinsics.yaml): the turn about the LiDAR's x, y, z (deg) that would
   put the floor's normal on the images' vertical. It assumes a level floor and plumb walls and pillars.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
from acfr_target import REFERENCE_CONVENTION, Board, estimate, frames_of, load_boards
from numpy.typing import NDArray
from scipy.optimize import least_squares

from calib.elevation import raise_elevation
from calib.geometry import Transform
from rigd.dataset import Cloud, read_pcd
from rigd.dataset.lasers import lacks_vertical_offsets, with_vertical_offsets
from rigd.dataset.records import transform_from_yaml
from rigd.dataset.store import read_yaml
from rigd.importers.camera_info import read_camera_info
from rigd.importers.reference_file import parse_convention, read_reference

F64 = NDArray[np.float64]
FLOOR_RINGS = 6  # rings 0..6 (-15 .. -3 deg) reach the floor
INLIER_M = 0.04
OFFSETS_DEG = (0.0, 0.1, 0.25, 0.5, 0.75)


def ransac_normal(points: F64, rng: np.random.Generator, tries: int = 300) -> F64:
    """The unit normal (z up) of the plane through most of ``points`` (N,3) within INLIER_M."""
    best, count = np.array([0.0, 0.0, 1.0]), -1
    for _ in range(tries):
        sample = points[rng.choice(len(points), 3, replace=False)]
        normal = np.cross(sample[1] - sample[0], sample[2] - sample[0])
        if np.linalg.norm(normal) < 1e-9:
            continue
        normal /= np.linalg.norm(normal)
        inliers = int(np.count_nonzero(np.abs((points - sample[0]) @ normal) < INLIER_M))
        if inliers > count:
            best, count = normal, inliers
    return best if best[2] > 0 else -best


def floor_points(clouds: list[Cloud]) -> tuple[list[F64], list[NDArray[np.int16]], F64]:
    """Per cloud the floor's points and their rings (within INLIER_M of its RANSAC plane), and the mean normal."""
    rng = np.random.default_rng(0)
    points, rings, normals = [], [], []
    for cloud in clouds:
        assert cloud.ring is not None
        low = (cloud.points_lidar[:, 2] < -0.9) & (cloud.ring <= FLOOR_RINGS)
        normal = ransac_normal(cloud.points_lidar[low], rng)
        height = np.median(cloud.points_lidar[low] @ normal)
        on = low & (np.abs(cloud.points_lidar @ normal - height) < INLIER_M)
        centred = cloud.points_lidar[on] - cloud.points_lidar[on].mean(axis=0)
        normal = np.linalg.svd(centred, full_matrices=False)[2][2]
        normal = normal if normal[2] > 0 else -normal
        points.append(cloud.points_lidar[on])
        rings.append(cloud.ring[on])
        normals.append(normal)
    mean = np.mean(normals, axis=0)
    return points, rings, mean / np.linalg.norm(mean)


def floor_rms_mm(points: F64, normal: F64) -> float:
    """The rms distance (mm) of ``points`` from their robustly fitted plane, started from ``normal``."""
    def residual(x: F64) -> F64:
        n = np.array([x[0], x[1], 1.0]) / np.hypot(1.0, np.hypot(x[0], x[1]))
        return np.asarray(points @ n - x[2], np.float64)
    start = np.array([normal[0] / normal[2], normal[1] / normal[2], float(np.median(points @ normal))])
    fit = least_squares(residual, start, loss="soft_l1", f_scale=0.01)
    return float(np.sqrt(np.mean(residual(fit.x) ** 2)) * 1000.0)


def report_floor(clouds: list[Cloud]) -> F64:
    points, rings, normal = floor_points(clouds)
    print(f"floor: {sum(len(p) for p in points)} points of rings 0..{FLOOR_RINGS}; normal in the LiDAR frame "
          f"{np.round(normal, 5).tolist()}")
    for label, offsets in (("as recorded", False), ("with the manual's vertical offsets", True)):
        row = []
        for offset in OFFSETS_DEG:
            raised = []
            for p, r in zip(points, rings, strict=True):
                cloud = with_vertical_offsets(Cloud(p, None, r), "floor") if offsets else Cloud(p, None, r)
                raised.append(raise_elevation(cloud.points_lidar, offset))
            row.append(f"{offset:+.2f} deg {floor_rms_mm(np.concatenate(raised), normal):.2f} mm")
        print(f"  rms from the plane, every beam raised by: {'; '.join(row)} ({label})")
    return normal


def report_ranges(boards: list[Board], rings: list[NDArray[np.int16]], solution: Transform) -> None:
    def per_ring(chosen: range) -> F64:
        total, count = np.zeros(16), np.zeros(16)
        for i in chosen:
            board = boards[i]
            rays = board.points_lidar / np.linalg.norm(board.points_lidar, axis=1)[:, None]
            along = (solution.apply(board.points_lidar) @ board.normal_cam - board.d_cam) / \
                ((rays @ solution.rotation.T) @ board.normal_cam)
            np.add.at(total, rings[i], along)
            np.add.at(count, rings[i], 1)
        return np.where(count > 20, total / np.maximum(count, 1), np.nan)
    even, odd = per_ring(range(0, len(boards), 2)), per_ring(range(1, len(boards), 2))
    both = np.isfinite(even) & np.isfinite(odd)
    print("board points beyond the camera's board plane along their rays, mean per ring 0..15 (cm):")
    print("  even frames " + " ".join(f"{v * 100:+.1f}" for v in even))
    print("  odd frames  " + " ".join(f"{v * 100:+.1f}" for v in odd))
    print(f"  correlation of the two {np.corrcoef(even[both], odd[both])[0, 1]:.2f}")


def vertical_direction(image: NDArray[np.uint8], K: F64, D: F64) -> F64:
    """The upright direction (camera frame, unit, y up negative) of the image's near-vertical line segments: their
    vanishing point (RANSAC), refitted by least squares on the segments within 1, 0.5 and 0.3 deg of the last one."""
    size = (image.shape[1], image.shape[0])
    map_x, map_y = cv2.fisheye.initUndistortRectifyMap(K, D, np.eye(3), K, size, cv2.CV_32FC1)
    grey = cv2.cvtColor(cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR), cv2.COLOR_BGR2GRAY)
    lines = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD).detect(grey)[0].reshape(-1, 4)
    length = np.hypot(lines[:, 2] - lines[:, 0], lines[:, 3] - lines[:, 1])
    tilt = np.degrees(np.arctan2(lines[:, 2] - lines[:, 0], lines[:, 3] - lines[:, 1]))
    middle = (lines[:, :2] + lines[:, 2:]) / 2
    # long, within 35 deg of the image's vertical, and not the floor's lines running away from the camera
    keep = (length > 60) & (np.abs((tilt + 90) % 180 - 90) < 35) & \
        ~((middle[:, 1] > size[1] * 0.4) & (np.abs(middle[:, 0] - K[0, 2]) < 150))
    ends = np.ones((int(keep.sum()), 3))
    planes = np.cross(np.c_[lines[keep, :2], ends[:, 0]], np.c_[lines[keep, 2:], ends[:, 0]]) @ K
    planes /= np.linalg.norm(planes, axis=1, keepdims=True)
    up = _ransac_vertical(planes, length[keep])
    for within_deg in (1.0, 0.5, 0.3):
        near = np.abs(np.degrees(np.arcsin(np.clip(planes @ up, -1, 1)))) < within_deg
        w = length[keep] * near
        up = np.linalg.eigh((planes * w[:, None]).T @ planes)[1][:, 0]
        up = -up if up[1] > 0 else up
    return np.asarray(up, np.float64)


def _ransac_vertical(planes: F64, length: F64, tries: int = 3000) -> F64:
    """The direction two segments' planes (unit normals through the camera centre) share that the longest total
    length of segments passes within 0.5 deg of."""
    rng = np.random.default_rng(0)
    best, score = np.array([0.0, -1.0, 0.0]), -1.0
    for _ in range(tries):
        i, j = rng.choice(len(planes), 2, replace=False)
        candidate = np.cross(planes[i], planes[j])
        if np.linalg.norm(candidate) < 1e-6:
            continue
        candidate /= np.linalg.norm(candidate)
        total = float(length[np.abs(planes @ candidate) < np.sin(np.radians(0.5))].sum())
        if total > score:
            best, score = (-candidate if candidate[1] > 0 else candidate), total
    return best


def report_gravity(root: Path, frames: list[int], floor_up: F64, transforms: dict[str, Transform]) -> None:
    camera = read_camera_info(root / "cfg" / "camera_info.yaml")
    assert camera.K is not None and camera.D is not None
    ups = [vertical_direction(np.asarray(cv2.imread(str(root / "images" / f"pose{n}.png")), np.uint8), camera.K,
                              camera.D) for n in frames[:4]]
    up = np.mean(ups, axis=0)
    up /= np.linalg.norm(up)
    spread = max(np.degrees(np.arccos(np.clip(u @ up, -1, 1))) for u in ups)
    print(f"images' vertical (camera frame) {np.round(up, 5).tolist()} from frames {frames[:4]} (within "
          f"{spread:.3f} deg of each other); the turn that puts the floor's normal on it, about the LiDAR's x, y, z:")
    for label, transform in transforms.items():
        axis = np.cross(transform.rotation @ floor_up, up)
        turn = np.degrees(transform.rotation.T @ axis)
        print(f"  {label}: {' '.join(f'{v:+.3f}' for v in turn)} deg")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("root", type=Path, help="the ACFR data folder (images/, pcd/, cfg/, the CSV)")
    parser.add_argument("--extrinsics", type=Path, nargs="*", default=[], help="rigd extrinsics.yaml files to check")
    args = parser.parse_args()
    frames = frames_of(args.root, None)
    clouds = [read_pcd(args.root / "pcd" / f"pose{n}_full.pcd") for n in frames]
    print(f"{len(clouds)} clouds; decoded without the VLP-16's vertical offsets: "
          f"{sum(lacks_vertical_offsets(c) for c in clouds)}")
    floor_up = report_floor(clouds)
    camera = read_camera_info(args.root / "cfg" / "camera_info.yaml")
    assert camera.K is not None and camera.D is not None
    options = argparse.Namespace(range_bias_m=0.0, ring_elevation_offsets=None, range_trend_m=0.0,
                                 vertical_offsets=False)
    boards = load_boards(args.root, frames, camera.K, camera.D, options)
    target = estimate(boards, False)
    rings = [np.asarray(read_pcd(args.root / "pcd" / f"pose{b.frame}_target.pcd").ring) for b in boards]
    report_ranges(boards, rings, target)
    reference = read_reference(args.root / "calibration_quickstart.csv", parse_convention(REFERENCE_CONVENTION))
    transforms = {"reference": reference.T_camera_lidar, "target-based estimate": target}
    for path in args.extrinsics:
        transforms[str(path)] = transform_from_yaml(read_yaml(path)["T_camera_lidar"], str(path))
    report_gravity(args.root, frames, floor_up, transforms)


if __name__ == "__main__":
    main()
