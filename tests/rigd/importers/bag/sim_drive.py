"""The simulated rig's drive (drivers.sim, moving with stops) taken both ways: by the capture engine from its recorded
session (a pcap of its VLP-16 and a replay folder of its camera, as tests/rigd/capture/ record it) and by
``rigd import bag`` from a bag of the same packets and frames; then the two sets of pairs side by side.

Used by tests/rigd/importers/bag/test_sim_drive.py (a short drive) and benchmarks/bag_vs_capture.py (a longer one).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from drivers.sim.motion import MotionRigSpec, Trajectory
from drivers.sim.stream import TURN_S
from drivers.vlp16 import read_batches
from rigd.capture import CaptureRequest, run_capture
from rigd.dataset import open_dataset
from rigd.importers.bag import BagImportOptions, import_bag
from rigd.importers.bag.stills import StillOptions
from tests.rigd.capture.capture_helpers import START_S, read_meta, record_session
from tests.rigd.importers.bag.bags import BagFormat, BagTypes

IMAGE_TOPIC, CLOUD_TOPIC = "/ladybug/panorama", "/velodyne_packets"
ENCODINGS = {1: "mono8", 3: "bgr8"}


def drive_bag(path: Path, pcap: Path, camera: Path, fmt: BagFormat = BagFormat.MCAP) -> Path:
    """The recorded session as a bag: a VelodyneScan per turn of the pcap's data packets from the second turn (each
    at its capture time, the simulated sensor's own clock) and the replay folder's frames as raw
    sensor_msgs/Image stamped with their host times."""
    types = BagTypes.of(fmt)
    batches = [b for b in read_batches(pcap) if len(b.data)]
    packets = np.concatenate([b.data for b in batches])
    times = np.concatenate([b.data_host_s for b in batches])
    turn = np.floor((times - START_S) / TURN_S + 1e-6).astype(np.int64)
    messages: list[tuple[float, str, str, object]] = []
    # From the second turn: the VLP-16 driver calls a stream's first piece partial (it cannot know where the turn
    # began), so the capture never fuses the recording's first turn; the bag holds the turns the capture can use.
    for k in np.unique(turn)[1:]:
        inside = turn == k
        scan = types.velodyne_scan(float(times[inside][0]), "velodyne", packets[inside], times[inside])
        messages.append((float(times[inside][-1]), CLOUD_TOPIC, "velodyne_msgs/msg/VelodyneScan", scan))
    with (camera / "timestamps.csv").open(newline="") as fh:
        for row in csv.DictReader(fh):
            image = cv2.imread(str(camera / row["image"]), cv2.IMREAD_UNCHANGED)
            t = float(row["host_time_s"])
            channels = 1 if image.ndim == 2 else image.shape[2]
            body = types.new("sensor_msgs/msg/Image", header=types.header(t, "ladybug"), height=image.shape[0],
                             width=image.shape[1], encoding=ENCODINGS[channels], is_bigendian=0,
                             step=image.shape[1] * channels, data=np.ascontiguousarray(image).reshape(-1))
            messages.append((t, IMAGE_TOPIC, "sensor_msgs/msg/Image", body))
    return types.write(path, messages)


@dataclass(frozen=True)
class TakenPair:
    """A pair as either path took it: the stop (index into the trajectory's places) its image shows, the image's
    time, its LiDAR sweeps' span and the still window it came from, s since the drive started."""

    stop: int | None
    image_s: float
    lidar_s: tuple[float, float]
    window_s: tuple[float, float]


def _stop_at(trajectory: Trajectory, t: float) -> int | None:
    return trajectory.stop_index(t)


def captured_pairs(out: Path, pcap: Path, camera: Path, trajectory: Trajectory, *, n: int,
                   still: StillOptions) -> list[TakenPair]:
    """The capture engine on the recorded session: ``n`` pairs with ``still``'s hold and place settings."""
    summary = run_capture(CaptureRequest(out=out, n=n, lidar=f"pcap:{pcap}", camera=f"replay:{camera}",
                                         still_seconds=still.still_seconds, sweeps=still.sweeps,
                                         min_move=still.min_move_m))
    pairs = []
    for folder in summary.pairs:
        meta = read_meta(folder)
        image = meta["camera"]["host_time_s"] - START_S
        first, last = (t - START_S for t in meta["lidar"]["device_time_s"])
        window = tuple(t - START_S for t in meta["still_window_host_s"])
        pairs.append(TakenPair(_stop_at(trajectory, image), image, (first, last), (window[0], window[1])))
    return pairs


def imported_pairs(out: Path, bag: Path, trajectory: Trajectory, *, still: StillOptions) -> list[TakenPair]:
    """``rigd import bag`` on the drive's bag with ``still``."""
    import_bag(bag, out, options=BagImportOptions(IMAGE_TOPIC, CLOUD_TOPIC, still=still))
    pairs = []
    for pair in open_dataset(out).pairs():
        image = pair.meta["camera"]["stamp_s"] - START_S
        first, last = (t - START_S for t in pair.meta["lidar"]["stamp_s"])
        window = tuple(t - START_S for t in pair.meta["still_window_s"])
        pairs.append(TakenPair(_stop_at(trajectory, image), image, (first, last), (window[0], window[1])))
    return pairs


@dataclass(frozen=True)
class Drive:
    """A recorded drive: its pcap, camera replay folder, bag and trajectory."""

    pcap: Path
    camera: Path
    bag: Path
    trajectory: Trajectory


def record_drive(folder: Path, spec: MotionRigSpec, duration_s: float) -> Drive:
    """``duration_s`` s of the simulated rig ``spec`` recorded as the capture tests do, and as a bag."""
    pcap, camera, trajectory = record_session(folder, spec, duration_s)
    return Drive(pcap, camera, drive_bag(folder / "drive", pcap, camera), trajectory)


def comparison_lines(captured: list[TakenPair], imported: list[TakenPair]) -> list[str]:
    """The two sets of pairs side by side, in words."""
    lines = [f"pairs: capture {len(captured)}, bag import {len(imported)}"]
    for k in range(max(len(captured), len(imported))):
        row = []
        for name, pairs in (("capture", captured), ("bag", imported)):
            if k < len(pairs):
                p = pairs[k]
                row.append(f"{name}: stop {p.stop} window {p.window_s[0]:6.2f}-{p.window_s[1]:6.2f} s image "
                           f"{p.image_s:6.2f} s lidar {p.lidar_s[0]:6.2f}-{p.lidar_s[1]:6.2f} s")
            else:
                row.append(f"{name}: -")
        lines.append(f"pair {k}: " + " | ".join(row))
    return lines
