"""Issue 34's check: the simulated rig's drive (moving with stops) written as a bag imports to the pairs the capture
takes of it: the same places, each from the same still window (both run the capture's stillness gate on the same
sweeps), each pair taken when the window has held. A short drive here; benchmarks/bag_vs_capture.py runs a
longer one at the capture's default settings."""

from __future__ import annotations

from pathlib import Path

from drivers.sim.motion import MotionRigSpec
from drivers.sim.stream import TURN_S
from rigd.importers.bag.stills import StillOptions
from tests.rigd.importers.bag import sim_drive

SPEC = MotionRigSpec(scene="indoor", seed=5, stops=3, still_s=1.2, move_s=1.0, width=128, height=64,
                     frame_period_s=0.2)
DURATION_S = 3 * SPEC.still_s + 2 * SPEC.move_s
STILL = StillOptions(still_seconds=0.5, sweeps=3)
SAME_SWEEP_S = 0.01  # a tenth of a turn: two times of one sweep


def test_bag_of_the_drive_imports_to_the_captured_pairs(tmp_path: Path) -> None:
    drive = sim_drive.record_drive(tmp_path, SPEC, DURATION_S)
    captured = sim_drive.captured_pairs(tmp_path / "captured", drive.pcap, drive.camera, drive.trajectory,
                                        n=SPEC.stops, still=STILL)
    imported = sim_drive.imported_pairs(tmp_path / "imported", drive.bag, drive.trajectory, still=STILL)
    report = "\n".join(sim_drive.comparison_lines(captured, imported))
    assert [p.stop for p in imported] == [p.stop for p in captured] == list(range(SPEC.stops)), report
    for cap, imp in zip(captured, imported, strict=True):
        # the same gate on the same sweeps (the bag holds the turns the capture can use): the same window, and
        # the pair taken at the same moment (times: the capture's are the packets', the bag's its first return's)
        assert abs(cap.window_s[0] - imp.window_s[0]) <= SAME_SWEEP_S, report
        assert abs(cap.window_s[1] - imp.window_s[1]) <= SAME_SWEEP_S, report
        assert abs(cap.image_s - imp.image_s) <= SAME_SWEEP_S, report
        stop_start, stop_end = drive.trajectory.stop_interval(imp.stop)  # type: ignore[arg-type]
        for t in (imp.image_s, *imp.lidar_s, cap.image_s, *cap.lidar_s):
            assert stop_start - TURN_S / 2 <= t <= stop_end + TURN_S / 2, report  # while standing at the stop
        assert imp.lidar_s[0] - STILL.max_offset_s <= imp.image_s <= imp.lidar_s[1] + STILL.max_offset_s


def test_comparison_lines_name_a_missing_pair() -> None:
    pair = sim_drive.TakenPair(0, 1.0, (0.9, 1.0), (0.0, 1.5))
    lines = sim_drive.comparison_lines([pair, pair], [pair])
    assert lines[0] == "pairs: capture 2, bag import 1" and lines[2].endswith("bag: -")
