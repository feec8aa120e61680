"""Time and peak memory of ``rigd import bag`` on a 1-minute ROS 2 MCAP (issue 34 target: <= 15 s, <= 500 MB).

The bag: the simulated rig (drivers.sim) driving through an indoor scene, still for ``--still`` s at each place and
driving ``--move`` s between (5 places in a minute by default). Its VLP-16 as velodyne_msgs/VelodyneScan, one
message per turn of the sensor's own data packets (drivers.sim.stream.LidarEmitter.turn_datagrams, 75 packets
each, at 600 rpm); its camera a colour 2048x1024 panorama as sensor_msgs/CompressedImage (JPEG) at 10 Hz (each
place rendered once, a frame at a stop is that render; while driving, the last place's). Writing the bag takes a
minute or two (the renders), in a child process of its own; only the import is timed: ``rigd import bag`` in a
child process, wall time and its peak RSS (wait4 of that child). The bag is written by a child so that this
process stays small: a child forked from a large parent is charged the parent's resident memory as its own peak
(Linux records it at exec), which is what made the first figure 472 MB.

Run: .venv/bin/python benchmarks/bag_import.py [--seconds 60] [--keep DIR] [--bag DIR (an existing bag)]
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

T0_S = 1_700_000_000.0
IMAGE_PERIOD_S = 0.1
WIDTH, HEIGHT = 2048, 1024


def _typestore() -> Any:
    """ROS 2 Humble's message types with velodyne_msgs (imported here: the measuring process stays small)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from rigd.importers.bag.reader import VELODYNE_MSGS

    store = get_typestore(Stores.ROS2_HUMBLE)
    for name, text in VELODYNE_MSGS.items():
        store.register(get_types_from_msg(text, name))
    return store


def write_bag(path: Path, seconds: float, still_s: float, move_s: float) -> dict[str, int]:
    import cv2  # here, not at the top: the measuring process stays small (module doc)
    import numpy as np
    from rosbags.rosbag2 import StoragePlugin, Writer

    from drivers.sim import render_panorama
    from drivers.sim.motion import MotionRigSpec
    from drivers.sim.stream import TURN_S, LidarEmitter

    store = _typestore()
    T = store.types
    stops = int(np.ceil(seconds / (still_s + move_s)))
    spec = MotionRigSpec(scene="indoor", seed=3, stops=stops, still_s=still_s, move_s=move_s).started(T0_S)
    emitter = LidarEmitter(spec, "127.0.0.1", 2368)
    scene, trajectory = emitter.scene, emitter.trajectory

    def stamp(t: float) -> object:
        sec = int(np.floor(t))
        return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9)))

    def header(t: float, frame: str) -> object:
        return T["std_msgs/msg/Header"](stamp=stamp(t), frame_id=frame)

    renders: dict[int, bytes] = {}

    def frame_jpeg(t: float) -> bytes:
        place = trajectory.stop_index(t)
        place = place if place is not None else min(int(t // trajectory.leg_s), len(trajectory.places) - 1)
        if place not in renders:
            rng = np.random.default_rng(place)
            image = render_panorama(scene, trajectory.places[place], WIDTH, HEIGHT, rng, supersample=1, color=True)
            renders[place] = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()
        return renders[place]

    counts = {"sweeps": 0, "packets": 0, "images": 0}
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        scans = writer.add_connection("/velodyne_packets", "velodyne_msgs/msg/VelodyneScan", typestore=store)
        images = writer.add_connection("/ladybug/panorama/compressed", "sensor_msgs/msg/CompressedImage",
                                       typestore=store)
        turns = int(seconds / TURN_S)
        next_image = 0.0
        for turn in range(turns):
            datagrams = emitter.turn_datagrams(turn)
            packets = [T["velodyne_msgs/msg/VelodynePacket"](stamp=stamp(t), data=np.frombuffer(p, np.uint8))
                       for t, _, p in datagrams]
            t_end = T0_S + (turn + 1) * TURN_S
            scan = T["velodyne_msgs/msg/VelodyneScan"](header=header(T0_S + turn * TURN_S, "velodyne"),
                                                       packets=packets)
            writer.write(scans, int(t_end * 1e9), store.serialize_cdr(scan, "velodyne_msgs/msg/VelodyneScan"))
            counts["sweeps"] += 1
            counts["packets"] += len(packets)
            while next_image < (turn + 1) * TURN_S:
                t = T0_S + next_image
                message = T["sensor_msgs/msg/CompressedImage"](header=header(t, "ladybug"), format="jpeg",
                                                               data=np.frombuffer(frame_jpeg(next_image), np.uint8))
                writer.write(images, int((t + 0.02) * 1e9),
                             store.serialize_cdr(message, "sensor_msgs/msg/CompressedImage"))
                counts["images"] += 1
                next_image += IMAGE_PERIOD_S
    return counts


def _write(path: Path, seconds: float, still_s: float, move_s: float) -> None:
    start = time.perf_counter()
    counts = write_bag(path, seconds, still_s, move_s)
    size = sum(p.stat().st_size for p in path.iterdir())
    print(f"bag: {counts['sweeps']} sweeps ({counts['packets']} packets), {counts['images']} images, "
          f"{size / 1e6:.0f} MB, written in {time.perf_counter() - start:.1f} s", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--still", type=float, default=8.0, help="seconds still at each place")
    parser.add_argument("--move", type=float, default=4.0, help="seconds driving between places")
    parser.add_argument("--keep", type=Path, default=None, help="write the bag and dataset here (kept)")
    parser.add_argument("--bag", type=Path, default=None, help="import this bag (one written by --keep) instead")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        bag = args.bag or root / "drive"
        if args.bag is None:
            writer = multiprocessing.get_context("spawn").Process(
                target=_write, args=(bag, args.seconds, args.still, args.move))
            writer.start()
            writer.join()
            if writer.exitcode != 0:
                sys.exit(f"writing the bag failed (exit {writer.exitcode})")
        dataset = root / f"dataset-{time.time_ns()}"
        command = [sys.executable, "-m", "rigd", "import", "bag", str(bag), str(dataset), "--image-topic",
                   "/ladybug/panorama/compressed", "--cloud-topic", "/velodyne_packets"]
        with tempfile.TemporaryFile("w+") as output:
            start = time.perf_counter()
            child = subprocess.Popen(command, stdout=output, stderr=subprocess.STDOUT)
            _, status, usage = os.wait4(child.pid, 0)  # this child's own figures, not the writer's
            wall = time.perf_counter() - start
            output.seek(0)
            print(output.read())
        print(f"import: {wall:.1f} s wall (target <= 15 s), peak RSS {usage.ru_maxrss / 1024:.0f} MB (target <= "
              f"500 MB), exit {os.waitstatus_to_exitcode(status)}")

if __name__ == "__main__":
    main()
