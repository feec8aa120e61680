"""A bag where ``rigd calibrate`` and ``rigd check`` take a dataset (docs/bags.md, "Calibrating a bag directly").

``rigd calibrate run.mcap --image-topic T --cloud-topic T``: when DATASET is a bag (a ``.bag``, ``.db3`` or
``.mcap`` file, or a ROS 2 bag folder with its ``metadata.yaml``) it is imported first, by
:func:`rigd.importers.bag.import_bag` with its default choice of still moments, into a temporary dataset (or
``--keep-dataset DIR``), and the command runs on that. The bag's options are refused for a dataset folder, and a bag
without its topics is refused with the topics it has. rosbags and the importer are only imported for a bag.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from rigd.errors import RigdError

if TYPE_CHECKING:
    from rigd.importers.bag import ImportSummary

BAG_SUFFIXES = (".bag", ".db3", ".mcap")
ROS2_METADATA = "metadata.yaml"
BAG_FILE = "bag.yaml"  # what the import wrote beside its pairs (rigd.importers.bag.importer.BAG_FILE)
# The options that belong to a bag, by their argparse names and as spelt on the command line.
BAG_OPTIONS = {"image_topic": "--image-topic", "cloud_topic": "--cloud-topic",
               "camera_info_topic": "--camera-info-topic", "rig": "--rig", "imu_topic": "--imu-topic",
               "odom_topic": "--odom-topic", "keep_dataset": "--keep-dataset"}


def is_bag(path: Path) -> bool:
    """Whether ``path`` is a bag rather than a dataset folder."""
    if path.is_dir():
        return (path / ROS2_METADATA).is_file()
    return path.suffix in BAG_SUFFIXES


def add_topic_options(parser: argparse.ArgumentParser | argparse._ArgumentGroup, *, required: bool) -> None:
    """--image-topic, --cloud-topic, --camera-info-topic, --rig, --imu-topic and --odom-topic, as ``rigd import
    bag`` and a bag as DATASET take them (the first two ``required`` or not)."""
    parser.add_argument("--image-topic", required=required, default=None, metavar="TOPIC",
                        help="sensor_msgs/Image or CompressedImage")
    parser.add_argument("--cloud-topic", required=required, default=None, metavar="TOPIC",
                        help="sensor_msgs/PointCloud2 or velodyne_msgs/VelodyneScan")
    parser.add_argument("--camera-info-topic", default=None, metavar="TOPIC",
                        help="sensor_msgs/CameraInfo for the intrinsics (plumb_bob: pinhole, equidistant: fisheye)")
    parser.add_argument("--rig", type=Path, default=None, metavar="RIG.yaml",
                        help="the rig file for the camera (and initial guess, prior, tolerance) instead of CameraInfo")
    parser.add_argument("--imu-topic", default=None, metavar="TOPIC",
                        help="sensor_msgs/Imu: a still stretch it says was turning (above 0.5 deg/s) or accelerating "
                        "(0.5 m/s^2 off gravity) is not kept")
    parser.add_argument("--odom-topic", default=None, metavar="TOPIC",
                        help="nav_msgs/Odometry: a still stretch its twist says was moving (above 1 cm/s or "
                        "0.5 deg/s) is not kept")


def add_bag_options(parser: argparse.ArgumentParser) -> None:
    """The options of a bag given as DATASET (the topics as ``rigd import bag`` takes them)."""
    group = parser.add_argument_group(
        "a bag as DATASET", "DATASET may be a ROS 1 .bag, a ROS 2 bag folder, a .db3 or an .mcap: its still moments "
        "are imported first, as rigd import bag does (docs/bags.md)")
    add_topic_options(group, required=False)
    group.add_argument("--keep-dataset", type=Path, default=None, metavar="DIR",
                       help="import into DIR (new or empty) and keep it (default: a temporary folder, removed after)")


@dataclass(frozen=True)
class DatasetInput:
    """The dataset a command reads: ``path``, the ``bag`` it was imported from (None: a dataset folder) and
    whether ``path`` is a temporary folder, removed when the command is done."""

    path: Path
    bag: Path | None = None
    temporary: bool = False

    def default_out(self, name: str) -> Path:
        """Where a command writes by default: ``DATASET/name``; for a bag imported into a temporary folder,
        ``BAG_name`` beside the bag (``run.mcap`` -> ``run_calibration``)."""
        if self.temporary and self.bag is not None:
            return self.bag.parent / f"{self.bag.stem}_{name}"
        return self.path / name

    def record_bag(self, out: Path) -> None:
        """Copy the import's bag.yaml (the headers' frame ids, every stretch's verdict) into ``out``, so that
        ``rigd export out/extrinsics.yaml`` names the bag's frames after the temporary dataset is gone."""
        if self.bag is not None and (self.path / BAG_FILE).is_file():
            shutil.copyfile(self.path / BAG_FILE, out / BAG_FILE)


