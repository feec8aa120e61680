"""``rigd export VERSION_OR_FILE --format F``: extrinsics as a ROS 2 launch file, a URDF joint, a static transform,
Kalibr or OpenCV YAML (rigd.exports, the formats the service's ``/extrinsics?format=`` gives).

The frames default to the ones the bag's headers named when the dataset was imported (``DATASET/bag.yaml``,
rigd import bag): the dataset is ``--dataset``, else the one extrinsics.yaml says it calibrated, else the
extrinsics' own folder (``rigd calibrate BAG`` copies bag.yaml there), else the folder above a
``DATASET/calibration/extrinsics.yaml``; without one, ``camera`` and ``velodyne`` as the service's.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from rigd.errors import RigdError

FORMATS = ("ros2-launch", "urdf", "ros-tf", "kalibr", "opencv")
DEFAULT_FRAMES = ("camera", "velodyne")  # the service's defaults (rigd/api/routes/extrinsics.py)
BAG_FILE = "bag.yaml"  # written by rigd import bag (rigd.importers.bag.importer.BAG_FILE)


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "export", help="extrinsics as a ROS 2 launch file, URDF joint, static transform, Kalibr or OpenCV file",
        description="Write T_camera_lidar (an extrinsics.yaml, a calibration folder, or version N of the service's "
        "store) in another tool's format. The camera frame is the parent, the LiDAR frame the child; their names "
        "come from the bag the dataset was imported from (docs/bags.md) unless given.")
    parser.add_argument("source", metavar="VERSION_OR_FILE",
                        help="an extrinsics.yaml, a folder holding one, or a version number of the store")
    parser.add_argument("--format", required=True, choices=FORMATS)
    parser.add_argument("--parent-frame", default=None, metavar="FRAME", help="the camera's frame id")
    parser.add_argument("--child-frame", default=None, metavar="FRAME", help="the LiDAR's frame id")
    parser.add_argument("--dataset", type=Path, default=None, help="the dataset whose bag.yaml names the frames")
    parser.add_argument("--data-dir", type=Path, default=Path("rigd-data"),
                        help="the service's data directory for a version number (default rigd-data)")
    parser.add_argument("--out", type=Path, default=None, metavar="FILE",
                        help="write here (default: stdout); never over the extrinsics read, nor over an existing "
                        "file without --overwrite")
    parser.add_argument("--overwrite", action="store_true", help="replace --out FILE if it exists")
    parser.set_defaults(func=run)


def _extrinsics_file(source: Path) -> Path:
    if source.is_dir():
        for candidate in (source / "extrinsics.yaml", source / "calibration" / "extrinsics.yaml"):
            if candidate.is_file():
                return candidate
        raise RigdError(f"{source}: no extrinsics.yaml in it (nor in calibration/)")
    if not source.is_file():
        raise RigdError(f"{source}: no such extrinsics file, and not a version number")
    return source


def _frames_of(dataset: Path | None) -> tuple[str, str] | None:
    """(camera, lidar) frame ids from ``dataset``'s bag.yaml, None when it has none."""
    from rigd.dataset.store import read_yaml_mapping

    if dataset is None or not (dataset / BAG_FILE).is_file():
        return None
    from rigd.exports import ExportError, check_frames

    frames = read_yaml_mapping(dataset / BAG_FILE).get("frames") or {}
    camera, lidar = frames.get("camera"), frames.get("lidar")
    if not (camera and lidar):
        return None
    try:
        check_frames(camera_frame=str(camera), lidar_frame=str(lidar))
    except ExportError as exc:
        raise ExportError(f"{dataset / BAG_FILE}: {exc}: give --parent-frame and --child-frame") from exc
    return str(camera), str(lidar)


def _datasets(args: argparse.Namespace, file: Path | None) -> list[Path]:
    """Where the frames may be named, in order: --dataset, the calibrated dataset, the calibration folder itself
    (``rigd calibrate BAG`` copies the bag.yaml of its temporary dataset there), the folder above."""
    from rigd.dataset.store import read_yaml_mapping

    found = [args.dataset] if args.dataset is not None else []
    if file is not None:
        recorded = read_yaml_mapping(file).get("dataset")
        if isinstance(recorded, str):
            found.append(Path(recorded))
        found += [file.resolve().parent, file.resolve().parent.parent]
    return found


def run(args: argparse.Namespace) -> int:
    from rigd.calibration.check_job import extrinsics_from_file, extrinsics_from_store
    from rigd.exports import ExportFormat, check_frames, render_transform
    from rigd.outdir import write_output_file

    check_frames(parent_frame=args.parent_frame or "camera", child_frame=args.child_frame or "velodyne")

    if args.source.isascii() and args.source.isdigit():
        file, number = None, int(args.source)
        T, label = extrinsics_from_store(args.data_dir, number), f"extrinsics version {number}"
    else:
        file, number = _extrinsics_file(Path(args.source)), None
        T, label = extrinsics_from_file(file), f"extrinsics from {file}"
    if args.dataset is not None and _frames_of(args.dataset) is None:
        raise RigdError(f"{args.dataset / BAG_FILE}: missing or without frames (was the dataset imported from a bag?)")
    recorded = next((f for d in _datasets(args, file) if (f := _frames_of(d)) is not None), DEFAULT_FRAMES)
    camera = args.parent_frame or recorded[0]
    lidar = args.child_frame or recorded[1]
    body = render_transform(T, ExportFormat(args.format), label=label, camera_frame=camera, lidar_frame=lidar,
                            version=number)
    if args.out is None:
        sys.stdout.write(body)
        return 0
    read = file if file is not None else args.data_dir / "rigd.db"
    write_output_file(args.out, body, inputs=[read], overwrite=args.overwrite)
    print(f"written: {args.out} ({args.format}, {camera} -> {lidar})", file=sys.stderr)
    return 0
