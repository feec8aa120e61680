"""Pairs that are still and synchronised, or none: the simulated rig's VLP-16 through a fault relay over real
UDP on loopback (its clock stepped back, a PPS lock stepping it, lost packets, zeroed ranges) and the rig
vibrating or creeping, each asserting what capture wrote or refused and what it said. Captures end when they
have their pairs or when a status shows what the test waits for; a deadline only keeps a test from hanging."""

from __future__ import annotations

import math
import re
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import pytest
from capture_helpers import (
    SILENCE_ALLOWED_S,
    Fault,
    RelayedEmitter,
    clock_step,
    dropping,
    free_udp_ports,
    pps_lock,
    read_meta,
    scanned_turns,
    stop_of_pair,
    zeroed,
)

from drivers.sim.disturbance import Disturbance
from drivers.sim.motion import MotionRigSpec, Trajectory, save_spec
from drivers.sim.stream import TURN_S
from rigd.capture import CaptureRequest, CaptureStatus, SensorSilenceError, run_capture
from rigd.capture import status as capture_status
from rigd.capture import watchdog as capture_watchdog
from rigd.capture.sync import SYNC_BOUND_S

MOVING = MotionRigSpec(scene="indoor", seed=1, stops=6, still_s=2.0, move_s=0.6, width=128, height=64,
                       frame_period_s=0.1)
# The clock steps 0.3 s into the second stop, while that stop's still window grows (a pair at the first stop
# before it). The window restarts at the step and, when the sweep that brought the step news anchors the new
# one, once more ("stepped inside the still window"): about 1.3 s to the next pair, inside the 2 s stop.
STEP_AT_S = MOVING.still_s + MOVING.move_s + 0.3
STEP_SAID = re.compile(r"the LiDAR's clock stepped (?P<way>back|forward) (?P<s>[\d.]+) s")


class Relayed:
    """A capture of the simulated rig whose VLP-16 goes through a fault: what it wrote, said and raised."""

    def __init__(self, tmp_path: Path, spec: MotionRigSpec, fault: Callable[[int, float], Fault]) -> None:
        self.tmp_path, self.spec, self.fault = tmp_path, spec, fault
        self.statuses: list[CaptureStatus] = []
        self.error: BaseException | None = None
        self.pairs: tuple[Path, ...] = ()
        self.start_s = 0.0
        self.trajectory: Trajectory | None = None
        self.timed_out = False

    def run(self, n: int, until: Callable[[CaptureStatus], bool] | None = None, turns: int | None = None,
            deadline_s: float = 60.0, **request: object) -> Relayed:
        """Capture ``n`` pairs, or stop once a status meets ``until``. ``turns``: send only the rig's first
        ``turns`` turns, scanned before it starts (RelayedEmitter). A capture still running after ``deadline_s``
        is stopped and ``timed_out`` set, so that a test cannot hang. ``request``: CaptureRequest's fields (its
        silence timeout SILENCE_ALLOWED_S unless given)."""
        data, position = free_udp_ports(2)
        scanned = None if turns is None else scanned_turns(self.spec, data, position, turns)
        spec = self.spec.started(time.time() + 0.5)  # its start known before its first datagram is faulted
        self.start_s = spec.start_host_s or 0.0
        stop = threading.Event()

        def progress(status: CaptureStatus) -> None:
            self.statuses.append(status)
            if until is not None and until(status):
                stop.set()

        def time_out() -> None:
            self.timed_out = True
            stop.set()

        timer = threading.Timer(deadline_s, time_out)
        sensor = RelayedEmitter(spec, "127.0.0.1", data, position, self.fault(data, self.start_s), scanned)
        with sensor as emitter:
            self.trajectory = emitter.trajectory
            save_spec(self.tmp_path / "sim-rig.yaml", spec)
            timer.start()
            try:
                summary = run_capture(CaptureRequest(self.tmp_path / "ds", n, lidar=f"udp:127.0.0.1:{data}:{position}",
                                                     camera=f"sim:{self.tmp_path / 'sim-rig.yaml'}",
                                                     **{"silence_timeout_s": SILENCE_ALLOWED_S, **request}),
                                      progress, stop)
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
                      lambda data, start: clock_step(data, STEP_AT_S, step_s)).run(2, still_seconds=0.5)
    assert relayed.error is None and len(relayed.pairs) == 2
    metas = assert_still_and_synchronised(relayed)
    # Steps and offsets are measured from when the packets were received (drivers.vlp16.clock), so each holds a
    # receive delay: microseconds on a quiet machine, milliseconds on a busy one, where this process sends and
    # reads them late (the step said first holds one packet's). Within SYNC_BOUND_S, the receive lag capture
    # accepts, of the sensor's truth: a kept offset would be 3 or 10 s off.
    said = [m for m in map(STEP_SAID.search, (s.message for s in relayed.statuses)) if m is not None]
    assert said and said[0]["way"] == ("back" if step_s < 0 else "forward"), relayed.statuses[-3:]
    assert float(said[0]["s"]) == pytest.approx(abs(step_s), abs=SYNC_BOUND_S)
    after = [m for m in metas if m["lidar"]["host_time_s"][0] > relayed.start_s + STEP_AT_S]
    assert after, "no pair after the step"
    for meta in after:
        steps = meta["sync"]["lidar_clock_steps"]
        assert len(steps) == 1 and steps[0]["seen"] == ("back" if step_s < 0 else "forward")
        assert steps[0]["step_s"] == pytest.approx(step_s, abs=SYNC_BOUND_S)
        assert meta["sync"]["lidar_offset_used_s"] == pytest.approx(-step_s, abs=SYNC_BOUND_S)  # measured again
        assert meta["lidar"]["packets_lost"] == 0  # whole sweeps (a +10 s step is no loss: test_vlp16_clock)


