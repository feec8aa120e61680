"""Pairs that are still and synchronised, or none: the simulated rig's VLP-16 through a fault relay over real
UDP on loopback (its clock stepped back, a PPS lock stepping it, lost packets, zeroed ranges) and the rig
vibrating or creeping, each asserting what capture wrote or refused and what it said."""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import pytest
from capture_helpers import (
    Fault,
    RelayedEmitter,
    clock_step,
    dropping,
    free_udp_ports,
    pps_lock,
    read_meta,
    stop_of_pair,
    zeroed,
)

from drivers.sim.disturbance import Disturbance
from drivers.sim.motion import MotionRigSpec, Trajectory, save_spec
from rigd.capture import CaptureRequest, CaptureStatus, SensorSilenceError, run_capture
from rigd.capture import engine as capture_engine
from rigd.capture.engine import SYNC_BOUND_S

MOVING = MotionRigSpec(scene="indoor", seed=1, stops=6, still_s=3.0, move_s=1.5, width=128, height=64,
                       frame_period_s=0.1)


class Relayed:
    """A capture of the simulated rig whose VLP-16 goes through a fault: what it wrote, said and raised."""

    def __init__(self, tmp_path: Path, spec: MotionRigSpec, fault: Callable[[int, float], Fault]) -> None:
        self.tmp_path, self.spec, self.fault = tmp_path, spec, fault
        self.statuses: list[CaptureStatus] = []
        self.error: BaseException | None = None
        self.pairs: tuple[Path, ...] = ()
        self.start_s = 0.0
        self.trajectory: Trajectory | None = None

    def run(self, n: int, stop_after_s: float = 40.0, **request: object) -> Relayed:
        """Capture ``n`` pairs, stopping after ``stop_after_s`` at most (so that a test cannot hang)."""
        data, position = free_udp_ports(2)
        spec = self.spec.started(time.time() + 0.5)  # its start known before its first datagram is faulted
        self.start_s = spec.start_host_s or 0.0
        stop = threading.Event()
        timer = threading.Timer(stop_after_s, stop.set)
        with RelayedEmitter(spec, "127.0.0.1", data, position, self.fault(data, self.start_s)) as emitter:
            self.trajectory = emitter.trajectory
            save_spec(self.tmp_path / "sim-rig.yaml", spec)
            timer.start()
            try:
                summary = run_capture(CaptureRequest(self.tmp_path / "ds", n, lidar=f"udp:127.0.0.1:{data}:{position}",
                                                     camera=f"sim:{self.tmp_path / 'sim-rig.yaml'}", **request),
                                      self.statuses.append, stop)
                self.pairs = summary.pairs
            except SensorSilenceError as exc:
                self.error = exc
            finally:
                timer.cancel()
        return self

    def said(self, text: str) -> bool:
        return any(text in s.message for s in self.statuses)


def assert_still_and_synchronised(relayed: Relayed) -> list[dict]:
    """Every pair's camera frame and every fused sweep, by when their packets were received, lie in one stop
    of the trajectory, and the offset the sweeps were placed with is the one their packets measure."""
    assert relayed.trajectory is not None
    metas = [read_meta(p) for p in relayed.pairs]
    stops = [stop_of_pair(m, relayed.trajectory, relayed.start_s, lidar_times="host_time_s") for m in metas]
    assert len(set(stops)) == len(stops)
    for meta in metas:
        window = meta["still_window_host_s"]
        assert window[0] <= meta["camera"]["host_time_s"] <= window[1]
        assert abs(meta["camera_minus_lidar_s"]) <= window[1] - window[0]
        sync = meta["sync"]
        assert 0 <= sync["lidar_receive_lag_s"] <= SYNC_BOUND_S
        assert meta["clock_offset_s"]["lidar"] == sync["lidar_offset_measured_s"]
        assert abs(sync["lidar_offset_measured_s"] - sync["lidar_offset_used_s"]) <= SYNC_BOUND_S
    return metas


@pytest.mark.parametrize("step_s, frame_period_s", [(-3.0, 0.5), (-3.0, 0.1), (10.0, 0.25)],
                         ids=["back, 2 Hz camera", "back, 10 Hz camera", "forward"])
def test_a_clock_stepping_mid_capture_gives_only_synchronised_pairs(tmp_path: Path, step_s: float,
                                                                    frame_period_s: float) -> None:
    """Stepped back 3 s, a 2 Hz camera used to get pairs of image and cloud metres apart and a 10 Hz one
    to wait for a frame for ever."""
    relayed = Relayed(tmp_path, replace(MOVING, frame_period_s=frame_period_s),
                      lambda data, start: clock_step(data, 5.0, step_s)).run(3, still_seconds=0.5)
    assert relayed.error is None and len(relayed.pairs) == 3
    metas = assert_still_and_synchronised(relayed)
    assert relayed.said(f"the LiDAR's clock stepped {'back' if step_s < 0 else 'forward'} {abs(step_s):.1f}")
    after = [m for m in metas if m["lidar"]["host_time_s"][0] > relayed.start_s + 5.0]
    assert after, "no pair after the step"
    for meta in after:
        steps = meta["sync"]["lidar_clock_steps"]
        assert len(steps) == 1 and steps[0]["seen"] == ("back" if step_s < 0 else "forward")
        assert steps[0]["step_s"] == pytest.approx(step_s, abs=5e-3)
        assert meta["sync"]["lidar_offset_used_s"] == pytest.approx(-step_s, abs=0.02)  # measured again, not kept
        assert meta["lidar"]["packets_lost"] == 0  # whole sweeps (a +10 s step is no loss: test_vlp16_clock)


