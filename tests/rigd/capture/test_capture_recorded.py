"""The capture loop on a recorded session of the moving simulated rig (pcap + camera replay directory).

Recorded sources are read as fast as the loop goes, so these tests are deterministic and need no waiting;
the trajectory the session was recorded from says where the rig was at every instant.
"""

from __future__ import annotations

import errno
import math
import re
import time
from pathlib import Path

import numpy as np
import pytest
from capture_helpers import START_S, free_udp_ports, read_meta, record_session, stop_of_pair

from drivers.sim.motion import MotionRigSpec, save_spec
from drivers.sim.stream import LidarEmitter
from rigd.capture import CaptureRequest, DiskFullError, SensorSilenceError, SourceEndedError, run_capture
from rigd.capture import sources as capture_sources
from rigd.capture import watchdog as capture_watchdog
from rigd.capture import writer as capture_writer
from rigd.capture.sync import SYNC_BOUND_S
from rigd.dataset import open_dataset
from rigd.errors import DatasetError

SPEC = MotionRigSpec(scene="indoor", seed=5, stops=4, still_s=1.5, move_s=1.0, width=128, height=64,
                     frame_period_s=0.2)
DURATION_S = 4 * SPEC.still_s + 3 * SPEC.move_s


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory):
    folder = tmp_path_factory.mktemp("recorded")
    return record_session(folder, SPEC, DURATION_S)


def request(out: Path, session, n: int, **kwargs) -> CaptureRequest:
    pcap, camera, _ = session
    return CaptureRequest(out=out, n=n, lidar=f"pcap:{pcap}", camera=f"replay:{camera}", still_seconds=0.5,
                          sweeps=3, **kwargs)


def test_one_pair_per_stop_and_none_in_motion(tmp_path: Path, session) -> None:
    statuses = []
    summary = run_capture(request(tmp_path / "ds", session, 3), statuses.append)
    _, _, trajectory = session
    assert [p.name for p in summary.pairs] == ["0000", "0001", "0002"]
    metas = [read_meta(p) for p in summary.pairs]
    stops = [stop_of_pair(m, trajectory, START_S) for m in metas]
    assert stops == [0, 1, 2]  # every stop lasts long enough for a pair, so none is skipped
    for meta in metas:
        window = meta["still_window_host_s"]
        assert window[1] - window[0] >= 0.5
        assert window[0] <= meta["camera"]["host_time_s"] <= window[1]
        # The recording's device clock is its host clock (offset ~0, up to float rounding of UNIX times).
        first, last = meta["lidar"]["device_time_s"]
        assert window[0] - 1e-3 <= first < last <= window[1] + 1e-3
        assert meta["lidar"]["sweeps_fused"] == 3 and meta["lidar"]["packets_lost"] == 0
        assert all(0.998 < c < 1.002 for c in meta["lidar"]["sweep_coverage"])
        motion = meta["motion"]
        assert motion["lidar_rotation_deg"] <= motion["lidar_still_rotation_deg"] == pytest.approx(0.05)
        assert motion["lidar_translation_m"] <= motion["lidar_still_translation_m"]
        sync = meta["sync"]  # the recording's packets carry their own times: measured and used agree
        assert sync["lidar_offset_used_s"] <= sync["lidar_offset_measured_s"] == meta["clock_offset_s"]["lidar"]
        assert 0 <= sync["lidar_receive_lag_s"] < 2e-3 and sync["bound_s"] == SYNC_BOUND_S
        assert sync["lidar_clock_steps"] == []
        assert meta["source"] == "captured" and meta["software_version"]
    moved = [m["motion"]["moved_since_previous_m"] for m in metas]
    assert moved[0] is None and min(moved[1:]) >= 0.5
    states = [s.state for s in statuses]
    for state in ("starting", "waiting_for_stop", "holding_still", "captured", "need_move", "done"):
        assert state in states
    dataset = open_dataset(tmp_path / "ds")
    assert (dataset.rig.camera.width, dataset.rig.camera.height) == (SPEC.width, SPEC.height)
    assert dataset.ground_truth is None  # a recorded camera is not the simulator's
    pair = dataset.load_pair(1)
    assert pair.cloud.ring is not None and pair.cloud.intensity is not None
    # Ring is the elevation rank: the fused points' elevations sort by ring (VLP-16: -15..15 deg in 2 deg steps),
    # seen from each laser's origin, 41.91 mm * tan(-elevation) above the sensor's (the VLP-16 manual).
    ring_elevation = -15.0 + 2.0 * pair.cloud.ring
    xyz = pair.cloud.points_lidar
    z_from_laser = xyz[:, 2] - 0.04191 * np.tan(np.radians(-ring_elevation))
    elevation = np.degrees(np.arctan2(z_from_laser, np.hypot(xyz[:, 0], xyz[:, 1])))
    np.testing.assert_allclose(elevation, ring_elevation, atol=0.05)


