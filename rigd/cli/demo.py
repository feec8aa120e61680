"""``rigd demo``: the main job end to end on the simulated rig (simulate -> calibrate -> report)."""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np

from calib.geometry import Transform
from rigd.calibration import CalibrationRequest, run_calibration
from rigd.simulate import write_simulated_dataset


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="simulate a rig, calibrate it from a perturbed guess, report the error",
        description="Runs the whole job on the simulated rig: writes a simulated dataset, calibrates it "
        "starting from the ground truth perturbed by a few degrees and centimetres, and prints the error "
        "against the simulator's ground truth and where the overlay images are.",
    )
    parser.add_argument("--out", type=Path, default=Path("demo-out"), help="working directory (default demo-out)")
    parser.add_argument("--scene", choices=["indoor", "outdoor"], default="indoor")
    parser.add_argument("--pairs", type=int, default=6)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--width", type=int, default=1024)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    dataset = args.out / "dataset"
    if dataset.exists():
        shutil.rmtree(dataset)
    print(f"simulating {args.pairs} {args.scene} pairs into {dataset}", file=sys.stderr)
    write_simulated_dataset(dataset, args.scene, args.pairs, args.seed, args.width, args.width // 2)
    from rigd.dataset import open_dataset

    truth = open_dataset(dataset).ground_truth
    assert truth is not None
    rng = np.random.default_rng(args.seed)
    start = Transform.from_rpy_xyz(truth.rpy_deg + rng.uniform(-3, 3, 3),
                                   truth.translation_m + rng.uniform(-0.05, 0.05, 3))
    request = CalibrationRequest(dataset=dataset, out_dir=args.out / "calibration", initial=start)
    outcome = run_calibration(request, lambda s, f: print(f"[{f * 100:5.1f} %] {s}", file=sys.stderr))
    rep = outcome.report
    init = rep["change_from_initial"]
    err = rep["error_vs_ground_truth"]
    print(f"initial guess moved by {init['rotation_deg']:.2f} deg, {init['translation_cm']:.1f} cm")
    print(f"error vs ground truth: {err['rotation_deg']:.3f} deg, {err['translation_cm']:.2f} cm "
          f"(rpy {np.round(err['rpy_deg'], 3).tolist()} deg, xyz {np.round(err['xyz_cm'], 2).tolist()} cm)")
    print(f"wall time {rep['quality']['wall_time_s']:.1f} s; extrinsics: {outcome.out_dir / 'extrinsics.yaml'}")
    print(f"overlays (before/after): {outcome.out_dir / 'overlays'}")
    return 0
