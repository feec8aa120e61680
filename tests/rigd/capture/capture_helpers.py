"""Helpers for the capture tests: a recorded session of the moving simulated rig (a pcap of its VLP-16 and a
replay directory of its camera), made without waiting in real time, and checks against its trajectory."""

from __future__ import annotations

import csv
import socket
from pathlib import Path

import cv2
import numpy as np
import yaml

from drivers.sim import render_panorama
from drivers.sim.motion import MotionRigSpec, Trajectory
from drivers.sim.stream import TURN_S, LidarEmitter
from drivers.vlp16 import write_pcap

REPO = Path(__file__).resolve().parents[3]
START_S = 1_700_000_000.0  # the recorded rig's time 0 on the host clock


def record_session(folder: Path, spec: MotionRigSpec, duration_s: float) -> tuple[Path, Path, Trajectory]:
    """``folder/lidar.pcap`` and ``folder/camera/`` (timestamps.csv + PNG panoramas every
    ``spec.frame_period_s``) of ``duration_s`` s of the rig's trajectory, and that trajectory."""
    spec = spec.started(START_S)
    emitter = LidarEmitter(spec, "192.168.1.201", 2368, 8308)  # never started: only its turns are used
    turns = int(duration_s / TURN_S)
    pcap = folder / "lidar.pcap"
    write_pcap(pcap, [d for turn in range(turns) for d in emitter.turn_datagrams(turn)])
    camera = folder / "camera"
    camera.mkdir()
    rows = []
    for k in range(int(duration_s / spec.frame_period_s)):
        t = k * spec.frame_period_s
        image = render_panorama(emitter.scene, emitter.trajectory.pose_at(t), spec.width, spec.height,
                                np.random.default_rng([spec.seed, k]), spec.image_noise_grey)
        cv2.imwrite(str(camera / f"{k:04d}.png"), image)
        rows.append({"image": f"{k:04d}.png", "device_time_s": t, "host_time_s": START_S + t, "sequence_id": k})
    with (camera / "timestamps.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return pcap, camera, emitter.trajectory


def read_meta(pair: Path) -> dict:
    return yaml.safe_load((pair / "meta.yaml").read_text())


def stop_of_pair(meta: dict, trajectory: Trajectory, start_s: float, still_tolerance_m: float = 0.01) -> int:
    """The stop a pair was taken at. Fails unless the rig stood within ``still_tolerance_m`` (and 0.1 deg)
    of that stop's place at the camera frame's instant and over the whole span of the fused sweeps."""
    times = [meta["camera"]["host_time_s"], *meta["lidar"]["device_time_s"]]
    times += list(np.linspace(*meta["lidar"]["device_time_s"], 20))
    stops = set()
    for t in times:
        rel = t - start_s
        pose = trajectory.pose_at(rel)
        nearest = min(range(len(trajectory.places)),
                      key=lambda i: np.linalg.norm(trajectory.places[i].translation_m - pose.translation_m))
        place = trajectory.places[nearest]
        assert np.linalg.norm(place.translation_m - pose.translation_m) < still_tolerance_m, f"moving at t={rel:.2f}"
        rotation_deg = np.degrees(np.arccos(np.clip((np.trace(place.rotation.T @ pose.rotation) - 1) / 2, -1, 1)))
        assert rotation_deg < 0.1, f"turning at t={rel:.2f}"
        stops.add(nearest)
    assert len(stops) == 1, f"pair spans several places: {stops}"
    return stops.pop()


def free_udp_ports(count: int) -> list[int]:
    """``count`` UDP ports free on 127.0.0.1 right now (bound to port 0 together, then released)."""
    sockets = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(count)]
    try:
        for sock in sockets:
            sock.bind(("127.0.0.1", 0))
        return [sock.getsockname()[1] for sock in sockets]
    finally:
        for sock in sockets:
            sock.close()