def _given(args: argparse.Namespace) -> list[str]:
    return [flag for name, flag in BAG_OPTIONS.items() if getattr(args, name, None) is not None]


def _bag_topics(bag: Path) -> str:
    from rigd.importers.bag.reader import Bag

    with Bag(bag) as opened:
        return opened.describe_topics()


def report_import(summary: ImportSummary, out: TextIO) -> None:
    """Every stretch of the recording with what became of it, then what was written (rigd import bag's lines)."""
    from rigd.importers.bag.stills import Verdict

    pair = 0
    for d in summary.decisions:
        span = f"{d.t_start_s - summary.start_s:8.2f} - {d.t_end_s - summary.start_s:8.2f} s"
        if d.verdict is Verdict.KEPT:
            print(f"{span}  kept as pair {pair:04d}: {d.reason}", file=out)
            pair += 1
        else:
            print(f"{span}  not kept ({d.verdict.value}): {d.reason}", file=out)
    print(f"written: {summary.out} ({summary.pairs} pairs; frames camera {summary.camera_frame!r}, lidar "
          f"{summary.lidar_frame!r} in {summary.out / BAG_FILE})", file=out)
    from rigd.importers.bag.importer import ros_frame

    for role, frame, option in (("camera", summary.camera_frame, "--parent-frame"),
                                ("lidar", summary.lidar_frame, "--child-frame")):
        if frame and ros_frame(frame) is None:
            print(f"  the {role} frame id {frame!r} is not a ROS name: not recorded (rigd export needs {option})",
                  file=out)


def _imported(bag: Path, out: Path, args: argparse.Namespace) -> Path:
    from rigd.importers.bag import BagImportOptions, import_bag

    options = BagImportOptions(args.image_topic, args.cloud_topic, args.camera_info_topic, args.rig,
                               imu_topic=args.imu_topic, odom_topic=args.odom_topic)
    print(f"importing the bag {bag} (docs/bags.md)", file=sys.stderr)
    summary = import_bag(bag, out, options=options, report=lambda line: print(line, file=sys.stderr))
    report_import(summary, sys.stderr)
    return out


@contextmanager
def dataset_input(args: argparse.Namespace) -> Iterator[DatasetInput]:
    """``args.dataset`` as the command's dataset: a dataset folder as it is; a bag imported first into
    ``--keep-dataset`` or a temporary folder, removed when the command is done (module doc)."""
    path: Path = args.dataset
    given = _given(args)
    if not is_bag(path):
        if given:
            raise RigdError(f"{path}: a dataset folder, not a bag ({', '.join(BAG_SUFFIXES)} or a ROS 2 bag folder "
                            f"with {ROS2_METADATA}); {', '.join(given)} are for a bag")
        yield DatasetInput(path)
        return
    if not path.exists():
        raise RigdError(f"{path}: bag does not exist")
    missing = [flag for name, flag in BAG_OPTIONS.items() if name in ("image_topic", "cloud_topic")
               and getattr(args, name, None) is None]
    if missing:
        raise RigdError(f"{path}: a bag; give {' and '.join(missing)} (it has: {_bag_topics(path)})")
    if args.keep_dataset is not None:
        yield DatasetInput(_imported(path, args.keep_dataset, args), path)
        return
    with tempfile.TemporaryDirectory(prefix="rigd-bag-") as tmp:
        yield DatasetInput(_imported(path, Path(tmp), args), path, temporary=True)