def test_a_pps_lock_stepping_the_clock_back_gives_only_synchronised_pairs(tmp_path: Path) -> None:
    relayed = Relayed(tmp_path, MOVING, lambda data, start: pps_lock(data, start, STEP_AT_S, 2.0)).run(
        2, still_seconds=0.5)
    assert relayed.error is None and len(relayed.pairs) == 2
    metas = assert_still_and_synchronised(relayed)
    locked = [m for m in metas if m["lidar"]["pps"] == "locked"]
    assert locked, "no pair after the lock"
    for meta in locked:
        assert meta["lidar"]["time_source"] == "gps"
        steps = meta["sync"]["lidar_clock_steps"]
        # Measured from receive times, as in the test above: within SYNC_BOUND_S of the truth.
        assert len(steps) == 1 and steps[0]["step_s"] == pytest.approx(-2.0, abs=SYNC_BOUND_S)
        assert meta["sync"]["lidar_offset_used_s"] == pytest.approx(0.0, abs=SYNC_BOUND_S)  # its clock is UTC again


STILL = MotionRigSpec(scene="indoor", seed=3, stops=1, still_s=30.0, move_s=1.0, width=128, height=64,
                      frame_period_s=0.25)


@pytest.mark.parametrize("fault, says", [
    (lambda data, start: dropping(data, 0.75), "loses packets: no sweep with at least 99% of a turn's packets"),
    (lambda data, start: zeroed(data), "sees almost nothing: returns in 0 of 5760 directions"),
])
def test_heavy_loss_or_a_blind_lidar_ends_the_capture_naming_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fault: Callable[[int, float], Fault], says: str) -> None:
    monkeypatch.setattr(capture_watchdog, "STARTUP_S", 1.0)
    started = time.monotonic()
    # Its turns scanned before it starts (RelayedEmitter): a busy machine's late turns, dropped whole, would leave
    # gaps in the stream, which capture names instead. 3.5 s of them: the error is due 2 s after the first.
    relayed = Relayed(tmp_path, STILL, fault).run(1, turns=math.ceil(3.5 / TURN_S), silence_timeout_s=2.0)
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


# A rule's refusal, in the status line (rigd.capture.engine: _decide checks the camera first, then the LiDAR's
# window, whose note gives the motion of the latest sweep from the window's first, and the thresholds).
LIDAR_RULE = re.compile(r"\(LiDAR: (?P<deg>[\d.]+) deg, (?P<mm>[\d.]+) mm from the window's first sweep; still is "
                        r"within (?P<max_deg>[\d.]+) deg, (?P<max_mm>[\d.]+) mm\)")
