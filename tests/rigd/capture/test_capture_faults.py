"""Faults around a capture, for real: two captures on one dataset or one UDP port (real processes), disk
errors before the first pair, a simulated camera process frozen with SIGSTOP, a VLP-16 whose head stopped
turning and one that stopped sending (real UDP on loopback)."""

from __future__ import annotations

import csv
import itertools
import multiprocessing
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from capture_helpers import free_udp_ports, record_session

from drivers.ladybug5 import HeadCalibration
from drivers.sim.motion import MotionRigSpec, Trajectory, save_spec
from drivers.sim.stream import TURN_S, LidarEmitter, SimFrame
from drivers.vlp16 import send_datagrams
from drivers.vlp16.layout import BLOCKS_PER_PACKET
from rigd.capture import CaptureRequest, CaptureStatus, SensorSilenceError, run_capture
from rigd.capture import sources as capture_sources
from rigd.capture import watchdog as capture_watchdog
from rigd.cli import main
from rigd.cli.exit_codes import ERROR, IO_ERROR

REPO = Path(__file__).resolve().parents[3]
Session = tuple[Path, Path, Trajectory]  # a recorded session: pcap, camera replay folder, trajectory
SPEC = MotionRigSpec(scene="indoor", seed=7, stops=2, still_s=6.0, move_s=1.0, width=64, height=32,
                     frame_period_s=1.0)


def future_camera(folder: Path) -> Path:
    """A replay directory whose one frame lies an hour ahead: a camera that never gets in the way."""
    folder.mkdir()
    cv2.imwrite(str(folder / "0000.png"), np.zeros((32, 64, 3), np.uint8))
    with (folder / "timestamps.csv").open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["image", "device_time_s", "host_time_s", "sequence_id"])
        writer.writerow(["0000.png", 0.0, time.time() + 3600.0, 0])
    return folder


def still_rig_datagrams(data_port: int, position_port: int, seconds: float) -> list[tuple[float, int, bytes]]:
    """``seconds`` of the VLP-16 stream of a rig standing still at its first place."""
    emitter = LidarEmitter(SPEC.started(time.time()), "127.0.0.1", data_port, position_port)  # not started
    return [d for turn in range(int(seconds / TURN_S)) for d in emitter.turn_datagrams(turn)]


def wait_for(condition: Callable[[], bool], timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.02)