def test_rerun_continues_and_does_not_repeat_the_last_place(tmp_path: Path, session) -> None:
    _, _, trajectory = session
    first = run_capture(request(tmp_path / "ds", session, 1))
    assert [p.name for p in first.pairs] == ["0000"]
    # The replay starts over at stop 0, where pair 0 was taken: the rerun must move on from it.
    second = run_capture(request(tmp_path / "ds", session, 3))
    assert [p.name for p in second.pairs] == ["0001", "0002"]
    stops = [stop_of_pair(read_meta(p), trajectory, START_S) for p in (*first.pairs, *second.pairs)]
    assert stops == [0, 1, 2]
    assert run_capture(request(tmp_path / "ds", session, 3)).pairs == ()  # complete: nothing to do


def test_stop_event_ends_the_capture_between_pairs(tmp_path: Path, session) -> None:
    import threading

    stop = threading.Event()

    def progress(status) -> None:
        if status.state == "captured":
            stop.set()

    summary = run_capture(request(tmp_path / "ds", session, 3), progress, stop)
    assert [p.name for p in summary.pairs] == ["0000"]
    assert sorted(p.name for p in (tmp_path / "ds" / "pairs").iterdir()) == ["0000"]  # no half-written pair


def test_recording_too_short_is_a_named_error(tmp_path: Path, session) -> None:
    with pytest.raises(SourceEndedError, match="ended|no more frames"):
        run_capture(request(tmp_path / "ds", session, 6))
    assert len(open_dataset(tmp_path / "ds")) == 4  # what it did capture is complete


def test_low_free_space_stops_before_writing(tmp_path: Path, session, monkeypatch: pytest.MonkeyPatch) -> None:
    class Usage:
        free = 1_000_000  # 1 MB: less than twice a pair

    monkeypatch.setattr(capture_writer.shutil, "disk_usage", lambda path: Usage)
    with pytest.raises(DiskFullError, match="MB free"):
        run_capture(request(tmp_path / "ds", session, 2))
    assert not (tmp_path / "ds" / "pairs").exists() or not any((tmp_path / "ds" / "pairs").iterdir())


def test_disk_full_while_writing_is_a_named_error(tmp_path: Path, session, monkeypatch: pytest.MonkeyPatch) -> None:
    def full(root, index, image, cloud, meta, extras=None):
        raise DatasetError(f"{root}: could not write pair") from OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(capture_writer, "write_pair", full)
    with pytest.raises(DiskFullError, match="disk full while writing pair 0000"):
        run_capture(request(tmp_path / "ds", session, 1))


@pytest.mark.parametrize("field, value", [("n", 0), ("sweeps", 0), ("still_seconds", 0.0), ("min_move", -1.0),
                                          ("silence_timeout_s", math.nan), ("min_sweep_fraction", 0.0),
                                          ("min_sweep_fraction", 1.5)])
def test_bad_request_values_are_refused(tmp_path: Path, session, field: str, value: float) -> None:
    from dataclasses import replace

    from rigd.capture import CaptureError

    with pytest.raises(CaptureError, match=field):
        run_capture(replace(request(tmp_path / "ds", session, 1), **{field: value}))


def test_lidar_silence_is_a_named_error(tmp_path: Path, session, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(capture_watchdog, "STARTUP_S", 0.5)  # no sensor-start allowance for this test
    data, position = free_udp_ports(2)
    _, camera, _ = session
    source = f"udp:127.0.0.1:{data}:{position}"
    with pytest.raises(SensorSilenceError, match=rf"no VLP-16 data from {re.escape(source)} for \d+\.\d s") as raised:
        run_capture(CaptureRequest(tmp_path / "ds", 1, lidar=source, camera=f"replay:{camera}", silence_timeout_s=0.3))
    # the silence it names: at least the start-up allowance (more when a busy machine is slow to notice)
    silent_s = re.search(r"for (\d+\.\d) s", str(raised.value))
    assert silent_s is not None and float(silent_s.group(1)) >= 0.5, raised.value


def test_camera_silence_is_a_named_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(capture_watchdog, "STARTUP_S", 1.0)
    monkeypatch.setattr(capture_sources, "SIM_FRAME_GAP_S", 0.0)  # no allowance for slow simulated renders
    data, position = free_udp_ports(2)
    silent = tmp_path / "camera-rig.yaml"
    save_spec(silent, SPEC.started(time.time() + 3600.0))  # its camera starts in an hour
    # The timeout leaves the loopback LiDAR slack: on a loaded machine its sender thread falls behind by
    # half a second, and the LiDAR's silence would be named instead of the camera's.
    with LidarEmitter(SPEC, "127.0.0.1", data, position):
        named = rf"no camera frame from sim:{re.escape(str(silent))} for \d+\.\d s"
        with pytest.raises(SensorSilenceError, match=named) as raised:
            run_capture(CaptureRequest(tmp_path / "ds", 1, lidar=f"udp:127.0.0.1:{data}:{position}",
                                       camera=f"sim:{silent}", silence_timeout_s=2.0))
    silent_s = re.search(r"for (\d+\.\d) s", str(raised.value))
    assert silent_s is not None and float(silent_s.group(1)) >= 1.0, raised.value  # at least the allowance