CAMERA_RULE = re.compile(r"\(the camera sees motion: [\d.]+ deg\)")
# The creep (0.5 cm/s) leaves the LiDAR's 2.6 mm after ~0.55 s: its windows end by 0.7 s, well short of this;
# a vibration's within a sweep or two. A still rig's window is held this long after its first whole sweep.
STILL_SECONDS = 1.0
# A disturbed rig is watched for twice that much of its stream: any window begun in its first second could
# have been held by its end, and none is. Its turns are scanned before it starts (RelayedEmitter), so that all
# of them reach the gate on a busy machine too (+2: the first sweep may be partial, the last is never closed).
DISTURBED_TURNS = math.ceil(2 * STILL_SECONDS / TURN_S) + 2


def stream_over() -> Callable[[CaptureStatus], bool]:
    """True at the first status without packets for a second (lidar_link.RATE_WINDOW_S) after some: the stream has
    ended and the capture, which shows that only from its loop, has judged every sweep sent."""
    seen = False

    def over(status: CaptureStatus) -> bool:
        nonlocal seen
        seen = seen or status.packet_rate_hz > 0
        return seen and status.packet_rate_hz == 0

    return over


@pytest.mark.parametrize("disturbance", [
    Disturbance(vibration_deg=0.1, vibration_hz=2.0, seed=5),
    Disturbance(creep_m_s=0.005, seed=6),
    Disturbance(),
], ids=["vibration 0.1 deg", "creep 0.5 cm/s", "still"])
def test_a_vibrating_or_creeping_rig_gives_no_pair_a_still_one_does(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, disturbance: Disturbance) -> None:
    # Every decision's status, not one each 0.5 s: which rule refused is asserted, and a vibrating rig's
    # refusals do not change the state, so only the periodic status would show them.
    monkeypatch.setattr(capture_status, "STATUS_PERIOD_S", 0.0)
    unfaulted: Callable[[int, float], Fault] = lambda data, start: (lambda t, port, payload: payload)  # noqa: E731
    relayed = Relayed(tmp_path, replace(STILL, disturbance=disturbance), unfaulted)
    if not disturbance.active:  # streamed the same way, for up to 5 s: its pair comes after about 1.2 s
        relayed.run(1, turns=math.ceil(5.0 / TURN_S), still_seconds=STILL_SECONDS)
        assert relayed.error is None and len(relayed.pairs) == 1
        motion = read_meta(relayed.pairs[0])["motion"]
        assert motion["lidar_rotation_deg"] <= motion["lidar_still_rotation_deg"]
        assert motion["lidar_translation_m"] <= motion["lidar_still_translation_m"]
        return
    relayed.run(1, until=stream_over(), turns=DISTURBED_TURNS, still_seconds=STILL_SECONDS)
    assert relayed.error is None and not relayed.timed_out
    assert relayed.pairs == () and not (tmp_path / "ds" / "pairs").exists()
    assert relayed.statuses[-1].state == "stopped"
    assert max(s.still_for_s for s in relayed.statuses) < STILL_SECONDS
    waiting = [s.message for s in relayed.statuses if s.state == "waiting_for_stop"]
    # The last refusal names a motion, from either rule (the camera's is asked first). A window that spans two
    # frames (0.25 s apart, half the vibration's period) shows the camera the vibration too; the creep it cannot
    # resolve, but at 128 px its own noise passes its half-pixel threshold in a few per cent of frame pairs.
    assert waiting and (LIDAR_RULE.search(waiting[-1]) or CAMERA_RULE.search(waiting[-1])), relayed.statuses[-3:]
    # The LiDAR's rule refuses the motion itself, each time beyond its bound for what the motion is.
    beyond = [m for m in map(LIDAR_RULE.search, waiting)
              if m is not None and (float(m["deg"]) > float(m["max_deg"]) or float(m["mm"]) > float(m["max_mm"]))]
    assert beyond, waiting[-5:]
    if disturbance.vibration_deg:  # a rotation
        assert all(float(m["deg"]) > float(m["max_deg"]) for m in beyond), [m[0] for m in beyond]
    else:  # a translation
        assert all(float(m["deg"]) <= float(m["max_deg"]) for m in beyond), [m[0] for m in beyond]
