"""End to end in real time: the simulated rig drives and stops while its VLP-16 sends real UDP packets on
loopback (a thread of this test) and ``rigd capture`` follows its camera (a child process); then the
dataset is calibrated. And a capture killed mid-pair, stopped with Ctrl-C, and rerun to completion."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from capture_helpers import (
    FOLLOW_LEAD_S,
    SILENCE_ALLOWED_S,
    capture_following,
    complete_pairs,
    free_udp_ports,
    read_meta,
    stop_of_pair,
)

from drivers.sim.motion import MotionRigSpec, save_spec
from drivers.sim.stream import LidarEmitter
from rigd.cli import main
from rigd.dataset import open_dataset

REPO = Path(__file__).resolve().parents[3]


def rig_config(path: Path) -> Path:
    """A rig file with an initial guess 1.5 deg / 3 cm off the simulator's truth, so calibrate can start."""
    path.write_text(yaml.safe_dump({
        "camera": {"model": "equirectangular", "width": 256, "height": 128},
        "lidar": {"model": "VLP-16"},
        "initial_guess": {"rpy_deg": [-0.18 + 1.5, 15.47, -55.14], "xyz_m": [0.0934 + 0.03, 0.0597, -0.1659]},
    }))
    return path


def test_capture_over_udp_then_calibrate(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("RIGD_CONFIG", raising=False)
    # Places to spare: on a busy machine a stop may pass without its pair, and the rig stays at its last place.
    spec = MotionRigSpec(scene="indoor", seed=1, stops=8, still_s=1.5, move_s=0.5, width=256, height=128)
    code, emitter = capture_following(tmp_path, spec, 3, rig_config(tmp_path / "rig.yaml"))
    out, start, trajectory = tmp_path / "dataset", emitter.spec.start_host_s, emitter.trajectory
    assert code == 0
    dataset = open_dataset(out)
    assert len(dataset) == 3
    metas = [read_meta(p) for p in dataset.pair_dirs]
    stops = [stop_of_pair(m, trajectory, start) for m in metas]
    assert len(set(stops)) == 3  # three distinct places, each pair from a still period
    for meta in metas:
        # Received over UDP at the sensor's rate: a few ms from send to decode, nothing lost.
        assert meta["lidar"]["packets_lost"] == 0 and meta["lidar"]["packets"] >= 3 * 75
        assert abs(meta["clock_offset_s"]["lidar"]) < 0.05
        assert meta["lidar"]["pps"] == "absent"
    np.testing.assert_allclose(dataset.ground_truth.rpy_deg, [-0.18, 15.47, -55.14], atol=1e-9)

    # One process: a pool's spawned workers take longer to start than these 3 small pairs take to solve (the
    # pool is the calibrate command's own tests' business).
    code = main(["calibrate", str(out), "--no-visuals", "--workers", "1", "--out", str(tmp_path / "calibration")])
    extrinsics = yaml.safe_load((tmp_path / "calibration" / "extrinsics.yaml").read_text())
    assert len(extrinsics["T_camera_lidar"]["rpy_deg"]) == 3
    # A result with its verdict (3 small pairs are rarely enough to trust every axis): the exit code says which.
    assert code == {"trusted": 0, "weak": 3, "failed": 4}[extrinsics["verdict"]["status"]]


# `rigd capture` in a process of its own whose modules are imported ahead: it runs when the test writes a line
# to it. Its import takes 1-5 s here, with the load, which would put a run's start anywhere in the rig's stops.
IMPORTED = "\n".join(["import sys", "import rigd.cli.capture", "from rigd.cli import main",
                      "print('imported', flush=True)", "sys.stdin.readline()", "sys.exit(main())"])
KILLED = MotionRigSpec(scene="indoor", seed=2, stops=20, still_s=1.5, move_s=0.5, width=128, height=64,
                       frame_period_s=0.2)


class Run:
    """``rigd capture`` with ``args``, imported, waiting to run; its stderr in ``log``."""

    def __init__(self, args: list[str], cwd: Path, env: dict[str, str], log: Path) -> None:
        self.log = log
        self.process = subprocess.Popen([sys.executable, "-c", IMPORTED, *args], cwd=cwd, env=env, text=True,
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=log.open("w"))

    def imported(self) -> None:
        assert self.process.stdout is not None
        assert self.process.stdout.readline() == "imported\n", self.log.read_text()

    def start(self) -> None:
        assert self.process.stdin is not None
        self.process.stdin.write("go\n")
        self.process.stdin.close()

    def said(self, text: str) -> bool:
        return text in self.log.read_text()


def until_a_run_can_start(spec: MotionRigSpec) -> None:
    """Sleep, if need be, until the simulated rig moves. A capture started late in a still period takes its first
    pair from a still window that ends in the next move, whose first centimetres the stillness gate cannot see
    yet (issue 35, item 3: 1 run in 3 here). Started while the rig moves, or in the first 0.2 s of a stop, a run
    has its camera's process up (0.3-0.9 s) and its pair (0.7 s into a window) within the stop."""
    assert spec.start_host_s is not None
    leg_s = spec.still_s + spec.move_s
    phase_s = (time.time() - spec.start_host_s) % leg_s
    if 0.2 < phase_s < spec.still_s:
        time.sleep(spec.still_s - phase_s)


def wait_for(condition, timeout_s: float, what: str, log: Path) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}:\n{log.read_text()}"
        time.sleep(0.005)


