"""``rigd import ford|kitti SRC OUT``: recordings of other rigs as rigd datasets (docs/dataset.md, "Importing")."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from tqdm import tqdm


def _scan_list(text: str) -> list[int]:
    """'1-10' or '1,3,5' (or both mixed) as a list of scan numbers."""
    out: list[int] = []
    try:
        for part in text.split(","):
            lo, _, hi = part.partition("-")
            out += list(range(int(lo), int(hi or lo) + 1))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"scans are numbers or ranges like 1-10,12, got {text!r}") from exc
    if not out or min(out) < 0:
        raise argparse.ArgumentTypeError(f"scans are numbers or ranges like 1-10,12, got {text!r}")
    return out


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("import", help="a recording of another rig as a rigd dataset",
                                   description="Read a recording made by another rig or tool into a rigd dataset "
                                   "(docs/dataset.md, 'Importing').")
    formats = parser.add_subparsers(dest="format", metavar="FORMAT", required=True)
    ford = formats.add_parser(
        "ford", help="the Ford Campus sample (Ladybug3 head + HDL-64E)",
        description="The Ford Campus sample of Pandey's MI calibration (camN/imageSSSS.jpg, masks/camN.png, "
        "scans/scanSSSS.pcd, head.yaml) as a head dataset, or one camera as a pinhole dataset; the reference pose "
        "is written to OUT/reference.yaml.")
    ford.add_argument("src", type=Path, metavar="SRC", help="the sample's folder (holds head.yaml)")
    ford.add_argument("out", type=Path, metavar="OUT", help="new (or empty) dataset folder")
    ford.add_argument("--camera", default=None, metavar="NAME", help="one camera (cam0..cam4) as a pinhole dataset")
    ford.add_argument("--scans", type=_scan_list, default=None, metavar="LIST",
                      help="scans to take, e.g. 1-10 (default: every scan the folder holds)")
    ford.add_argument("--panorama", type=int, default=None, metavar="WIDTH",
                      help="the five cameras stitched into one equirectangular panorama WIDTH px wide (rigd's own "
                      "stitching from the head calibration) instead of the head")
    ford.set_defaults(func=_ford)
    kitti = formats.add_parser(
        "kitti", help="one camera of a KITTI raw drive (HDL-64E)",
        description="A KITTI raw drive folder (image_0X/data/*.png, velodyne_points/data/*.bin, and "
        "calib_cam_to_cam.txt / calib_velo_to_cam.txt beside it or in the date folder) as a pinhole dataset of "
        "rectified camera X; KITTI's own calibration is written to OUT/reference.yaml.")
    kitti.add_argument("src", type=Path, metavar="DRIVE", help="the drive folder (DATE_drive_NNNN_sync)")
    kitti.add_argument("out", type=Path, metavar="OUT", help="new (or empty) dataset folder")
    kitti.add_argument("--camera", type=int, choices=range(4), default=2, help="rectified camera 0-3 (default 2)")
    kitti.add_argument("--frames", type=_scan_list, default=None, metavar="LIST",
                       help="frames to take, e.g. 0-5 or 0,50,100 (default: every frame)")
    kitti.set_defaults(func=_kitti)


def _bar(desc: str, unit: str) -> tuple[tqdm, Any]:
    bar = tqdm(desc=desc, unit=unit)

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    return bar, progress


def _ford(args: argparse.Namespace) -> int:
    from rigd.importers.ford import import_ford  # scipy/cv2 only when importing

    bar, progress = _bar("import ford", "scan")
    with bar:
        n = import_ford(args.src, args.out, args.camera, args.scans, progress, args.panorama)
    what = f"camera {args.camera}" if args.camera else f"panorama {args.panorama} px" if args.panorama else "head"
    print(f"written: {args.out} ({n} pairs, {what}; reference pose in {args.out / 'reference.yaml'})")
    return 0


def _kitti(args: argparse.Namespace) -> int:
    from rigd.importers.kitti import import_kitti

    bar, progress = _bar("import kitti", "frame")
    with bar:
        n = import_kitti(args.src, args.out, args.camera, args.frames, progress)
    print(f"written: {args.out} ({n} pairs, camera {args.camera}; KITTI's calibration in "
          f"{args.out / 'reference.yaml'})")
    return 0
