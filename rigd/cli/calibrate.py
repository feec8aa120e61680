"""``rigd calibrate DATASET``: estimate T_camera_lidar with the GMM edge alignment."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from calib.assess import Status
from calib.methods import Method
from rigd.calibration import CalibrationRequest, run_calibration
from rigd.calibration.service import DEFAULT_SIGMAS_DEG, PAPER_SIGMAS_DEG
from rigd.cli.args import parse_init, parse_prior, parse_sigmas, parse_tolerance
from rigd.cli.bag_input import DatasetInput, add_bag_options, dataset_input
from rigd.cli.exit_codes import Calibrate
from rigd.dataset.working import WORKING_WIDTH_PX
from rigd.report import ElevationOffset, InitialSearch, ReferenceAgreement, Uncertainty, Verdict


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "calibrate",
        help="estimate T_camera_lidar from a dataset",
        description="Targetless calibration (Kang & Doh 2020): aligns image edges and LiDAR edges with a "
        "Gaussian mixture model, coarse to fine. Writes OUT/extrinsics.yaml, overlays/ (the LiDAR edge "
        "points over each image before and after, coloured by range, and a close-up of where they moved most) and "
        "clouds/ (coloured PLY per pair).",
    )
    parser.add_argument("dataset", type=Path, metavar="DATASET", help="a dataset folder, or a bag (below)")
    start = parser.add_mutually_exclusive_group()
    start.add_argument("--init", type=str, default=None,
                       help="initial guess 'roll,pitch,yaw,x,y,z' in deg and m (default: rig.yaml initial_guess; "
                       "without one rigd searches globally)")
    start.add_argument("--search", action="store_true",
                       help="search globally for the initial guess even if rig.yaml has one (after a reassembly): "
                       "any yaw, roll and pitch within rig.yaml search.tilt_deg (default 30), the lever arm from "
                       "the prior or zero")
    parser.add_argument("--sigmas", type=str, default=None,
                        help="sigma_in per coarse-to-fine level, degrees at 1 m (default: "
                        f"{','.join(map(str, DEFAULT_SIGMAS_DEG))}; with --method paper the paper's 15,10,5 px of a "
                        f"1024-wide panorama = {','.join(map(str, PAPER_SIGMAS_DEG))})")
    parser.add_argument("--method", choices=[m.value for m in Method], default=None,
                        help="rigd: the paper's GMM with the changes in docs/method.md, the default; nid-assessed: NID "
                        "with restarts, per-axis sigma and verdict, the default on a single pinhole camera given a "
                        "start, clouds with intensity and no Gaussian prior (docs/baselines.md); paper: the paper's "
                        "settings as printed; mi, nid, gom: the photometric baselines (LiDAR reflectivity against the "
                        "image; no trust assessment, exit code 5); rigd+nid: rigd, then NID from its solution; gmm-*: "
                        "the ablations (docs/results.md)")
    parser.add_argument("--out", type=Path, default=None, help="output directory (default DATASET/calibration; for a "
                        "bag BAG_calibration beside it, or DIR/calibration with --keep-dataset DIR)")
    parser.add_argument("--json", action="store_true", help="print one JSON object with the result on stdout")
    parser.add_argument("--no-visuals", action="store_true", help="skip overlays and PLY clouds")
    parser.add_argument("--workers", type=_workers, default=2, metavar="N",
                        help="processes for the pairs' edges and the independent solves (default 2; 1: all in "
                        "this process, the least memory; docs/performance.md)")
    parser.add_argument("--prior", type=str, default=None, metavar="X,Y,Z,SIGMA_CM",
                        help="Gaussian prior on the lever arm (t of T_camera_lidar, m) with its sigma in cm, e.g. "
                        "from the rig's drawing (default: rig.yaml prior)")
    parser.add_argument("--prior-rotation", type=str, default=None, metavar="ROLL,PITCH,YAW,SIGMA_DEG",
                        help="Gaussian prior on the rotation (deg) with its sigma in deg")
    parser.add_argument("--fix", choices=["translation"], default=None,
                        help="hold the translation at the prior's lever arm (or the initial guess's)")
    parser.add_argument("--fit-elevation-offset", action="store_true",
                        help="also fit the LiDAR's common elevation offset (or the cameras' common principal-point "
                        "error along the vertical), for cameras that look all round: a panorama or a head; about "
                        "1.5 times the time (docs/method.md item 18)")
    parser.add_argument("--tolerance", type=str, default=None, metavar="ROT_DEG,TRANS_CM",
                        help="field tolerance of the verdict (default: rig.yaml tolerance, else 0.2,2)")
    parser.add_argument("--max-width", type=_max_width, default=WORKING_WIDTH_PX, metavar="PX",
                        help=f"working resolution: wider images are halved until at most PX wide (default "
                        f"{WORKING_WIDTH_PX}; 0: full resolution, slower and no more accurate; docs/performance.md)")
    add_bag_options(parser)
    parser.set_defaults(func=run)


def _progress(stage: str, fraction: float) -> None:
    print(f"[{fraction * 100:5.1f} %] {stage}", file=sys.stderr, flush=True)


def _workers(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--workers needs a whole number, got {text!r}") from None
    if not 1 <= n <= 64:
        raise argparse.ArgumentTypeError(f"--workers must be 1 to 64, got {n}")
    return n


def _max_width(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--max-width needs a whole number of pixels, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"--max-width must be 0 (full resolution) or positive, got {n}")
    return n


def _on_iter(level: int, iteration: int, cost: float) -> None:
    print(f"  level {level + 1} iteration {iteration:3d} cost {cost:.6f}", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    with dataset_input(args) as data:
        return _calibrate(args, data)


def _calibrate(args: argparse.Namespace, data: DatasetInput) -> int:
    request = CalibrationRequest(
        dataset=data.path,
        out_dir=args.out or data.default_out("calibration"),
        initial=parse_init(args.init) if args.init else None,
        sigmas_deg=parse_sigmas(args.sigmas) if args.sigmas else None,
        method=Method(args.method) if args.method else None,
        write_visuals=not args.no_visuals,
        prior=parse_prior(args.prior, args.prior_rotation),
        fix_translation=args.fix == "translation",
        tolerance=parse_tolerance(args.tolerance) if args.tolerance else None,
        search=args.search,
        workers=args.workers,
        max_width=args.max_width or None,
        fit_elevation=args.fit_elevation_offset,
    )
    outcome = run_calibration(request, _progress, _on_iter)
    data.record_bag(outcome.out_dir)
    report = outcome.report
    if args.json:
        print(json.dumps(report))
    else:
        T = outcome.T_camera_lidar
        print(f"T_camera_lidar rpy_deg {np.round(T.rpy_deg, 3).tolist()} xyz_m {np.round(T.translation_m, 4).tolist()}")
        print(f"written: {outcome.out_dir / 'extrinsics.yaml'}")
        if "initial_search" in report:
            print_search(report["initial_search"])
        if "lidar_elevation_offset" in report:
            print_elevation(report["lidar_elevation_offset"])
        print_trust(report["uncertainty"], report["verdict"])
        if "error_vs_ground_truth" in report:
            err = report["error_vs_ground_truth"]
            print(f"error vs ground truth: {err['rotation_deg']:.3f} deg, {err['translation_cm']:.2f} cm")
        if "agreement_with_reference" in report:
            print_reference(report["agreement_with_reference"])
    return Calibrate[Status(report["verdict"]["status"]).name]


def _fmt(values: list[float | None]) -> str:
    return ", ".join("unknown" if v is None else (">1000" if v > 1e3 else f"{v:.3g}") for v in values)


def print_elevation(fit: ElevationOffset) -> None:
    bound = " (at the end of the searched range: check the LiDAR's calibration)" if fit["at_bound"] else ""
    print(f"LiDAR elevation offset: {fit['offset_deg']:+.3f} deg (sigma {fit['sigma_deg']:.3f} deg){bound}; the "
          "LiDAR's points raised by it fit the images best. Where the rings are too sparse to fit it, declare it: "
          f"rig.yaml lidar: {{elevation_offset_deg: {fit['offset_deg']:.3f}, elevation_offset_sigma_deg: "
          f"{fit['sigma_deg']:.3f}}}")


def print_search(section: InitialSearch) -> None:
    start = section["start"]
    scores = " and ".join(section["grid"]["scores"])
    print(f"initial guess by global search ({section['grid']['mounts']} mounts scored by {scores}, "
          f"{section['wall_time_s']:.0f} s): start rpy_deg {np.round(start['rpy_deg'], 1).tolist()} from grid "
          f"mount {start['grid_rpy_deg']}")
    for c in section["candidates"][1:]:
        print(f"  runner-up by {c['score']}: {c['from_start_deg']:.1f} deg away, cost {_cost(c['cost'])}")


def _cost(value: float | None) -> str:
    return "unknown" if value is None else f"{value:.4f}"


def print_reference(ref: ReferenceAgreement) -> None:
    z = ", ".join(f"{k} {v:+.2f}" for k, v in ref["z_per_axis"].items() if v is not None)
    print(f"vs the published reference (reference.yaml): {ref['rotation_deg']:.3f} deg, "
          f"{ref['translation_cm']:.2f} cm" + (f"; per axis in its sigmas: {z}" if z else ""))


def print_trust(u: Uncertainty, v: Verdict) -> None:
    # About the LiDAR's own axes (docs/conventions.md): at a pinhole's gimbal lock not the Euler angles' own.
    print(f"sigma about the LiDAR's x, y, z (roll, pitch, yaw): {_fmt(u['rpy_deg'])} deg; "
          f"x, y, z: {_fmt(u['xyz_cm'])} cm")
    print(f"weakest: {u['weakest']}")
    axes = f" ({', '.join(v['weak_axes'])})" if v["weak_axes"] else ""
    print(f"verdict: {v['status'].upper()}{axes}")
    for reason in v["reasons"]:
        print(f"  - {reason}")
    if v.get("next_steps"):
        print("what to do:")
        for step in v.get("next_steps", []):
            print(f"  - {step}")