def test_killed_or_stopped_capture_keeps_complete_pairs_and_a_rerun_finishes(tmp_path: Path) -> None:
    data_port, position_port = free_udp_ports(2)
    out = tmp_path / "dataset"
    pairs = out / "pairs"
    env = {k: v for k, v in os.environ.items() if k != "RIGD_CONFIG"}
    args = ["capture", "--n", "3", "--out", str(out), "--lidar", f"udp:127.0.0.1:{data_port}:{position_port}",
            "--camera", f"sim:{tmp_path / 'sim-rig.yaml'}", "--still-seconds", "0.5",
            "--config", str(rig_config(tmp_path / "rig.yaml")), "--silence-timeout", str(SILENCE_ALLOWED_S)]
    first = Run(args, tmp_path, env, tmp_path / "first.log")
    runs = [first]
    try:
        first.imported()
        spec = KILLED.started(time.time() + FOLLOW_LEAD_S)  # the first run listens, and its camera is up, by then
        save_spec(tmp_path / "sim-rig.yaml", spec)  # read by each run as it starts
        with LidarEmitter(spec, "127.0.0.1", data_port, position_port) as emitter:
            # 1. Killed (SIGKILL: no chance to clean up) as pair 0001 is being written, or just after.
            first.start()
            second, third = (Run(args, tmp_path, env, tmp_path / f"{name}.log") for name in ("second", "third"))
            runs += [second, third]  # imported while the first one captures
            wait_for(lambda: (pairs / ".0001.tmp").exists() or (pairs / "0001").exists()
                     or first.process.poll() is not None, 60, "pair 0001", first.log)
            assert first.process.poll() is None, first.log.read_text()
            first.process.kill()
            first.process.wait(10)
            after_kill = complete_pairs(out)
            assert after_kill in (["0000"], ["0000", "0001"])

            # 2. Ctrl-C while waiting for the rig: stops cleanly between pairs, exit code 130.
            second.imported()
            second.start()
            wait_for(lambda: second.said("move to the next place") or second.said("waiting for the rig"), 60,
                     "the capture loop", second.log)
            second.process.send_signal(signal.SIGINT)
            assert second.process.wait(30) == 130
            assert second.said("stopped after")
            stopped = complete_pairs(out)
            assert stopped[: len(after_kill)] == after_kill

            # 3. The same command again finishes the dataset.
            third.imported()
            until_a_run_can_start(emitter.spec)
            third.start()
            assert third.process.wait(90) == 0, third.log.read_text()
            trajectory, started = emitter.trajectory, emitter.spec.start_host_s
    finally:
        for run in runs:
            if run.process.poll() is None:
                run.process.kill()
                run.process.wait(10)
    assert complete_pairs(out) == ["0000", "0001", "0002"]
    assert not (pairs / ".0001.tmp").exists() and not (pairs / ".0002.tmp").exists()
    stops = [stop_of_pair(read_meta(pairs / name), trajectory, started) for name in ("0000", "0001", "0002")]
    assert len(set(stops)) == 3
