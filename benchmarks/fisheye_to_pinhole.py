"""A fisheye dataset's frames undistorted to a pinhole camera of the same K: a benchmark's input, not a product path.

Run: .venv/bin/python benchmarks/fisheye_to_pinhole.py /tmp/acfr12 /tmp/acfr12p

Every image of the fisheye dataset (rig.yaml ``camera.model: fisheye``) is remapped with
``cv2.fisheye.initUndistortRectifyMap`` to a pinhole camera with the fisheye's own K and no distortion, at the same
size (the fisheye's rim beyond the pinhole's field is cut, the pinhole's corners the fisheye does not reach are
black and masked). The clouds, the reference and the initial guess are copied as they are: the camera frame is the
same, so a calibration of the new dataset answers the same T_camera_lidar. It lets the pinhole default
(``nid-assessed``) run on a fisheye recording, and separates what the fisheye model does from what the scene does.
"""

from __future__ import annotations

import argparse
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from rigd.dataset import open_dataset, read_pcd
from rigd.dataset.records import CameraKind
from rigd.dataset.store import write_pair, write_rig

MASK_FILE = "masks/camera.png"


def undistort_maps(K: NDArray[np.float64], D: NDArray[np.float64], size: tuple[int, int]) -> tuple[NDArray[np.float32],
                                                                                                   NDArray[np.float32]]:
    """The remap tables (H,W) float32 px from a pinhole image of ``K`` and ``size`` (w, h) into the fisheye image."""
    map_x, map_y = cv2.fisheye.initUndistortRectifyMap(K, D, np.eye(3), K, size, cv2.CV_32FC1)
    return np.asarray(map_x, np.float32), np.asarray(map_y, np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("source", type=Path, help="a rigd dataset with a fisheye camera")
    parser.add_argument("out", type=Path, help="a new folder")
    args = parser.parse_args()
    source = open_dataset(args.source, None)
    camera = source.rig.camera
    if camera.kind is not CameraKind.FISHEYE or camera.K is None or camera.D is None:
        raise SystemExit(f"{args.source}: rig.yaml's camera is not a fisheye with K and D")
    if args.out.exists() and any(args.out.iterdir()):
        raise SystemExit(f"{args.out}: exists and is not empty")
    size = (camera.width, camera.height)
    map_x, map_y = undistort_maps(camera.K, camera.D, size)
    inside = (map_x >= 0) & (map_x <= size[0] - 1) & (map_y >= 0) & (map_y <= size[1] - 1)
    (args.out / "masks").mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(args.out / MASK_FILE), np.where(inside, 255, 0).astype(np.uint8))
    pinhole = replace(camera, kind=CameraKind.PINHOLE, D=np.zeros(5), mask=MASK_FILE)
    write_rig(args.out, replace(source.rig, camera=pinhole))
    for name in ("reference.yaml", "ground_truth.yaml"):
        if (args.source / name).is_file():
            shutil.copyfile(args.source / name, args.out / name)
    for index in range(len(source)):
        pair = source.load_pair(index)
        image = cv2.remap(pair.image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        cloud = read_pcd(source.pair_dirs[index] / "cloud.pcd")  # as stored: rig.yaml's elevation offset is copied
        write_pair(args.out, index, image, cloud, {"source": "fisheye_to_pinhole", "from": str(args.source),
                                                        "pair": source.pair_dirs[index].name})
    print(f"written: {args.out} ({len(source)} pairs, pinhole K of the fisheye, {int(inside.mean() * 100)} % of the "
          "image inside the fisheye's view)")


if __name__ == "__main__":
    main()
