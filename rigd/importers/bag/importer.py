"""``rigd import bag BAG OUT``: two passes over the bag, then the dataset.

1. Every sweep of the cloud topic is decoded and reduced to the gate's direction grid in worker processes
   (:mod:`.sweeps`; its points are not kept: a long drive never sits in memory) and fed to the gate in bag
   order; the image topic's stamps are read (the first image is decoded, so
   a bad encoding fails at once; every image reduced to a small grey one for :mod:`.motion`), the IMU and
   odometry topics' samples taken (:mod:`.motion`) and the camera-info topic's first message kept.
2. :mod:`.stills` picks the pairs; their images and sweeps are read again by their bag time (a VelodyneScan
   pair's cloud fuses the sweeps capture would: :func:`_pair_cloud`) and written with
   rigd.dataset's writers (atomic pairs under the writer lock), with rig.yaml from ``--rig``, else from the
   CameraInfo, else an equirectangular panorama when the image is 2:1.

``OUT/bag.yaml`` records the bag, its topics, the frame ids of the messages' headers (``rigd export`` names the
transform's frames with them) and what became of every stretch of the recording.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rigd.capture.fuse import fuse_sweeps, sweeps_for_frame
from rigd.capture.gate import SweepSample
from rigd.dataset.lasers import VLP16, VerticalOffsets, lacks_vertical_offsets
from rigd.dataset.pcd import Cloud
from rigd.dataset.records import CameraConfig, CameraKind, RigConfig
from rigd.dataset.store import read_yaml, write_pair, write_rig, write_yaml
from rigd.errors import DatasetError
from rigd.exports import frame_problem
from rigd.importers.bag.clouds import velodyne_scan_vlp16
from rigd.importers.bag.errors import BagError
from rigd.importers.bag.images import decode_compressed, decode_image
from rigd.importers.bag.intrinsics import camera_from_info
from rigd.importers.bag.motion import (
    MotionEvidence,
    MotionSamples,
    MotionSource,
    MotionThresholds,
    describe_sources,
    intervals_yaml,
    jpeg_small_grey,
    moving_intervals,
    small_grey,
)
from rigd.importers.bag.reader import (
    CLOUD_KINDS,
    IMAGE_KINDS,
    IMU_KINDS,
    INFO_KINDS,
    ODOMETRY_KINDS,
    Bag,
    Message,
    Topic,
    TopicKind,
)
from rigd.importers.bag.stills import Decision, StillOptions, SweepTime, Verdict, WindowTracker, select_pairs
from rigd.importers.bag.sweeps import ReducedSweep, decode_sweep, reduce_sweep, where

BAG_FILE = "bag.yaml"
MOTION_ROLES = {"imu": (MotionSource.IMU, "--imu-topic"), "odom": (MotionSource.ODOMETRY, "--odom-topic")}
U8 = NDArray[np.uint8]


@dataclass(frozen=True)
class BagImportOptions:
    """The topics to read (``camera_info_topic``, ``imu_topic``, ``odom_topic`` optional), an optional rig file for
    the camera (and initial guess, prior, tolerance), how still moments are chosen, the thresholds of the other
    evidence of motion (:mod:`.motion`)."""

    image_topic: str
    cloud_topic: str
    camera_info_topic: str | None = None
    rig: Path | None = None
    still: StillOptions = field(default_factory=StillOptions)
    imu_topic: str | None = None
    odom_topic: str | None = None
    motion: MotionThresholds = field(default_factory=MotionThresholds)


@dataclass(frozen=True)
class ImportSummary:
    """What an import wrote: ``pairs`` in ``out``, every stretch's :class:`Decision` (times s on the headers'
    clock), the headers' frame ids and the recording's first stamp s (for times relative to it)."""

    out: Path
    pairs: int
    decisions: tuple[Decision, ...]
    camera_frame: str
    lidar_frame: str
    start_s: float


@dataclass
class _Scan:
    """What pass 1 keeps: sweep spans and bag times, image stamps and bag times, the first image and info."""

    sweeps: list[SweepTime] = field(default_factory=list)
    sweep_ns: list[int] = field(default_factory=list)
    image_t_s: list[float] = field(default_factory=list)
    image_ns: list[int] = field(default_factory=list)
    first_image: U8 | None = None
    camera_info: Message | None = None
    motion: MotionSamples = field(default_factory=MotionSamples)
    camera_frame: str = ""
    lidar_frame: str = ""
    empty_sweeps: int = 0


def decode_frame(message: Message, kind: TopicKind) -> U8:
    if kind is TopicKind.COMPRESSED_IMAGE:
        return decode_compressed(message.body, where=where(message))
    return decode_image(message.body, where=where(message))


def _take(scan: _Scan, tracker: WindowTracker, sweep: ReducedSweep) -> None:
    """A reduced sweep, in bag order, into the gate."""
    if sweep.time is None or sweep.grid is None:
        scan.empty_sweeps += 1
        return
    grid = sweep.grid
    tracker.add(index=len(scan.sweeps), sample=SweepSample(sweep.time.t_start_s, sweep.time.t_end_s, grid.range_m,
                                                           grid))
    scan.sweeps.append(sweep.time)
    scan.sweep_ns.append(sweep.bag_time_ns)
    scan.lidar_frame = scan.lidar_frame or sweep.frame_id


def _small_grey(message: Message, kind: TopicKind, thresholds: MotionThresholds) -> U8:
    """The image reduced for :mod:`.motion` (a compressed one decoded at an eighth of its size when it can be)."""
    if kind is TopicKind.COMPRESSED_IMAGE:
        reduced = jpeg_small_grey(message.body.data, width_px=thresholds.image_width_px)
        if reduced is not None:
            return reduced
    return small_grey(decode_frame(message, kind), width_px=thresholds.image_width_px)


def _take_image(scan: _Scan, message: Message, kind: TopicKind, thresholds: MotionThresholds) -> None:
    if scan.first_image is None:
        scan.first_image = decode_frame(message, kind)
        scan.camera_frame = message.frame_id
    scan.image_t_s.append(message.stamp_s)
    scan.image_ns.append(message.bag_time_ns)
    if thresholds.images:
        scan.motion.add_image(t_s=message.stamp_s, grey=_small_grey(message, kind, thresholds))


def _take_other(scan: _Scan, message: Message, topics: dict[str, Topic]) -> None:
    """A message of the camera-info, IMU or odometry topic."""
    if "imu" in topics and message.topic == topics["imu"].name:
        scan.motion.add_imu(t_s=message.stamp_s, body=message.body, where=where(message))
    elif "odom" in topics and message.topic == topics["odom"].name:
        scan.motion.add_odometry(t_s=message.stamp_s, body=message.body, where=where(message))
    elif scan.camera_info is None:
        scan.camera_info = message


def _scan(bag: Bag, topics: dict[str, Topic], tracker: WindowTracker, options: BagImportOptions) -> _Scan:
    scan = _Scan()
    image, cloud = topics["image"], topics["cloud"]
    for message in bag.messages(topics=list(topics.values())):
        if message.topic == cloud.name:
            _take(scan, tracker, reduce_sweep(message, cloud.kind))
        elif message.topic == image.name:
            _take_image(scan, message, image.kind, options.motion)
        else:
            _take_other(scan, message, topics)
    return scan


def _optional_topics(bag: Bag, options: BagImportOptions) -> dict[str, Topic]:
    """The camera-info, IMU and odometry topics the options name, checked for their types."""
    wanted = (("info", options.camera_info_topic, INFO_KINDS, "--camera-info-topic"),
              ("imu", options.imu_topic, IMU_KINDS, "--imu-topic"),
              ("odom", options.odom_topic, ODOMETRY_KINDS, "--odom-topic"))
    return {role: bag.topic(name=name, kinds=kinds, role=flag) for role, name, kinds, flag in wanted
            if name is not None}


def _check_motion_topics(bag: Bag, topics: dict[str, Topic], scan: _Scan) -> None:
    """An IMU or odometry topic named but without a message is an error (the import would ignore it silently)."""
    for role, (source, flag) in MOTION_ROLES.items():
        if role in topics and source not in scan.motion.sources:
            raise BagError(f"{bag.path}: no message on {topics[role].name} ({flag})")


def _check_overlap(bag: Bag, topics: dict[str, Topic], scan: _Scan) -> None:
    image, cloud = topics["image"], topics["cloud"]
    if not scan.sweeps:
        empty = f" ({scan.empty_sweeps} messages without a valid return)" if scan.empty_sweeps else ""
        raise BagError(f"{bag.path}: no LiDAR sweep on {cloud.name}{empty}")
    if not scan.image_t_s:
        raise BagError(f"{bag.path}: no image on {image.name}")
    lidar = (scan.sweeps[0].t_start_s, max(s.t_end_s for s in scan.sweeps))
    camera = (min(scan.image_t_s), max(scan.image_t_s))
    if camera[1] < lidar[0] or camera[0] > lidar[1]:
        raise BagError(f"{bag.path}: the topics do not overlap in time: {image.name} is stamped {camera[0]:.3f} to "
                       f"{camera[1]:.3f} s, {cloud.name} {lidar[0]:.3f} to {lidar[1]:.3f} s (header stamps; are the "
                       "two sensors on different clocks?)")


def _camera(bag: Bag, options: BagImportOptions, scan: _Scan) -> RigConfig:
    """rig.yaml: the rig file's, else the CameraInfo's camera, else a 2:1 image's panorama; sizes checked."""
    assert scan.first_image is not None
    height, width = scan.first_image.shape[:2]
    if options.rig is not None:
        try:
            rig = RigConfig.from_yaml(read_yaml(options.rig), str(options.rig))
        except DatasetError as exc:
            raise BagError(str(exc)) from exc
        camera = rig.camera
    elif scan.camera_info is not None:
        camera = camera_from_info(scan.camera_info.body, where=where(scan.camera_info))
        rig = RigConfig(camera)
    elif width == 2 * height:
        camera = CameraConfig(CameraKind.EQUIRECTANGULAR, width, height)
        rig = RigConfig(camera)
    else:
        raise BagError(f"{bag.path}: no intrinsics for the {width}x{height} images of {options.image_topic}: give "
                       "--camera-info-topic or --rig (only a 2:1 image is taken for an equirectangular panorama)")
    if camera.kind is CameraKind.HEAD:
        raise BagError(f"{options.rig}: a head rig has several images per pair; a bag import takes one image topic")
    if (camera.width, camera.height) != (width, height):
        source = options.rig if options.rig is not None else options.camera_info_topic
        raise BagError(f"{source}: the camera is {camera.width}x{camera.height}, the images of {options.image_topic} "
                       f"are {width}x{height}")
    return rig


