"""How well a head's factory calibration holds between its cameras, measured on its own frames.

Run: .venv/bin/python benchmarks/head_overlaps.py HEAD_DATASET EXTRINSICS_YAML

SIFT features are matched between every two cameras of a place; each match in camera A is lifted to 3D with the
depth of the LiDAR points around it (the head's solution EXTRINSICS_YAML, `rigd calibrate HEAD_DATASET`'s
extrinsics.yaml) and projected into camera B with the factory poses (rig.yaml's T_head_camera). Per camera pair:
the median residual (px) and the small rotation (deg, in the head frame) that best turns the predicted rays onto
the observed ones: how far B is turned against A. docs/results.md uses it on the Ford head, where one camera
alone calibrates up to 0.5 deg from the head's solution.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from rigd.dataset.store import open_dataset

F64 = NDArray[np.float64]
RATIO = 0.7  # Lowe's ratio test
DEPTH_RADIUS_PX = 2.5  # LiDAR points around a feature that give its depth
MIN_DEPTH_M = 3.0  # nearer features move with the cameras' few cm of baseline


def _features(image: NDArray[np.uint8], mask: NDArray[np.bool_] | None) -> tuple[F64, NDArray[np.float32] | None]:
    """SIFT keypoints (N,2) px and descriptors of ``image`` where ``mask`` shows the scene."""
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    kp, desc = cv2.SIFT_create(4000).detectAndCompute(  # type: ignore[attr-defined]
        grey, None if mask is None else mask.astype(np.uint8))
    return np.array([k.pt for k in kp], dtype=np.float64).reshape(-1, 2), desc


def _depth(tree: cKDTree, depth_m: F64, uv: F64) -> float | None:
    """The median depth (m) of the LiDAR points within DEPTH_RADIUS_PX of ``uv`` (2,), None where they disagree
    by more than 5 % (a depth edge) or lie nearer than MIN_DEPTH_M."""
    near = tree.query_ball_point(uv, DEPTH_RADIUS_PX)
    if len(near) < 2:
        return None
    z = depth_m[near]
    median = float(np.median(z))
    return median if np.ptp(z) <= 0.05 * median and median >= MIN_DEPTH_M else None


def _rotation_fit(observed: F64, predicted: F64) -> F64:
    """The small rotation w (3,) rad with observed ~ predicted + w x predicted (unit rays (N,3)), least squares."""
    a = np.concatenate([np.array([[0.0, p[2], -p[1]], [-p[2], 0.0, p[0]], [p[1], -p[0], 0.0]]) for p in predicted])
    return np.asarray(np.linalg.lstsq(a, (observed - predicted).reshape(-1), rcond=None)[0], dtype=np.float64)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("extrinsics", type=Path)
    args = ap.parse_args(argv)
    ds = open_dataset(args.dataset)
    sensors = getattr(ds.rig.camera, "sensors", None)
    if not sensors:
        print(f"{args.dataset}: not a multi-camera head", file=sys.stderr)
        return 2
    m = np.array(yaml.safe_load(args.extrinsics.read_text())["T_camera_lidar"]["matrix"], dtype=np.float64)
    head_from_cam = [s.T_head_camera.matrix for s in sensors]
    ks = [np.asarray(s.camera.K, dtype=np.float64) for s in sensors]
    found: dict[tuple[int, int], list[F64]] = {}
    for i in range(len(ds)):
        pair = ds.load_pair(i)
        points_head = pair.cloud.points_lidar @ m[:3, :3].T + m[:3, 3]
        views = []
        for c, image in enumerate(pair.images):
            cam_from_head = np.linalg.inv(head_from_cam[c])
            p = points_head @ cam_from_head[:3, :3].T + cam_from_head[:3, 3]
            p = p[p[:, 2] > 1.0]
            uv = p[:, :2] / p[:, 2:] @ ks[c][:2, :2].T + ks[c][:2, 2]
            views.append((*_features(image, ds.masks[c]), cKDTree(uv), p[:, 2]))
        for a, (uv_a, desc_a, tree_a, depth_a) in enumerate(views):
            for b, (uv_b, desc_b, _, _) in enumerate(views):
                if a == b or desc_a is None or desc_b is None or len(desc_a) < 2 or len(desc_b) < 2:
                    continue
                for best, second in cv2.BFMatcher().knnMatch(desc_a, desc_b, k=2):
                    z = _depth(tree_a, depth_a, uv_a[best.queryIdx]) if best.distance < RATIO * second.distance \
                        else None
                    if z is None:
                        continue
                    x_head = head_from_cam[a] @ np.r_[z * np.linalg.solve(ks[a], np.r_[uv_a[best.queryIdx], 1.0]), 1.0]
                    x_b = (np.linalg.inv(head_from_cam[b]) @ x_head)[:3]
                    if x_b[2] <= 1.0:
                        continue
                    predicted = ks[b][:2, :2] @ (x_b[:2] / x_b[2]) + ks[b][:2, 2]
                    ray_obs = head_from_cam[b][:3, :3] @ np.linalg.solve(ks[b], np.r_[uv_b[best.trainIdx], 1.0])
                    ray_pred = head_from_cam[b][:3, :3] @ x_b
                    found.setdefault((a, b), []).append(np.r_[uv_b[best.trainIdx] - predicted, z,
                                                              ray_obs / np.linalg.norm(ray_obs),
                                                              ray_pred / np.linalg.norm(ray_pred)])
    print("cameras | matches kept | median residual du, dv (px) | turn of B against A (deg) | median depth (m)")
    for (a, b), rows in sorted(found.items()):
        r = np.array(rows)
        keep = np.all(np.abs(r[:, :2] - np.median(r[:, :2], axis=0)) < 4.0, axis=1)  # mismatches out
        if keep.sum() < 15:
            continue
        du, dv = np.median(r[keep, :2], axis=0)
        turn = np.degrees(np.linalg.norm(_rotation_fit(r[keep, 3:6], r[keep, 6:9])))
        print(f"{sensors[a].name}->{sensors[b].name} | {int(keep.sum())} of {len(r)} | {du:+.2f}, {dv:+.2f} | "
              f"{turn:.3f} | {np.median(r[keep, 2]):.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
