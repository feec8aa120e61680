"""A simulated rig stands at its last place for good: a capture that still lacks pairs once the rig has stood
there longer than a stop lasts ends with an error naming the rig, the pairs written and the likely cause,
rather than waiting for a new place for ever. The pairs written stay complete."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
from capture_helpers import complete_pairs

from drivers.sim.motion import MotionRigSpec, save_spec
from rigd.capture import CaptureError, CaptureRequest, CaptureStatus, SimRigEndedError, SourceEndedError, run_capture
from rigd.capture import sim_end as capture_sim_end
from rigd.dataset import open_dataset
from rigd.errors import RigdError

WAIT_S = 30.0  # far beyond when the error is due: a capture still running then would wait for ever


@pytest.fixture(autouse=True)
def no_rig_file(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("RIGD_CONFIG", raising=False)


def capture_until_it_ends(request: CaptureRequest) -> tuple[BaseException, float]:
    """Run ``request`` in a thread; what it raised and after how many seconds. A capture still running after
    WAIT_S is stopped (between pairs: its sensors are closed) and the test fails."""
    statuses: list[CaptureStatus] = []
    outcome: list[BaseException] = []
    stop = threading.Event()

    def capture() -> None:
        try:
            run_capture(request, statuses.append, stop)
        except BaseException as exc:  # handed to the test's thread
            outcome.append(exc)

    started = time.monotonic()
    thread = threading.Thread(target=capture, daemon=True)
    thread.start()
    thread.join(WAIT_S)
    if thread.is_alive():
        waiting = statuses[-1] if statuses else None
        stop.set()
        thread.join(WAIT_S)
        pytest.fail(f"the capture still waits after {WAIT_S:g} s: {waiting}")
    elapsed = time.monotonic() - started
    assert outcome, f"the capture ended without an error: {statuses[-3:]}"
    return outcome[0], elapsed


def whole_pairs(out: Path) -> list[str]:
    """:func:`complete_pairs`, and no half-written pair folder left behind."""
    pairs = out / "pairs"
    assert not pairs.is_dir() or not [p.name for p in pairs.iterdir() if not p.name.isdigit()], \
        "a half-written pair is left"
    return complete_pairs(out)


def test_more_pairs_than_the_sim_rig_has_places_end_with_an_error(tmp_path: Path) -> None:
    rig = tmp_path / "sim-rig.yaml"
    save_spec(rig, MotionRigSpec(scene="indoor", seed=4, stops=2, still_s=1.5, move_s=0.5, width=64, height=32))
    out = tmp_path / "ds"
    error, elapsed = capture_until_it_ends(CaptureRequest(out, 5, lidar=f"sim:{rig}", camera="sim",
                                                          still_seconds=0.5))
    assert isinstance(error, SimRigEndedError), error
    assert isinstance(error, SourceEndedError) and isinstance(error, CaptureError)  # rigd: error: ..., exit code 2
    # The rig reaches its last place 2 s after it starts; it has stood there its 1.5 s stop and 5 s of grace by
    # 8.5 s (at once, if that place already has its pair); the sensors' processes take a second or two to start.
    assert elapsed < 13.0
    written = whole_pairs(out)
    assert 1 <= len(written) <= 2  # one pair a place at most; the last place, where the rig stays, gives one
    assert open_dataset(out).rig.lidar_elevation_sigma_deg == 0.0  # the simulated beams are where the table says
    message = str(error)
    assert message.startswith(f"the simulated rig (--lidar sim:{rig}) has stopped at all its 2 places and stands at "
                              "the last one for good"), message
    assert f"{out} has {len(written)} of the 5 pairs asked ({len(written)} written by this run, complete)" in message
    assert f"too few places for the 5 pairs missing: give it more places (stops in {rig})" in message


def test_a_sim_camera_too_slow_for_the_stops_ends_the_capture_with_an_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # A frame a minute at most: the camera gives one frame while the rig stops at both its places (as on a
    # machine so busy that a render takes longer than a leg), so 2 pairs cannot be had from its 2 places.
    # Before the fix: no camera frame for 20 s, then a "stopped or hung" camera error.
    monkeypatch.setattr(capture_sim_end, "SIM_END_GRACE_S", 1.0)  # no pair can come at the last place: not 5 s
    rig = tmp_path / "sim-rig.yaml"
    save_spec(rig, MotionRigSpec(scene="indoor", seed=4, stops=2, still_s=0.6, move_s=0.4, width=64, height=32,
                                 frame_period_s=60.0))
    out = tmp_path / "ds"
    error, elapsed = capture_until_it_ends(CaptureRequest(out, 2, lidar=f"sim:{rig}", camera="sim",
                                                          still_seconds=0.5))
    assert isinstance(error, SimRigEndedError) and isinstance(error, RigdError), error
    # Last stop at 1 s, stood there 0.6 s + 1 s of grace: 2.6 s after the rig starts (at once, if that place has
    # its pair), well before the camera's 20 s silence allowance.
    assert elapsed < 15.0
    written = whole_pairs(out)
    assert len(written) <= 1
    message = str(error)
    kept = f"{len(written)} written by this run, complete" if written else "none written by this run"
    assert message.startswith(f"the simulated rig (--lidar sim:{rig}) has stopped at all its 2 places"), message
    assert (f"{out} has {len(written)} of the 2 pairs asked ({kept}); {2 - len(written)} of its stops gave no pair: "
            "the simulated camera renders too slowly for this machine's load (each stop's view must be rendered "
            "within a leg: 0.6 s standing + 0.4 s driving); close other jobs, or lengthen its stops (still_s) or "
            f"shrink its panorama (width, height) in {rig} (for `rigd demo`: a smaller --width)") in message