def _fetch(bag: Bag, topic: Topic, bag_time_ns: int, stamp_s: float | None) -> Message:
    """The message of ``topic`` at ``bag_time_ns`` (the one stamped ``stamp_s`` if several share the time)."""
    found = list(bag.messages(topics=[topic], start_ns=bag_time_ns, stop_ns=bag_time_ns + 1))
    match = [m for m in found if stamp_s is None or m.stamp_s == stamp_s]
    if not match:
        raise BagError(f"{bag.path}: the message of {topic.name} at bag time {bag_time_ns} ns is gone on the second "
                       "read (was the bag changed during the import?)")
    return match[0]


@dataclass(frozen=True)
class _PairCloud:
    """A pair's cloud, the header frame id of its sweeps and their spans (first, last return) s, in time order."""

    cloud: Cloud
    frame_id: str
    spans: list[tuple[float, float]]
    window: tuple[float, float]  # the still window (start, end) s when the pair was taken, as capture's


def _pair_cloud(bag: Bag, topic: Topic, scan: _Scan, decision: Decision, frame_t: float,
                options: StillOptions) -> _PairCloud:
    """The cloud of a kept stretch's pair with its image at ``frame_t`` s. VelodyneScan: the sweeps capture would
    fuse (rigd.capture.fuse.sweeps_for_frame: in the window as it stood when the pair was taken, the
    ``options.sweeps`` nearest the image),
    decoded again and fused as capture fuses them; PointCloud2 (no packets to fuse by beam): the one sweep
    nearest the image."""
    window, last = decision.window, decision.last_sweep
    assert window is not None and decision.sweep is not None and last is not None
    spans = [(s.t_start_s, s.t_end_s) for s in scan.sweeps[window.first: last + 1]]
    held = (spans[0][0], spans[-1][1])  # the window when capture would take the pair
    if topic.kind is not TopicKind.VELODYNE_SCAN:
        sweep = decode_sweep(_fetch(bag, topic, scan.sweep_ns[decision.sweep], None), topic.kind)
        assert sweep is not None  # it was decoded in the first pass
        return _PairCloud(Cloud(sweep.points_lidar, sweep.intensity, sweep.ring), sweep.frame_id,
                          [(sweep.t_start_s, sweep.t_end_s)], held)
    chosen = [window.first + i for i in sweeps_for_frame(spans, frame_t, held, options.sweeps)]
    messages = [_fetch(bag, topic, scan.sweep_ns[k], None) for k in chosen]
    sweeps = [velodyne_scan_vlp16(m.body, where=where(m)) for m in messages]
    decoded = [s for s in sweeps if s is not None]
    assert len(decoded) == len(chosen)  # each was decoded in the first pass
    return _PairCloud(fuse_sweeps(decoded), messages[0].frame_id,
                      [(s.start.device, s.end.device) for s in decoded], held)


