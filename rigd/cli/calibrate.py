"""``rigd calibrate DATASET``: estimate T_camera_lidar; the field engineer's options in ``--help``, the expert's in
``--help-expert``. The options become one :class:`CalibrationRequest`, as the service's body does."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from calib.assess import Status
from calib.methods import FIELD_METHODS, Method
from rigd.calibration import CalibrationRequest, Options, Start, run_calibration
from rigd.calibration.advice import Action
from rigd.calibration.request import PriorIn, ToleranceIn, TransformIn
from rigd.cli.args import ExpertHelp, expert, numbers, parse_init, print_progress, validated
from rigd.cli.bag_input import DatasetInput, add_bag_options, dataset_input
from rigd.cli.exit_codes import Calibrate
from rigd.dataset.working import WORKING_WIDTH_PX
from rigd.locks import reading
from rigd.outdir import claim_output_dir
from rigd.report import (
    CalibrationReport,
    ElevationOffset,
    InitialSearch,
    NextStep,
    ReferenceAgreement,
    Uncertainty,
    Verdict,
)


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "calibrate",
        help="estimate T_camera_lidar from a dataset",
        description="Targetless calibration (Kang & Doh 2020): aligns image edges and LiDAR edges with a "
        "Gaussian mixture model, coarse to fine. Writes OUT/extrinsics.yaml, overlays/ (the LiDAR edge "
        "points over each image before and after, coloured by range, and a close-up of where they moved most) and "
        "clouds/ (coloured PLY per pair). --help-expert lists the options for research and tuning.",
    )
    parser.add_argument("dataset", type=Path, metavar="DATASET", help="a dataset folder, or a bag (below)")
    start = parser.add_mutually_exclusive_group()
    start.add_argument("--init", type=str, default=None, metavar="ROLL,PITCH,YAW,X,Y,Z",
                       help="initial guess in deg and m (default: rig.yaml initial_guess; without one rigd "
                       "searches globally)")
    start.add_argument("--search", action="store_true",
                       help="search globally for the initial guess even if rig.yaml has one (after a reassembly): "
                       "any yaw, roll and pitch within rig.yaml search.tilt_deg (default 30), the lever arm from "
                       "the prior or zero")
    parser.add_argument("--method", choices=[m.value for m in FIELD_METHODS], default=None,
                        help="gmm: the GMM edge alignment; nid-assessed: NID (image against LiDAR reflectivity) with "
                        "the same assessment. Default: nid-assessed on a single pinhole camera given a start, clouds "
                        "with intensity and no Gaussian prior, else gmm; the report says which and why "
                        "(research methods: rigd evaluate)")
    parser.add_argument("--lever-arm-m", type=str, default=None, metavar="X,Y,Z",
                        help="the lever arm from the rig's drawing: t of T_camera_lidar, in METRES (default: rig.yaml "
                        "prior)")
    parser.add_argument("--lever-arm-sigma-cm", type=float, default=1.0, metavar="CM",
                        help="how well the drawing knows the lever arm, in cm per axis (default 1)")
    parser.add_argument("--fix", choices=["translation"], default=None,
                        help="hold the translation at the lever arm (or the initial guess's)")
    parser.add_argument("--tolerance", type=str, default=None, metavar="ROT_DEG,TRANS_CM",
                        help="field tolerance of the verdict in deg and cm (default: rig.yaml tolerance, else 0.2,2)")
    parser.add_argument("--tolerance-per-axis", type=str, default=None, metavar="R,P,Y,X,Y,Z",
                        help="each axis's own tolerance: roll, pitch, yaw in deg, x, y, z in cm (default: "
                        "--tolerance's on every axis)")
    parser.add_argument("--fit-elevation-offset", action="store_true",
                        help="also fit the LiDAR's common elevation offset, for cameras that look all round: a "
                        "panorama or a head; about 1.5 times the time (docs/method.md item 18)")
    parser.add_argument("--out", type=Path, default=None, help="output directory (default DATASET/calibration; for a "
                        "bag BAG_calibration beside it, or DIR/calibration with --keep-dataset DIR)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace what --out holds (default: refused unless it is empty or this command's own "
                        "DATASET/calibration)")
    parser.add_argument("--json", action="store_true", help="print one JSON object with the result on stdout")
    parser.add_argument("--no-visuals", action="store_true", help="skip overlays and PLY clouds")
    add_bag_options(parser)
    _expert_options(parser)
    parser.set_defaults(func=run)


def _expert_options(parser: argparse.ArgumentParser) -> None:
    """Options for research and tuning, listed by --help-expert only."""
    parser.add_argument("--help-expert", action=ExpertHelp, help="list the expert options too, and exit")
    expert(parser, "--rotation-prior-deg", type=str, default=None, metavar="ROLL,PITCH,YAW,SIGMA",
           help="Gaussian prior on the rotation and its sigma, all in deg")
    expert(parser, "--sigmas-deg", type=str, default=None, metavar="S1,S2,...",
           help="the GMM's sigma_in per coarse-to-fine level, deg at 1 m (default: the method's schedule)")
    expert(parser, "--workers", type=_bounded("--workers", 1, 64), default=2, metavar="N",
           help="processes for the pairs' edges and the independent solves (default 2; 1: all in this process, "
           "the least memory; docs/performance.md)")
    expert(parser, "--max-width", type=_bounded("--max-width", 0, 1 << 20), default=WORKING_WIDTH_PX, metavar="PX",
           help=f"working resolution: wider images are halved until at most PX wide (default {WORKING_WIDTH_PX}; "
           "0: full resolution, slower and no more accurate; docs/performance.md)")


def _bounded(option: str, low: int, high: int) -> Any:
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option} needs a whole number, got {text!r}") from None
        if not low <= n <= high:
            raise argparse.ArgumentTypeError(f"{option} must be {low} to {high}, got {n}")
        return n
    return parse


def options_of(args: argparse.Namespace) -> Options:
    """The :class:`Options` the command line asks for, validated as the service validates its body."""
    prior: dict[str, Any] = {}
    if args.lever_arm_m is not None:
        prior |= {"xyz_m": numbers(args.lever_arm_m, "--lever-arm-m", 3), "sigma_cm": args.lever_arm_sigma_cm}
    if args.rotation_prior_deg is not None:
        values = numbers(args.rotation_prior_deg, "--rotation-prior-deg", 4)
        prior |= {"rpy_deg": values[:3], "sigma_deg": values[3]}
    tolerance = None
    given: dict[str, Any] = {}
    if args.tolerance is not None:
        rot, trans = numbers(args.tolerance, "--tolerance", 2)
        given |= {"rotation_deg": rot, "translation_cm": trans}
    if args.tolerance_per_axis is not None:
        axes = numbers(args.tolerance_per_axis, "--tolerance-per-axis", 6)
        given |= {"rpy_deg": axes[:3], "xyz_cm": axes[3:]}
    if given:
        tolerance = validated(ToleranceIn, "--tolerance / --tolerance-per-axis", **given)
    return validated(
        Options, "rigd calibrate",
        method=Method(args.method) if args.method else None,
        prior=validated(PriorIn, "--lever-arm-m / --rotation-prior-deg", **prior) if prior else None,
        fix_translation=args.fix == "translation",
        tolerance=tolerance,
        fit_elevation_offset=args.fit_elevation_offset,
        sigmas_deg=numbers(args.sigmas_deg, "--sigmas-deg", None) if args.sigmas_deg else None)


def request_of(args: argparse.Namespace, data: DatasetInput) -> CalibrationRequest:
    initial: TransformIn | None = parse_init(args.init) if args.init else None
    start = Start.SEARCH if args.search else Start.GIVEN if initial is not None else Start.RIG
    return validated(CalibrationRequest, "rigd calibrate", dataset=data.path, start=start, initial=initial,
                     options=options_of(args), out_dir=args.out or data.default_out("calibration"),
                     write_visuals=not args.no_visuals, workers=args.workers, max_width=args.max_width or None)


def _on_iter(level: int, iteration: int, cost: float) -> None:
    print(f"  level {level + 1} iteration {iteration:3d} cost {cost:.6f}", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    with dataset_input(args) as data:
        target = args.out or data.default_out("calibration")
        request = request_of(args, data)
        # Written beside, then put in place whole: no overlays of an earlier run stay beside this one's; the default
        # folder is this command's own, a folder named with --out is replaced only with --overwrite.
        with reading(data.path), claim_output_dir(target, inputs=[data.path / "rig.yaml", data.path / "pairs"],
                                                  overwrite=args.overwrite or args.out is None) as out_dir:
            outcome = run_calibration(request.model_copy(update={"out_dir": out_dir}), print_progress, _on_iter)
            data.record_bag(out_dir)
    report = outcome.report
    if args.json:
        print(json.dumps(report))
    else:
        print_report(report, target / "extrinsics.yaml")
    return Calibrate[Status(report["verdict"]["status"]).name]


def print_report(report: CalibrationReport, written: Path) -> None:
    T = report["T_camera_lidar"]
    print(f"T_camera_lidar rpy_deg {np.round(T['rpy_deg'], 3).tolist()} xyz_m {np.round(T['xyz_m'], 4).tolist()}")
    print(f"written: {written}")
    method = report["method"]
    print(f"method: {method['name']} ({method.get('why', 'asked for')})")
    if "start" in report:
        print(f"start: {report['start']['choice']} ({report['start']['why']})")
    if "places" in report:
        pairs, places = len(report["places"]["of_pairs"]), report["places"]["count"]
        print(f"pairs: {pairs} at {places} place{'s' if places != 1 else ''} (pairs at one place count once)")
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
    fixed = f"; {', '.join(v['fixed_axes'])} held as given, not checked" if v.get("fixed_axes") else ""
    print(f"verdict: {v['status'].upper()}{axes}{fixed}")
    for reason in v["reasons"]:
        print(f"  - {reason}")
    if v.get("next_steps"):
        print("what to do:")
        for step in v.get("next_steps", []):
            print(f"  - {step_words(step)}")


# How rigd calibrate and rig.yaml do what an advice step asks (rigd.calibration.advice.Action; the page has buttons).
HOW = {
    Action.LEVER_ARM.value: "--lever-arm-m X,Y,Z --lever-arm-sigma-cm 1, or rig.yaml prior: {xyz_m: [x, y, z], "
                            "sigma_cm: 1.0} (metres, sigma in cm)",
    Action.FIX_TRANSLATION.value: "--fix translation",
    Action.SEARCH.value: "--search",
    Action.CLOSER_START.value: "--init ROLL,PITCH,YAW,X,Y,Z",
    Action.FIT_ELEVATION.value: "--fit-elevation-offset there, then rig.yaml lidar: {elevation_offset_deg: ..., "
                                "elevation_offset_sigma_deg: ...}",
}


def step_words(step: NextStep | str) -> str:
    """A step with how to do it here; a report stored before steps were records holds its words alone."""
    if isinstance(step, str):
        return step
    how = [HOW[a] for a in step["actions"] if a in HOW]
    if Action.CAPTURE.value in step["actions"] and step["pairs"]:
        how.append(f"rigd capture --n {step['pairs']}")
    return step["text"] + (f" ({'; '.join(how)})" if how else "")
