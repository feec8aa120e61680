"""``rigd import FORMAT SRC OUT``: recordings of other rigs as rigd datasets (docs/dataset.md, "Importing")."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from rigd.cli.args import non_negative_float, parse_init, positive_int, progress_bar
from rigd.cli.bag_input import add_topic_options
from rigd.errors import RigdError


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
    _register_bag(formats)
    _register_pairs(formats)


def _register_bag(formats: Any) -> None:
    bag = formats.add_parser(
        "bag", help="a ROS 1 / ROS 2 bag or MCAP: its still moments as pairs",
        description="Read a ROS 1 .bag, a ROS 2 bag (folder, .db3 or .mcap) without ROS installed; find the moments "
        "the rig stood still with rigd capture's stillness gate and keep up to --n of them at distinct places, each "
        "image with the sweep nearest it (docs/bags.md). Images: sensor_msgs/Image or CompressedImage; clouds: "
        "sensor_msgs/PointCloud2 or velodyne_msgs/VelodyneScan (decoded by rigd's VLP-16 decoder).")
    bag.add_argument("src", type=Path, metavar="BAG", help="the .bag file, ROS 2 bag folder, .db3 or .mcap file")
    bag.add_argument("out", type=Path, metavar="OUT", help="new (or empty) dataset folder")
    add_topic_options(bag, required=True)
    bag.add_argument("--n", type=positive_int, default=12, help="pairs to keep at most (default 12)")
    bag.add_argument("--still-seconds", type=non_negative_float, default=2.0,
                     help="a still stretch lasts this long (default 2)")
    bag.add_argument("--sweeps", type=positive_int, default=5, help="and holds this many sweeps (default 5)")
    bag.add_argument("--min-move", type=non_negative_float, default=0.5, metavar="M",
                     help="places at least this far apart, m of range change (default 0.5, as rigd capture)")
    bag.add_argument("--max-offset", type=non_negative_float, default=0.05, metavar="S",
                     help="an image within this many seconds of its sweep (default 0.05)")
    bag.add_argument("--image-motion", type=non_negative_float, default=0.0, metavar="GREY",
                     help="a still stretch where two consecutive images (grey, 64 px wide) differ by more than this "
                     "mean grey level is not kept, e.g. 4 (default 0: the images are not consulted, as traffic "
                     "in view changes a still rig's images too)")
    bag.set_defaults(func=_bag)


def _register_pairs(formats: Any) -> None:
    pairs = formats.add_parser(
        "pairs", help="a folder of images and one of PCD clouds, with a ROS camera_info YAML",
        description="Pair the images of IMAGES with the PCD clouds of CLOUDS by the number in their names (the last "
        "run of digits: pose1.png with pose1_full.pcd) or by sorted order, and write them as a dataset with the "
        "camera of a ROS camera_info YAML (plumb_bob: pinhole; equidistant / fisheye: OpenCV's fisheye). A published "
        "calibration given with --reference, in the convention --reference-convention names, becomes "
        "OUT/reference.yaml (docs/dataset.md, 'Importing').")
    pairs.add_argument("images", type=Path, metavar="IMAGES", help="folder of the images (.png, .jpg)")
    pairs.add_argument("clouds", type=Path, metavar="CLOUDS", help="folder of the PCD clouds (may be IMAGES)")
    pairs.add_argument("out", type=Path, metavar="OUT", help="new (or empty) dataset folder")
    pairs.add_argument("--camera-info", type=Path, required=True, metavar="YAML",
                       help="the camera's ROS camera_info YAML (message fields K, D, or camera_calibration's file)")
    pairs.add_argument("--image-glob", default=None, metavar="PATTERN",
                       help="the images taken from IMAGES (default *.png, *.jpg, *.jpeg)")
    pairs.add_argument("--cloud-glob", default="*.pcd", metavar="PATTERN",
                       help="the clouds taken from CLOUDS (default *.pcd), e.g. '*_full.pcd'")
    pairs.add_argument("--by-order", action="store_true",
                       help="pair the n-th image with the n-th cloud in sorted name order (numbers compared as "
                       "numbers); --only then counts from 0")
    pairs.add_argument("--only", type=_scan_list, default=None, metavar="LIST",
                       help="the pairs to take by their number, e.g. 1,5,9 or 1-10 (default: every pair)")
    pairs.add_argument("--reference", type=Path, default=None, metavar="FILE",
                       help="a published calibration (text: rows of numbers, or a 4x4); several rows: the mean of "
                       "those within 2 std, their std its sigma")
    pairs.add_argument("--reference-convention", default=None, metavar="FRAME:LAYOUT",
                       help="how --reference is written, never guessed: FRAME camera-in-lidar (p_lidar = R p_camera "
                       "+ t) or lidar-in-camera (p_camera = R p_lidar + t); LAYOUT rpy-rad-xyz, rpy-deg-xyz, "
                       "xyz-rpy-rad, xyz-rpy-deg (R = Rz(yaw) Ry(pitch) Rx(roll), metres), xyz-quat-xyzw or matrix; "
                       "e.g. camera-in-lidar:rpy-rad-xyz")
    pairs.add_argument("--init", default=None, metavar="R,P,Y,X,Y,Z",
                       help="rig.yaml's initial guess of T_camera_lidar, deg and m (default none: rigd calibrate "
                       "searches)")
    pairs.add_argument("--lidar-model", default="VLP-16", metavar="NAME", help="the LiDAR's name (default VLP-16)")
    pairs.add_argument("--vertical-offsets", choices=("auto", "manual", "as-recorded"), default="auto",
                       help="a VLP-16's per-laser vertical offsets (up to 11.2 mm, its manual's table): added on load "
                            "(manual), not (as-recorded), or auto (default): added when every cloud lacks them, as "
                            "clouds from the ROS driver before 2023 do (docs/dataset.md)")
    pairs.add_argument("--mask", type=Path, default=None, metavar="PNG",
                       help="an image of the camera's size, non-zero where it shows the scene (the rig's own body "
                       "zero), copied to OUT/masks/camera.png")
    pairs.set_defaults(func=_pairs)


def _pairs(args: argparse.Namespace) -> int:
    from rigd.dataset import open_dataset
    from rigd.dataset.lasers import VerticalOffsets
    from rigd.importers.pairs import IMAGE_GLOBS, PairsOptions, PairsSource, import_pairs
    from rigd.importers.reference_file import parse_convention, read_reference

    if (args.reference is None) != (args.reference_convention is None):
        raise RigdError("--reference and --reference-convention go together: the convention is never guessed")
    reference = None if args.reference is None else \
        read_reference(args.reference, parse_convention(args.reference_convention))
    source = PairsSource(args.images, args.clouds, (args.image_glob,) if args.image_glob else IMAGE_GLOBS,
                         args.cloud_glob, args.by_order)
    offsets = None if args.vertical_offsets == "auto" else VerticalOffsets(args.vertical_offsets)
    options = PairsOptions(args.camera_info, args.lidar_model, parse_init(args.init).transform if args.init else None,
                           reference, args.mask, offsets)
    bar, progress = progress_bar("import pairs", "pair")
    with bar:
        n = import_pairs(source, args.out, options, args.only, progress)
    print(f"written: {args.out} ({n} pairs" + (f"; reference pose in {args.out / 'reference.yaml'})"
                                               if reference is not None else ")"))
    if open_dataset(args.out).rig.lidar_vertical_offsets is VerticalOffsets.MANUAL:
        print("the clouds are given the VLP-16 manual's per-laser vertical offsets as they are loaded "
              "(rig.yaml lidar.vertical_offsets: manual" + (")" if offsets else "; they were decoded without them)"))
    return 0


def _ford(args: argparse.Namespace) -> int:
    from rigd.importers.ford import import_ford  # scipy/cv2 only when importing

    bar, progress = progress_bar("import ford", "scan")
    with bar:
        n = import_ford(args.src, args.out, args.camera, args.scans, progress, args.panorama)
    what = f"camera {args.camera}" if args.camera else f"panorama {args.panorama} px" if args.panorama else "head"
    print(f"written: {args.out} ({n} pairs, {what}; reference pose in {args.out / 'reference.yaml'})")
    return 0


def _kitti(args: argparse.Namespace) -> int:
    from rigd.importers.kitti import import_kitti

    bar, progress = progress_bar("import kitti", "frame")
    with bar:
        n = import_kitti(args.src, args.out, args.camera, args.frames, progress)
    print(f"written: {args.out} ({n} pairs, camera {args.camera}; KITTI's calibration in "
          f"{args.out / 'reference.yaml'})")
    return 0


def _bag(args: argparse.Namespace) -> int:
    from rigd.cli.bag_input import report_import
    from rigd.importers.bag import BagImportOptions, import_bag
    from rigd.importers.bag.motion import MotionThresholds
    from rigd.importers.bag.stills import StillOptions

    still = StillOptions(n=args.n, still_seconds=args.still_seconds, sweeps=args.sweeps, min_move_m=args.min_move,
                         max_offset_s=args.max_offset)
    options = BagImportOptions(args.image_topic, args.cloud_topic, args.camera_info_topic, args.rig, still,
                               imu_topic=args.imu_topic, odom_topic=args.odom_topic,
                               motion=MotionThresholds(image_change_grey=args.image_motion))
    report_import(import_bag(args.src, args.out, options=options, report=print), sys.stdout)
    return 0