def _meta(bag: Bag, topics: dict[str, Topic], decision: Decision, image: Message, pair: _PairCloud,
          options: BagImportOptions) -> dict[str, Any]:
    window, still = decision.window, options.still
    assert window is not None
    lidar_mid = 0.5 * (pair.spans[0][0] + pair.spans[-1][1])
    return {
        "source": "rosbag",
        "bag": str(bag.path),
        "camera": {"topic": image.topic, "frame_id": image.frame_id, "stamp_s": image.stamp_s,
                   "bag_time_ns": image.bag_time_ns, "type": topics["image"].kind.value},
        "lidar": {"topic": topics["cloud"].name, "frame_id": pair.frame_id,
                  "stamp_s": [pair.spans[0][0], pair.spans[-1][1]], "points": len(pair.cloud),
                  "type": topics["cloud"].kind.value, "sweeps": len(pair.spans),
                  "sweep_stamps_s": [list(span) for span in pair.spans]},
        "camera_minus_lidar_s": image.stamp_s - lidar_mid,
        "still_window_s": list(pair.window),
        "motion": {"still_seconds": still.still_seconds, "sweeps_in_window": window.sweeps,
                   "lidar_rotation_deg": window.rotation_deg, "lidar_translation_m": window.translation_m,
                   "tolerance_deg": still.tolerance_deg, "min_move_m": still.min_move_m,
                   "max_offset_s": still.max_offset_s},
    }


