"""Helpers for the capture tests: a recorded session of the moving simulated rig (a pcap of its VLP-16 and a
replay directory of its camera), made without waiting in real time, checks against its trajectory, and a fault
relay: the simulated VLP-16 with a fault applied to every datagram on its way out (real UDP on loopback), its
turns scanned as it streams or before it starts."""

from __future__ import annotations

import csv
import importlib
import socket
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import yaml

from drivers.sim import render_panorama
from drivers.sim.motion import MotionRigSpec, Trajectory, save_spec
from drivers.sim.stream import TURN_S, LidarEmitter
from drivers.vlp16 import PpsStatus, encode_position_packet, gprmc_sentence, write_pcap
from drivers.vlp16.layout import BLOCKS_PER_PACKET, HOUR_US, POSITION_TIMESTAMP_OFFSET
from rigd.dataset import open_dataset

REPO = Path(__file__).resolve().parents[3]
START_S = 1_700_000_000.0  # the recorded rig's time 0 on the host clock
Datagram = tuple[float, int, bytes]  # (host send time s, port, payload)
FOLLOW_LEAD_S = 0.6  # a capture's camera process takes 0.3-0.9 s to its first frame
# A simulated VLP-16 scanning as it streams drops the turns it cannot send on time: on a machine far busier than
# two spare jobs its stream can be broken turns for seconds. Tests not about silence allow this much of it.
SILENCE_ALLOWED_S = 20.0


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


def stop_of_pair(meta: dict, trajectory: Trajectory, start_s: float, still_tolerance_m: float = 0.01,
                 lidar_times: str = "device_time_s") -> int:
    """The stop a pair was taken at. Fails unless the rig stood within ``still_tolerance_m`` (and 0.1 deg)
    of that stop's place at the camera frame's instant and at every instant a fused sweep was scanned: the
    simulated VLP-16 scans each turn at the pose of its middle, so from half a turn after the first sweep's
    start to half a turn before the last one's end (``lidar_times``: device times, which are the host clock
    for the simulated rig, or ``host_time_s``, when the packets were received, whatever the sensor's clock
    said)."""
    first, last = meta["lidar"][lidar_times]
    times = [meta["camera"]["host_time_s"], *np.linspace(first + TURN_S / 2, last - TURN_S / 2, 20)]
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


def complete_pairs(out: Path) -> list[str]:
    """Names of the pair folders, each checked to load completely (image, cloud, meta); none before rig.yaml."""
    if not (out / "rig.yaml").is_file():
        return []
    dataset = open_dataset(out)
    for i in range(len(dataset)):
        pair = dataset.load_pair(i)
        assert len(pair.cloud) > 1000 and pair.meta["source"] == "captured"
    return [p.name for p in dataset.pair_dirs]


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


def capture_following(folder: Path, spec: MotionRigSpec, n: int, config: Path) -> tuple[int, LidarEmitter]:
    """``rigd capture`` of ``n`` pairs into ``folder/dataset`` from the simulated rig ``spec``: its VLP-16 over UDP
    on loopback (a thread here), its camera followed through its rig file (a child process); the
    exit code and the emitter (its started spec, scene and trajectory). The rig starts FOLLOW_LEAD_S after the
    capture, its modules imported before: the capture listens, and its camera is up, early in the first stop."""
    from rigd.cli import main

    importlib.import_module("rigd.cli.capture")  # what `rigd capture` imports: 1-2 s on a busy machine
    data_port, position_port = free_udp_ports(2)
    started = spec.started(time.time() + FOLLOW_LEAD_S)
    with LidarEmitter(started, "127.0.0.1", data_port, position_port) as emitter:
        save_spec(folder / "sim-rig.yaml", emitter.spec)
        code = main(["capture", "--n", str(n), "--out", str(folder / "dataset"),
                     "--lidar", f"udp:127.0.0.1:{data_port}:{position_port}",
                     "--camera", f"sim:{folder / 'sim-rig.yaml'}", "--still-seconds", "0.5", "--config", str(config),
                     "--silence-timeout", str(SILENCE_ALLOWED_S)])
    return code, emitter


# -- the fault relay ---------------------------------------------------------------------------------------

Fault = Callable[[float, int, bytes], "bytes | None"]  # (s since the rig started, port, payload) -> sent or None


