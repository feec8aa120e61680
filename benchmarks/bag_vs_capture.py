"""Issue 34's check at full length: the simulated rig's drive (moving with stops) taken by the capture engine from its
recorded session and by ``rigd import bag`` from a bag of the same packets and frames, at the capture's default
settings (2 s, 5 sweeps, places 0.5 m apart); prints both sets of pairs side by side and whether they agree (the
same stops, each from the same still window). tests/rigd/importers/bag/test_sim_drive.py is the short version.

Run from the repository's root: .venv/bin/python -m benchmarks.bag_vs_capture [--stops 6] [--width 512]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from drivers.sim.motion import MotionRigSpec
from drivers.sim.stream import TURN_S
from rigd.importers.bag.stills import StillOptions
from tests.rigd.importers.bag.sim_drive import captured_pairs, comparison_lines, imported_pairs, record_drive

SAME_SWEEP_S = 0.01


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stops", type=int, default=6)
    parser.add_argument("--still", type=float, default=3.0, help="seconds still at each stop")
    parser.add_argument("--move", type=float, default=1.5, help="seconds driving between stops")
    parser.add_argument("--width", type=int, default=512, help="panorama width px (height half of it)")
    parser.add_argument("--keep", type=Path, default=None, help="write the recordings and datasets here (kept)")
    args = parser.parse_args()
    spec = MotionRigSpec(scene="indoor", seed=7, stops=args.stops, still_s=args.still, move_s=args.move,
                         width=args.width, height=args.width // 2, frame_period_s=0.1)
    still = StillOptions()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        start = time.perf_counter()
        drive = record_drive(root, spec, args.stops * args.still + (args.stops - 1) * args.move)
        print(f"recorded {args.stops} stops (pcap + camera folder, and a bag) in {time.perf_counter() - start:.1f} s")
        start = time.perf_counter()
        captured = captured_pairs(root / "captured", drive.pcap, drive.camera, drive.trajectory, n=args.stops,
                                  still=still)
        print(f"capture: {time.perf_counter() - start:.1f} s")
        start = time.perf_counter()
        imported = imported_pairs(root / "imported", drive.bag, drive.trajectory, still=still)
        print(f"bag import: {time.perf_counter() - start:.1f} s")
    print("\n".join(comparison_lines(captured, imported)))
    same_stops = [p.stop for p in captured] == [p.stop for p in imported]
    same_windows = len(captured) == len(imported) and all(
        i.window_s[0] - SAME_SWEEP_S <= c.window_s[0] <= i.window_s[0] + TURN_S + SAME_SWEEP_S
        for c, i in zip(captured, imported, strict=True))
    print(f"same stops: {same_stops}; same still windows (within a turn): {same_windows}")


if __name__ == "__main__":
    main()
