"""``rigd check DATASET``: is the calibration still right? ok / drifted / unknown (exit 0 / 1 / 2)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from calib.check import DriftOptions, DriftStatus
from calib.geometry import Transform
from rigd.calibration.check import extrinsics_from_file, extrinsics_from_store, run_check
from rigd.cli.args import parse_tolerance
from rigd.cli.exit_codes import Check
from rigd.dataset import open_dataset
from rigd.errors import RigdError


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "check",
        help="is an existing calibration still right for new pairs? (exit 0 ok, 1 drifted, 2 unknown or error)",
        description="Searches the finest levels of the calibration from the given extrinsics on the dataset's "
        "pairs and reports the per-axis change with its uncertainty: ok (every axis known to be within its "
        "threshold), drifted (an axis moved beyond its threshold by more than 3 sigma) or unknown (the pairs "
        "cannot tell). Exit code 0, 1, 2 (2 is also any error, with a message). See docs/check.md.",
    )
    parser.add_argument("dataset", type=Path, metavar="DATASET")
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--against", type=Path, default=None, metavar="FILE",
                        help="extrinsics.yaml (or any YAML with T_camera_lidar) to check; default: the dataset's "
                        "rig.yaml initial_guess")
    source.add_argument("--version", type=int, default=None, metavar="N",
                        help="extrinsics version N of the service's store in --data-dir")
    parser.add_argument("--data-dir", type=Path, default=Path("rigd-data"), help="the service's data directory "
                        "for --version (default rigd-data)")
    parser.add_argument("--threshold", type=str, default=None, metavar="ROT_DEG,TRANS_CM",
                        help="change that matters per axis (default 0.2,2)")
    parser.add_argument("--json", action="store_true", help="print one JSON object with the result on stdout")
    parser.set_defaults(func=run)


def _checked(args: argparse.Namespace) -> Transform:
    if args.against is not None:
        return extrinsics_from_file(args.against)
    if args.version is not None:
        return extrinsics_from_store(args.data_dir, args.version)
    guess = open_dataset(args.dataset).rig.initial_guess
    if guess is None:
        raise RigdError(f"{args.dataset / 'rig.yaml'}: no initial_guess; give the extrinsics to check with "
                        "--against FILE or --version N")
    return guess


def _options(text: str | None) -> DriftOptions:
    if text is None:
        return DriftOptions()
    tol = parse_tolerance(text, "--threshold")
    return DriftOptions(threshold_rot_deg=tol.tolerance_rot_deg, threshold_trans_cm=tol.tolerance_trans_cm)


def run(args: argparse.Namespace) -> int:
    opts = _options(args.threshold)
    outcome = run_check(args.dataset, _checked(args), opts,
                        lambda stage, f: print(f"[{f * 100:5.1f} %] {stage}", file=sys.stderr, flush=True))
    rep = outcome.report
    if args.json:
        print(json.dumps(rep))
    else:
        c, s = rep["change"], rep["sigma"]
        print(f"change roll, pitch, yaw: {', '.join(f'{v:+.3f}' for v in c['rpy_deg'])} deg "
              f"(sigma {', '.join(f'{v:.3f}' for v in s['rpy_deg'])})")
        print(f"change x, y, z: {', '.join(f'{v:+.2f}' for v in c['xyz_cm'])} cm "
              f"(sigma {', '.join(f'{v:.2f}' for v in s['xyz_cm'])})")
        axes = f" ({', '.join(rep['axes'])})" if rep["axes"] else ""
        print(f"status: {rep['status'].upper()}{axes}; {rep['pairs']} pairs, {rep['wall_time_s']:.1f} s")
        for reason in rep["reasons"]:
            print(f"  - {reason}")
    return Check[DriftStatus(rep["status"]).name]
