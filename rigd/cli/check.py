"""``rigd check DATASET``: is the calibration still right? ok / drifted / unknown (exit 0 / 1 / 2)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from calib.drift import DriftOptions, DriftStatus
from calib.geometry import Transform
from rigd.calibration.check_job import extrinsics_from_file, extrinsics_from_store, group_lines, run_check
from rigd.cli.args import parse_threshold, print_progress
from rigd.cli.bag_input import DatasetInput, add_bag_options, dataset_input
from rigd.cli.exit_codes import Check
from rigd.dataset import open_dataset
from rigd.errors import RigdError
from rigd.locks import reading
from rigd.results import CheckReport
from rigd.store.jsonsafe import json_safe


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "check",
        help="is an existing calibration still right for new pairs? (exit 0 ok, 1 drifted, 2 unknown)",
        description="Searches the finest levels of the calibration from the given extrinsics on the dataset's "
        "pairs and judges the rotation and the translation change by their length: ok (both within their "
        "thresholds at 95 % confidence), drifted (one moved beyond its threshold, and the change is real at 95 % "
        "confidence) or unknown (the pairs cannot tell; at least 4 places are needed). Exit code 0, 1, 2; an error "
        "exits 65 with a message (docs/reliability.md). See docs/check.md.",
    )
    parser.add_argument("dataset", type=Path, metavar="DATASET", help="a dataset folder, or a bag (below)")
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--against", type=Path, default=None, metavar="FILE",
                        help="extrinsics.yaml (or any YAML with T_camera_lidar) to check; default: the dataset's "
                        "rig.yaml initial_guess")
    source.add_argument("--version", type=int, default=None, metavar="N",
                        help="extrinsics version N of the service's store in --data-dir")
    parser.add_argument("--data-dir", type=Path, default=Path("rigd-data"), help="the service's data directory "
                        "for --version (default rigd-data)")
    parser.add_argument("--threshold", type=str, default=None, metavar="ROT_DEG,TRANS_CM",
                        help="length of a rotation (deg) and of a translation (cm) change that matters "
                        f"(default {DriftOptions().threshold_rot_deg:g},{DriftOptions().threshold_trans_cm:g})")
    parser.add_argument("--json", action="store_true", help="print one JSON object with the result on stdout")
    add_bag_options(parser)
    parser.set_defaults(func=run)


def _checked(args: argparse.Namespace, dataset: DatasetInput) -> Transform:
    if args.against is not None:
        return extrinsics_from_file(args.against)
    if args.version is not None:
        return extrinsics_from_store(args.data_dir, args.version)
    guess = open_dataset(dataset.path).rig.initial_guess
    if guess is None:
        where = f"{args.dataset}: its rig (--rig)" if dataset.bag is not None else str(args.dataset / "rig.yaml")
        raise RigdError(f"{where} has no initial_guess; give the extrinsics to check with --against FILE or "
                        "--version N")
    return guess


def run(args: argparse.Namespace) -> int:
    opts = parse_threshold(args.threshold)
    with dataset_input(args) as dataset, reading(dataset.path):  # no capture into it meanwhile
        outcome = run_check(dataset.path, _checked(args, dataset), opts, print_progress)
    rep = outcome.report
    if args.json:
        print(json.dumps(json_safe(rep)))
    else:
        print("\n".join(report_lines(rep)))
    return Check[DriftStatus(rep["status"]).name]


def report_lines(rep: CheckReport) -> list[str]:
    """The report in words: the change per axis with its sigma, per group its length and bound, the answer."""
    c, s = rep["change"], rep["sigma"]
    lines = [f"change roll, pitch, yaw: {', '.join(f'{v:+.3f}' for v in c['rpy_deg'])} deg "
             f"(sigma {', '.join(f'{v:.3f}' for v in s['rpy_deg'])})",
             f"change x, y, z: {', '.join(f'{v:+.2f}' for v in c['xyz_cm'])} cm "
             f"(sigma {', '.join(f'{v:.2f}' for v in s['xyz_cm'])})"]
    lines += group_lines(rep)
    axes = f" ({', '.join(rep['axes'])})" if rep["axes"] else ""
    lines.append(f"status: {rep['status'].upper()}{axes}; {rep['pairs']} pairs at {rep['places']} places, "
                 f"{rep['wall_time_s']:.1f} s")
    return lines + [f"  - {reason}" for reason in rep["reasons"]]