def test_a_pps_lock_stepping_the_clock_back_gives_only_synchronised_pairs(tmp_path: Path) -> None:
    relayed = Relayed(tmp_path, MOVING, lambda data, start: pps_lock(data, start, 5.0, 2.0)).run(3, still_seconds=0.5)
    assert relayed.error is None and len(relayed.pairs) == 3
    metas = assert_still_and_synchronised(relayed)
    locked = [m for m in metas if m["lidar"]["pps"] == "locked"]
    assert locked, "no pair after the lock"
    for meta in locked:
        assert meta["lidar"]["time_source"] == "gps"
        steps = meta["sync"]["lidar_clock_steps"]
        assert len(steps) == 1 and steps[0]["step_s"] == pytest.approx(-2.0, abs=5e-3)
        assert meta["sync"]["lidar_offset_used_s"] == pytest.approx(0.0, abs=0.02)  # its clock is UTC again


STILL = MotionRigSpec(scene="indoor", seed=3, stops=1, still_s=30.0, move_s=1.0, width=128, height=64,
                      frame_period_s=0.25)


@pytest.mark.parametrize("fault, says", [
    (lambda data, start: dropping(data, 0.75), "loses packets: no sweep with at least 99% of a turn's packets"),
    (lambda data, start: zeroed(data), "sees almost nothing: returns in 0 of 5760 directions"),
])
def test_heavy_loss_or_a_blind_lidar_ends_the_capture_naming_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fault: Callable[[int, float], Fault], says: str) -> None:
    monkeypatch.setattr(capture_engine, "STARTUP_S", 1.0)
    started = time.monotonic()
    relayed = Relayed(tmp_path, STILL, fault).run(1, silence_timeout_s=2.0)
    assert isinstance(relayed.error, SensorSilenceError), relayed.statuses[-3:]
    assert says in str(relayed.error) and re.search(r"for 2\.\d s", str(relayed.error))
    assert relayed.said("the LiDAR's sweeps are incomplete" if "loses" in says else "the LiDAR sees almost nothing")
    assert time.monotonic() - started < 15.0  # the silence timeout after the first packets, not a wait for stillness
    assert not (tmp_path / "ds" / "pairs").exists()


def test_light_loss_gives_pairs_of_whole_sweeps_with_the_loss_in_meta(tmp_path: Path) -> None:
    relayed = Relayed(tmp_path, STILL, lambda data, start: dropping(data, 0.01, seed=4)).run(
        1, still_seconds=1.0, sweeps=3)
    assert relayed.error is None and len(relayed.pairs) == 1
    meta = read_meta(relayed.pairs[0])
    assert meta["lidar"]["min_sweep_fraction"] == 0.99
    assert all(c >= 0.99 - 0.003 for c in meta["lidar"]["sweep_coverage"])
    assert meta["lidar"]["packets_lost"] == 0  # its sweeps are whole ...
    assert meta["stream"]["packets_lost_total"] > 0  # ... though the stream lost some


@pytest.mark.parametrize("disturbance", [
    Disturbance(vibration_deg=0.1, vibration_hz=2.0, seed=5),
    Disturbance(creep_m_s=0.005, seed=6),
    Disturbance(),
], ids=["vibration 0.1 deg", "creep 0.5 cm/s", "still"])
def test_a_vibrating_or_creeping_rig_gives_no_pair_a_still_one_does(tmp_path: Path, disturbance: Disturbance) -> None:
    unfaulted: Callable[[int, float], Fault] = lambda data, start: (lambda t, port, payload: payload)  # noqa: E731
    relayed = Relayed(tmp_path, replace(STILL, disturbance=disturbance), unfaulted).run(1, stop_after_s=10.0,
                                                                                        still_seconds=2.0)
    assert relayed.error is None
    if not disturbance.active:
        assert len(relayed.pairs) == 1
        motion = read_meta(relayed.pairs[0])["motion"]
        assert motion["lidar_rotation_deg"] <= motion["lidar_still_rotation_deg"]
        assert motion["lidar_translation_m"] <= motion["lidar_still_translation_m"]
        return
    assert relayed.pairs == () and not (tmp_path / "ds" / "pairs").exists()
    waiting = [s.message for s in relayed.statuses if s.state == "waiting_for_stop"]
    assert waiting and "from the window's first sweep" in waiting[-1], relayed.statuses[-3:]
    assert relayed.statuses[-1].state == "stopped"
    assert max(s.still_for_s for s in relayed.statuses) < 2.0