def _decisions_yaml(decisions: list[Decision]) -> list[dict[str, Any]]:
    return [{"stamp_s": [d.t_start_s, d.t_end_s], "verdict": d.verdict.value, "reason": d.reason}
            for d in decisions]


def import_bag(bag_path: Path, out: Path, *, options: BagImportOptions,
               report: Callable[[str], None] | None = None) -> ImportSummary:
    """Write the dataset ``out`` from the still moments of ``bag_path`` (module doc); ``report`` gets a line per
    stage. Raises BagError (or DatasetError for ``out``) naming what is wrong; nothing is written then."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise DatasetError(f"{out}: exists and is not empty; give a new folder")
    say = report or (lambda line: None)
    with Bag(Path(bag_path)) as bag:
        topics = {"image": bag.topic(name=options.image_topic, kinds=IMAGE_KINDS, role="--image-topic"),
                  "cloud": bag.topic(name=options.cloud_topic, kinds=CLOUD_KINDS, role="--cloud-topic")}
        topics.update(_optional_topics(bag, options))
        tracker = WindowTracker(options.still)
        scan = _scan(bag, topics, tracker, options)
        _check_overlap(bag, topics, scan)
        say(f"read {len(scan.sweeps)} sweeps of {topics['cloud'].name} and {len(scan.image_t_s)} images of "
            f"{topics['image'].name}" + "".join(f", {s}" for s in describe_sources(scan.motion)))
        _check_motion_topics(bag, topics, scan)
        if options.camera_info_topic is not None and scan.camera_info is None:
            raise BagError(f"{bag.path}: no message on {options.camera_info_topic} (--camera-info-topic)")
        rig = _camera(bag, options, scan)
        order = np.argsort(scan.image_t_s, kind="stable")
        image_t_s = [scan.image_t_s[i] for i in order]
        start_s = min(scan.sweeps[0].t_start_s, image_t_s[0])
        decisions = select_pairs(windows=tracker.finish(), image_t_s=image_t_s, sweeps=scan.sweeps,
                                 options=options.still, motion=MotionEvidence(scan.motion, options.motion, start_s))
        kept = [d for d in decisions if d.verdict is Verdict.KEPT]
        if not kept:
            raise BagError(no_still_moment(bag.path, decisions, options.still))
        write_rig(out, rig)
        lacking = []
        for index, decision in enumerate(kept):
            assert decision.image is not None and decision.sweep is not None
            image_index = int(order[decision.image])
            image = _fetch(bag, topics["image"], scan.image_ns[image_index], scan.image_t_s[image_index])
            pair = _pair_cloud(bag, topics["cloud"], scan, decision, image.stamp_s, options.still)
            write_pair(out, index, decode_frame(image, topics["image"].kind), pair.cloud,
                       _meta(bag, topics, decision, image, pair, options))
            lacking.append(rig.lidar_model == VLP16 and lacks_vertical_offsets(pair.cloud))
        if all(lacking):  # a VLP-16's PointCloud2 from a ROS driver without its lasers' offsets (rigd.dataset.lasers)
            write_rig(out, dataclasses.replace(rig, lidar_vertical_offsets=VerticalOffsets.MANUAL))
            say("the VLP-16's clouds lack its lasers' vertical offsets (every ring on its nominal cone): rig.yaml "
                "adds them as each cloud is loaded (lidar.vertical_offsets: manual)")
        summary = ImportSummary(out, len(kept), tuple(decisions), scan.camera_frame, scan.lidar_frame, start_s)
        write_yaml(out / BAG_FILE, {
            "bag": str(bag.path),
            "topics": {role: {"name": t.name, "type": t.kind.value} for role, t in topics.items()},
            "frames": {"camera": ros_frame(scan.camera_frame), "lidar": ros_frame(scan.lidar_frame)},
            "options": dataclasses.asdict(options.still),
            "motion_thresholds": dataclasses.asdict(options.motion),
            "moving": intervals_yaml(moving_intervals(samples=scan.motion, thresholds=options.motion)),
            "stretches": _decisions_yaml(decisions),
        })
    return summary


def ros_frame(frame_id: str) -> str | None:
    """A header's frame id as the exports may write it (a ROS 1 leading '/' dropped), None when it is no ROS name:
    it reaches generated code and XML (rigd.exports), and a recording's headers are anyone's text."""
    name = frame_id[1:] if frame_id.startswith("/") else frame_id
    return name if frame_problem(name) is None else None


def no_still_moment(path: Path, decisions: list[Decision], options: StillOptions) -> str:
    """The error of a recording without a pair: what its stretches were."""
    counts = {v: sum(d.verdict is v for d in decisions) for v in Verdict if v is not Verdict.KEPT}
    seen = ", ".join(f"{n} {v.value}" for v, n in counts.items() if n)
    held = [d for d in decisions if d.window is not None]
    hint = (f"the rig never stood still for {options.still_seconds:g} s ({options.sweeps} sweeps) within "
            f"{options.tolerance_deg:g} deg tolerance" if not held else
            "no still stretch had an image near one of its sweeps" if all(d.verdict is Verdict.NO_IMAGE for d in held)
            else "see the stretches above")
    return f"{path}: no still moment to take a pair from: {hint} (stretches: {seen or 'none'})"
