"""rigd datasets from the real pinhole sample (camera + 64-ring LiDAR frames with a reference calibration).

Run: .venv/bin/python benchmarks/pinhole_sample.py ../shared/data/pinhole_sample OUT [--kitti-cut]

Writes OUT/pin3 (ours_3 alone) and OUT/pin12 (ours_1 + ours_2), each with rig.yaml (the camera's K, D, size)
and ground_truth.yaml (the sample's reference calibration), the frames under pairs/NNNN/. With
``--kitti-cut`` also OUT/pin3k and OUT/pin123k: every frame cut to KITTI's aspect (the 580 rows around the
principal point) and scaled to 1224x370, K adjusted with pixel centres at integer coordinates, a stand-in for
the narrow street frames of issue 10 that this machine does not have. docs/results.md measures them with
``rigd evaluate convergence OUT/pin3 --trials 10 --rot-deg 2 --trans-m 0.05`` (its GMM rows with
``--method rigd --start-axes rpy``).
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import cv2
import numpy as np
import yaml

KITTI_ROWS = 580  # rows kept around the principal point: 1920 x 580 has KITTI's 1224 x 370 aspect
KITTI_SCALE = 1224 / 1920


def _frame(src: Path, name: str) -> tuple[dict, np.ndarray, Path]:
    """The sample's frame ``name``: its calibration.yaml, image (H,W,3) uint8 and the PCD's path."""
    folder = src / name
    for needed in ("calibration.yaml", "image.png", "calib.pcd"):
        if not (folder / needed).is_file():
            raise SystemExit(f"pinhole_sample: {folder / needed} is missing")
    image = cv2.imread(str(folder / "image.png"), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise SystemExit(f"pinhole_sample: {folder / 'image.png'} is not a readable image")
    return yaml.safe_load((folder / "calibration.yaml").read_text()), image, folder / "calib.pcd"


def _kitti_cut(image: np.ndarray, camera: dict) -> tuple[np.ndarray, dict]:
    """``image`` cut to KITTI_ROWS rows around cy and scaled by KITTI_SCALE, with the camera adjusted."""
    k = np.asarray(camera["K"], dtype=np.float64)
    r0 = int(np.clip(round(k[1, 2] - KITTI_ROWS / 2), 0, image.shape[0] - KITTI_ROWS))
    cut = image[r0:r0 + KITTI_ROWS]
    size = (round(cut.shape[1] * KITTI_SCALE), round(KITTI_ROWS * KITTI_SCALE))
    scaled = cv2.resize(cut, size, interpolation=cv2.INTER_AREA)
    s = KITTI_SCALE  # pixel centres at integer coordinates: u' = (u + 0.5) s - 0.5
    k_new = [[float(k[0, 0] * s), 0.0, float((k[0, 2] + 0.5) * s - 0.5)],
             [0.0, float(k[1, 1] * s), float((k[1, 2] - r0 + 0.5) * s - 0.5)], [0.0, 0.0, 1.0]]
    return scaled, dict(camera, K=k_new, width=size[0], height=size[1])


def make(src: Path, root: Path, frames: list[str], kitti: bool) -> None:
    """One dataset at ``root`` from the sample's ``frames`` (they share one camera and reference)."""
    if root.exists():
        shutil.rmtree(root)
    camera: dict = {}
    calibration: dict = {}
    for index, name in enumerate(frames):
        calibration, image, pcd = _frame(src, name)
        camera = calibration["camera"]
        if kitti:
            image, camera = _kitti_cut(image, camera)
        pair = root / "pairs" / f"{index:04d}"
        pair.mkdir(parents=True)
        if kitti:
            cv2.imwrite(str(pair / "image.png"), image)
        else:
            shutil.copy(src / name / "image.png", pair / "image.png")  # the sample's own bytes
        shutil.copy(pcd, pair / "cloud.pcd")
    (root / "rig.yaml").write_text(yaml.safe_dump({"camera": camera, "lidar": {"model": "64-ring"}}))
    (root / "ground_truth.yaml").write_text(yaml.safe_dump({"T_camera_lidar": calibration["T_camera_lidar"]}))
    print(f"written: {root} ({len(frames)} pairs, {camera['width']}x{camera['height']})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sample", type=Path, help="the pinhole_sample directory (ours_1, ours_2, ours_3)")
    parser.add_argument("out", type=Path)
    parser.add_argument("--kitti-cut", action="store_true", help="also the 1224x370 cuts pin3k, pin123k")
    args = parser.parse_args()
    if not args.sample.is_dir():
        sys.exit(f"pinhole_sample: {args.sample} is not a directory")
    make(args.sample, args.out / "pin3", ["ours_3"], kitti=False)
    make(args.sample, args.out / "pin12", ["ours_1", "ours_2"], kitti=False)
    if args.kitti_cut:
        make(args.sample, args.out / "pin3k", ["ours_3"], kitti=True)
        make(args.sample, args.out / "pin123k", ["ours_1", "ours_2", "ours_3"], kitti=True)


if __name__ == "__main__":
    main()
