"""A dense LiDAR's dataset thinned to a VLP-16's 2 deg rings at several phases, its rings picked by the dataset's
medians and by each pair's, each calibrated as `rigd calibrate` does and compared with the dense dataset's own
solution: the verdict, the difference per axis (rotation about the LiDAR's x, y, z in deg; translation in cm) and
the axes the verdict vouches for beyond the tolerance (what must never happen).

    python benchmarks/thinned_head.py /tmp/fh [--phases 0,0.5,1,1.5] [--work /tmp/thinned]

(/tmp/fh: `rigd import ford ../shared/data/ford_ladybug3 /tmp/fh`, docs/dataset.md). Each calibration starts from
the dataset's rig.yaml guess; about 25 s each on a quiet 2-core machine.
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

import numpy as np

from calib.uncertainty import AXES, TO_DISPLAY, xi_of
from rigd.calibration import CalibrationRequest, run_calibration
from rigd.dataset.thin import RingsBy, ThinOptions, thin_dataset
from rigd.report import CalibrationReport


def solve(dataset: Path) -> tuple[np.ndarray, CalibrationReport, float]:
    """The dataset calibrated from its rig.yaml guess: its pose tau (6,), its report and the seconds it took."""
    began = time.perf_counter()
    outcome = run_calibration(CalibrationRequest(dataset=dataset, write_visuals=False))
    return outcome.T_camera_lidar.tau, outcome.report, time.perf_counter() - began


def vouched_beyond(report: CalibrationReport, diff: np.ndarray) -> list[str]:
    """The axes the verdict vouches for (not weak, not held) whose difference is beyond its tolerance."""
    verdict = report["verdict"]
    tolerance = report["tolerance"].get("per_axis") or [report["tolerance"]["rotation_deg"]] * 3 + \
        [report["tolerance"]["translation_cm"]] * 3
    unvouched = set(verdict["weak_axes"]) | set(verdict.get("fixed_axes", []))
    if verdict["status"] not in ("trusted", "weak"):
        return []
    return [ax for ax, d, tol in zip(AXES, diff, tolerance, strict=True) if ax not in unvouched and abs(d) > tol]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--phases", default="0,0.5,1,1.5", help="grid phases, deg")
    parser.add_argument("--work", type=Path, default=Path("/tmp/thinned"), help="where the thinned sets go")
    args = parser.parse_args()
    dense, report, wall = solve(args.dataset)
    print(f"dense: {report['verdict']['status']} {report['verdict']['weak_axes']} ({wall:.0f} s)")
    print("| phase | rings by | verdict | from the dense solution (deg; cm) | in all | vouched beyond tolerance | s |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for phase in (float(p) for p in args.phases.split(",")):
        for by in RingsBy:
            out = args.work / f"{args.dataset.name}_{by.value}_{phase:g}"
            shutil.rmtree(out, ignore_errors=True)
            thin_dataset(args.dataset, out, ThinOptions(2.0, phase, rings_by=by))
            tau, report, wall = solve(out)
            diff = xi_of(dense, tau) * TO_DISPLAY
            v = report["verdict"]
            axes = f" ({', '.join(v['weak_axes'])})" if v["weak_axes"] else ""
            shown = ", ".join(f"{d:+.2f}" for d in diff[:3]) + "; " + ", ".join(f"{d:+.2f}" for d in diff[3:])
            total = f"{np.linalg.norm(diff[:3]):.2f}° / {np.linalg.norm(diff[3:]):.1f} cm"
            beyond = ", ".join(vouched_beyond(report, diff)) or "none"
            print(f"| {phase:g}° | {by.value} | {v['status']}{axes} | {shown} | {total} | {beyond} | {wall:.0f} |",
                  flush=True)


if __name__ == "__main__":
    main()