@pytest.fixture
def no_rig_file(monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    """The environment without a rig file, for this process and for a ``rigd`` run from this tree."""
    monkeypatch.delenv("RIGD_CONFIG", raising=False)
    return {**{k: v for k, v in os.environ.items() if k != "RIGD_CONFIG"}, "PYTHONPATH": str(REPO)}


# -- one capture per dataset and per port ------------------------------------------------------------------

def test_a_second_capture_into_the_dataset_or_on_the_port_is_refused_at_once(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        no_rig_file: dict[str, str]) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(capture_watchdog, "STARTUP_S", 1.0)  # without the fixes, the second waits for data: fail fast
    camera = future_camera(tmp_path / "camera")
    ports = free_udp_ports(4)
    out = tmp_path / "ds"

    def args(dataset: Path, data: int, position: int) -> list[str]:
        return ["capture", "--n", "2", "--out", str(dataset), "--lidar", f"udp:127.0.0.1:{data}:{position}",
                "--camera", f"replay:{camera}", "--silence-timeout", "0.5"]

    log = tmp_path / "first.log"
    first_args = args(out, *ports[:2])
    first_args[-1] = "60"  # waits for its LiDAR, holding the dataset and the ports
    first = subprocess.Popen([sys.executable, "-m", "rigd", *first_args], cwd=tmp_path, env=no_rig_file,
                             stdout=subprocess.DEVNULL, stderr=log.open("w"))
    try:
        wait_for(lambda: "waiting for the LiDAR" in log.read_text(), 60, "the first capture to start")
        started = time.monotonic()
        assert main(args(out, *ports[2:])) == ERROR  # same dataset, other ports
        err = capsys.readouterr().err
        assert f"rigd: error: dataset {out} is being written by another process (pid {first.pid}: " in err
        assert "rigd capture" in err
        assert main(args(tmp_path / "other", *ports[:2])) == ERROR  # other dataset, the first one's data port
        err = capsys.readouterr().err
        assert f"port {ports[0]} is in use by another process (pid {first.pid}: " in err
        assert time.monotonic() - started < 1.0  # refused at once, not after a silence timeout
        assert not (out / "pairs").exists() and not (tmp_path / "other" / "rig.yaml").exists()
        first.send_signal(signal.SIGINT)
        assert first.wait(30) == 130
    finally:
        first.kill()
        first.wait(10)


# -- disk errors before the first pair ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory):  # -> Session
    """A recorded rig that stands still for its first 6 s: one pair's worth."""
    return record_session(tmp_path_factory.mktemp("recorded"), SPEC, 3.0)


def recorded_args(session: Session, out: Path) -> list[str]:
    pcap, camera, _ = session
    return ["capture", "--n", "1", "--out", str(out), "--lidar", f"pcap:{pcap}", "--camera", f"replay:{camera}",
            "--still-seconds", "0.5", "--sweeps", "3"]


def test_a_full_disk_before_the_first_pair_is_a_clear_error(
        tmp_path: Path, session: Session, capsys: pytest.CaptureFixture[str], no_rig_file: dict[str, str]) -> None:
    out = tmp_path / "ds"
    out.mkdir()
    (out / ".rig.yaml.tmp").symlink_to("/dev/full")  # rig.yaml's write fails with ENOSPC, as on a full disk
    assert main(recorded_args(session, out)) == IO_ERROR
    err = capsys.readouterr().err
    assert f"rigd: error: {out / 'rig.yaml'}: cannot write (No space left on device)" in err
    assert "free some space and rerun" in err and "Traceback" not in err
    assert not os.path.lexists(out / ".rig.yaml.tmp")  # nothing half written
    assert not (out / "rig.yaml").exists() and not (out / "pairs").exists()
    assert main(recorded_args(session, out)) == 0  # space freed: the rerun writes the pair under its lock
    assert [p.name for p in (out / "pairs").iterdir()] == ["0000"] and (out / "rig.yaml").is_file()


def test_an_output_that_cannot_be_created_is_a_clear_error(
        tmp_path: Path, session: Session, capsys: pytest.CaptureFixture[str], no_rig_file: dict[str, str]) -> None:
    (tmp_path / "file").write_text("not a folder")
    out = tmp_path / "file" / "ds"
    assert main(recorded_args(session, out)) == ERROR
    err = capsys.readouterr().err
    assert f"rigd: error: {out}: cannot create the dataset folder (Not a directory)" in err


def read_only(folder: Path) -> tuple[list[str], str]:
    """A command prefix under which ``folder`` is read-only, and the error expected: a tmpfs mounted read-only
    on it in a user and mount namespace of the command's own; without namespaces, a folder without write
    permission (which root ignores: then the test is skipped)."""
    mount = 'mount -t tmpfs -o ro,size=64k tmpfs "$1" && shift && exec "$@"'
    prefix = ["unshare", "--user", "--map-root-user", "--mount", "sh", "-c", mount, "sh", str(folder)]
    if shutil.which("unshare") and subprocess.run([*prefix, "true"], capture_output=True).returncode == 0:
        return prefix, "Read-only file system"
    if os.geteuid() == 0:
        pytest.skip("neither a user namespace nor a non-root user to make a folder read-only")
    folder.chmod(0o555)
    return [], "Permission denied"


def test_a_read_only_output_is_a_clear_error(tmp_path: Path, session: Session, no_rig_file: dict[str, str]) -> None:
    out = tmp_path / "ds"
    out.mkdir()
    prefix, reason = read_only(out)
    try:
        result = subprocess.run([*prefix, sys.executable, "-m", "rigd", *recorded_args(session, out)], cwd=tmp_path,
                                env=no_rig_file, capture_output=True, text=True, timeout=120)
    finally:
        out.chmod(0o755)
    assert result.returncode == IO_ERROR, result.stderr
    assert f"rigd: error: {out}: cannot write into the dataset folder ({reason}" in result.stderr
    assert list(out.iterdir()) == []


# -- sensors that stop -------------------------------------------------------------------------------------

def test_a_frozen_simulated_camera_ends_the_capture_with_an_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(capture_sources, "SIM_FRAME_GAP_S", 0.0)  # its 64x32 frames come every 0.25 s
    save_spec(tmp_path / "rig.yaml", replace(SPEC, frame_period_s=0.25))
    framed = threading.Event()  # a frame has reached the capture: its silence allowance is now silence_timeout_s
    convert = capture_sources.sim_frame

    def sim_frame(frame: SimFrame, head: HeadCalibration | None) -> capture_sources.CameraFrame:
        framed.set()
        return convert(frame, head)

    monkeypatch.setattr(capture_sources, "sim_frame", sim_frame)
    statuses: list[CaptureStatus] = []
    outcome: list[BaseException] = []

    def capture() -> None:
        try:
            run_capture(CaptureRequest(tmp_path / "ds", 1, lidar=f"sim:{tmp_path / 'rig.yaml'}", camera="sim",
                                       still_seconds=30.0, silence_timeout_s=1.0), statuses.append)
        except BaseException as exc:  # handed to the test's thread
            outcome.append(exc)

    thread = threading.Thread(target=capture, daemon=True)
    thread.start()
    wait_for(lambda: any(s.packet_rate_hz > 0 for s in statuses), 60, "the simulated LiDAR")
    wait_for(framed.is_set, 60, "a camera frame")
    camera = next(p for p in multiprocessing.active_children() if p.name == "sim-camera")
    assert camera.pid is not None
    os.kill(camera.pid, signal.SIGSTOP)
    stopped = time.monotonic()
    try:
        thread.join(20.0)
        assert not thread.is_alive(), "capture hangs on the stopped camera process"
    finally:
        if camera.is_alive():
            os.kill(camera.pid, signal.SIGKILL)
    assert isinstance(outcome[0], SensorSilenceError), outcome
    assert "no camera frame from sim for 1." in str(outcome[0]) and "stopped or hung" in str(outcome[0])
    assert time.monotonic() - stopped < 10.0  # ~1 s of silence, then the child ended within its 2 s grace period
    assert not camera.is_alive()


def frozen(datagrams: list[tuple[float, int, bytes]], data_port: int) -> list[tuple[float, int, bytes]]:
    """The same packets from a head that stopped turning: every block at azimuth 123.45 deg."""
    out = []
    for t, port, payload in datagrams:
        if port == data_port:
            packet = bytearray(payload)
            for block in range(BLOCKS_PER_PACKET):
                packet[block * 100 + 2 : block * 100 + 4] = (12345).to_bytes(2, "little")
            payload = bytes(packet)
        out.append((t, port, payload))
    return out


def run_udp_capture(tmp_path: Path, datagrams: Iterable[tuple[float, int, bytes]], ports: list[int],
                    silence_timeout_s: float) -> tuple[BaseException, list[tuple[float, CaptureStatus]], float]:
    """Send ``datagrams`` at the sensor's pace to a capture, until it raises (the rest are not sent); its error,
    its statuses (with the monotonic time they came) and when the last datagram left."""
    statuses: list[tuple[float, CaptureStatus]] = []
    sent: list[float] = []
    raised = threading.Event()

    def send() -> None:
        send_datagrams(itertools.takewhile(lambda _: not raised.is_set(), datagrams), "127.0.0.1", speed=1.0)
        sent.append(time.monotonic())

    sender = threading.Thread(target=send, daemon=True)
    request = CaptureRequest(tmp_path / "ds", 1, lidar=f"udp:127.0.0.1:{ports[0]}:{ports[1]}",
                             camera=f"replay:{future_camera(tmp_path / 'camera')}", silence_timeout_s=silence_timeout_s)
    def progress(status: CaptureStatus) -> None:
        statuses.append((time.monotonic(), status))
        if sender.ident is None:  # the capture is listening: send
            sender.start()

    with pytest.raises(SensorSilenceError) as caught:
        try:
            run_capture(request, progress)
        finally:
            raised.set()
    sender.join(10.0)
    return caught.value, statuses, sent[0]


def test_a_head_that_stopped_turning_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(capture_watchdog, "STARTUP_S", 1.0)
    ports = free_udp_ports(2)
    # Sent until the error, due 1.5 s after the first packet: still arriving then (their rate is in it).
    datagrams = frozen(still_rig_datagrams(ports[0], ports[1], 4.0), ports[0])
    error, statuses, _ = run_udp_capture(tmp_path, datagrams, ports, silence_timeout_s=1.5)
    assert "sends packets (7" in str(error) and "but its head does not turn (0 rpm)" in str(error)
    assert "motor is stopped" in str(error)
    assert max(s.packet_rate_hz for _, s in statuses) == pytest.approx(754, rel=0.05)


def test_the_packet_rate_falls_to_zero_when_the_stream_stops(tmp_path: Path) -> None:
    ports = free_udp_ports(2)
    error, statuses, ended = run_udp_capture(tmp_path, still_rig_datagrams(ports[0], ports[1], 1.0), ports,
                                             silence_timeout_s=2.5)
    assert "no VLP-16 data from udp:127.0.0.1" in str(error)
    assert max(s.packet_rate_hz for t, s in statuses if t < ended) == pytest.approx(754, rel=0.05)
    # 0 once no sweep has come for a second (engine.RATE_WINDOW_S), the last one taken up to half a second late
    # on a busy machine; statuses come every 0.5 s, and the silence error ends them 2.5 s after the last sweep.
    late = [s.packet_rate_hz for t, s in statuses if t > ended + 1.5]
    assert late and set(late) == {0.0}