def scanned_turns(spec: MotionRigSpec, data_port: int, position_port: int, turns: int) -> list[list[Datagram]]:
    """The first ``turns`` turns of the rig's VLP-16 stream, scanned now for the rig started at time 0 (send
    times s since its start, device stamps from 0): :class:`RelayedEmitter` moves them onto its start."""
    emitter = LidarEmitter(spec.started(0.0), "127.0.0.1", data_port, position_port)  # never started
    return [emitter.turn_datagrams(turn) for turn in range(turns)]


class RelayedEmitter(LidarEmitter):
    """The simulated rig's VLP-16 with ``fault`` between it and the network: each datagram, with its time
    since the rig started (s) and its port, goes out as ``fault`` returns it (None: dropped).

    ``scanned`` (:func:`scanned_turns`): the turns to send, scanned before the rig started; after them the
    sensor falls silent. Scanned as it streams, a turn that would leave more than a turn late is lost whole
    (drivers.sim.stream), which a busy machine makes frequent: a still rig's turn takes 15 ms to scan, one of a
    rig that vibrates or creeps, which needs a ray casting of its own, 35 ms, most of a turn's 99.5 ms loaded.
    """

    def __init__(self, spec: MotionRigSpec, host: str, data_port: int, position_port: int, fault: Fault,
                 scanned: list[list[Datagram]] | None = None) -> None:
        super().__init__(spec, host, data_port, position_port)
        self.fault = fault
        self.scanned = scanned

    def turn_datagrams(self, turn: int) -> list[Datagram]:
        start = self.spec.start_host_s
        assert start is not None
        if self.scanned is None:
            datagrams = super().turn_datagrams(turn)
        elif turn < len(self.scanned):  # scanned for a start at 0: moved onto this rig's start
            datagrams = [(t + start, port, shifted(payload, port, self.data_port, start))
                         for t, port, payload in self.scanned[turn]]
        else:  # silent from here; at the turn's pace, so that the thread scanning ahead does not spin
            time.sleep(max(0.0, start + (turn - 1) * TURN_S - time.time()))
            return []
        out = []
        for t, port, payload in datagrams:
            sent = self.fault(t - start, port, payload)
            if sent is not None:
                out.append((t, port, sent))
        return out


def shifted(payload: bytes, port: int, data_port: int, seconds: float) -> bytes:
    """The datagram with its device timestamp moved by ``seconds`` (modulo the hour, as the sensor counts)."""
    offset = 1200 if port == data_port else POSITION_TIMESTAMP_OFFSET
    packet = bytearray(payload)
    stamp = int.from_bytes(packet[offset : offset + 4], "little")
    packet[offset : offset + 4] = ((stamp + round(seconds * 1e6)) % HOUR_US).to_bytes(4, "little")
    return bytes(packet)


def clock_step(data_port: int, at_s: float, step_s: float) -> Fault:
    """The device clock jumps by ``step_s`` at ``at_s`` (negative: back)."""
    return lambda t, port, payload: shifted(payload, port, data_port, step_s) if t >= at_s else payload


def pps_lock(data_port: int, start_s: float, at_s: float, ahead_s: float) -> Fault:
    """A free-running device clock ``ahead_s`` ahead of UTC (the host clock) until a PPS lock at ``at_s`` sets
    it to UTC, stepping it back: from then on position packets say locked, with the $GPRMC time."""

    def fault(t: float, port: int, payload: bytes) -> bytes:
        if t < at_s:
            return shifted(payload, port, data_port, ahead_s)
        if port == data_port:
            return payload
        utc = start_s + t
        return encode_position_packet(round(utc * 1e6) % HOUR_US, PpsStatus.LOCKED, gprmc_sentence(utc))

    return fault


def dropping(data_port: int, fraction: float, seed: int = 0) -> Fault:
    """Data packets lost at random, ``fraction`` of them."""
    rng = np.random.default_rng(seed)
    return lambda t, port, payload: None if port == data_port and rng.random() < fraction else payload


def zeroed(data_port: int) -> Fault:
    """A blind sensor: every range of every data packet 0 (no return), azimuths and stamps as usual."""
    distance = (np.arange(BLOCKS_PER_PACKET)[:, None] * 100 + 4 + 3 * np.arange(32)[None, :]).ravel()

    def fault(t: float, port: int, payload: bytes) -> bytes:
        if port != data_port:
            return payload
        packet = np.frombuffer(payload, np.uint8).copy()
        packet[distance] = 0
        packet[distance + 1] = 0
        return packet.tobytes()

    return fault

