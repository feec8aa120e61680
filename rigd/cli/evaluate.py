"""``rigd evaluate PROTOCOL DATASET``: the paper's convergence and precision protocols and drift here, initial and
compare in rigd.cli.evaluate_initial and rigd.cli.evaluate_compare (docs/evaluation.md)."""

from __future__ import annotations

import argparse
from typing import Any

from calib.drift import DriftOptions
from calib.evaluate import Params6, PoseError, StartAxes
from rigd.cli.args import (
    add_evaluation_options,
    add_method_option,
    add_start_axes_option,
    evaluation_settings,
    non_negative_float,
    numbers,
    parse_threshold,
    positive_int,
)
from rigd.cli.evaluate_compare import register_compare
from rigd.cli.evaluate_initial import register_initial
from rigd.errors import RigdError
from rigd.evaluate.drift import DriftRequest, run_drift
from rigd.evaluate.protocols import (
    ConvergenceRequest,
    EvaluationOutcome,
    PrecisionRequest,
    Source,
    run_convergence,
    run_precision,
)


def _where(settings: dict[str, Any]) -> str:
    cluster = settings.get("cluster")
    return f"workers: {settings['workers']}" + (f" of the cluster at {cluster}" if cluster else "")


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "evaluate",
        help="convergence and precision statistics of the calibration on a dataset",
        description="Run many calibrations in parallel and summarise them (Kang & Doh 2020, 8.5 and 8.2.2). "
        "Writes OUT/<protocol>.yaml with every number and OUT/<protocol>.png.",
    )
    protocols = parser.add_subparsers(dest="protocol", metavar="PROTOCOL", required=True)
    conv = protocols.add_parser(
        "convergence", help="random starts around the reference (paper Fig. 19)",
        description="Calibrate with all pairs from TRIALS starts drawn uniformly within +-ROT_DEG on each of "
        "roll/pitch/yaw and +-TRANS_M on each of x/y/z around the reference: the ground truth when the dataset "
        "has one, else a first calibration from --init / rig.yaml's initial_guess.")
    add_evaluation_options(conv)
    add_method_option(conv)
    conv.add_argument("--trials", type=positive_int, default=200, help="number of starts (default 200)")
    conv.add_argument("--rot-deg", type=non_negative_float, default=5.0, help="start range in degrees (default 5)")
    conv.add_argument("--trans-m", type=non_negative_float, default=0.1, help="start range in metres (default 0.1)")
    add_start_axes_option(conv)
    conv.set_defaults(func=run)
    prec = protocols.add_parser(
        "precision", help="random subsets of pairs from one start (paper Table 1, Fig. 11)",
        description="Calibrate SUBSETS random subsets of SIZE pairs, all from one start (--init, else rig.yaml's "
        "initial_guess, else the ground truth), and report the per-parameter standard deviation.")
    add_evaluation_options(prec)
    add_method_option(prec)
    prec.add_argument("--subsets", type=positive_int, default=100, help="number of subsets (default 100)")
    prec.add_argument("--size", type=positive_int, default=12, help="pairs per subset (default 12)")
    prec.set_defaults(func=run)
    drift = protocols.add_parser(
        "drift", help="how well rigd check tells drift from none (detection and false-alarm rates)",
        description="Injects known errors into the ground truth (none, rotations of --rot-deg, translations of "
        "--trans-cm, random directions), runs rigd check from each and counts ok / drifted / unknown. "
        "Writes OUT/drift.yaml.")
    add_evaluation_options(drift)
    drift.add_argument("--trials", type=positive_int, default=120, help="number of trials (default 120)")
    drift.add_argument("--rot-deg", type=str, default="0.3,0.5,1", help="injected rotations, deg (default 0.3,0.5,1)")
    drift.add_argument("--trans-cm", type=str, default="2,5", help="injected translations, cm (default 2,5)")
    drift.add_argument("--threshold", type=str, default=None, metavar="ROT_DEG,TRANS_CM",
                       help="rigd check's thresholds (default its own, "
                       f"{DriftOptions().threshold_rot_deg:g},{DriftOptions().threshold_trans_cm:g})")
    drift.add_argument("--size", type=positive_int, default=None, metavar="N",
                       help="each trial checks N pairs drawn at random (default all pairs: then every trial "
                       "without an injected error is the same check)")
    drift.set_defaults(func=run_drift_command)
    register_initial(protocols)
    register_compare(protocols)


def _fmt_params(p: Params6 | None, digits: int) -> str:
    if p is None:
        return "n/a (fewer than 2 runs)"
    return (f"roll {p.roll_deg:.{digits}f} pitch {p.pitch_deg:.{digits}f} yaw {p.yaw_deg:.{digits}f} deg, "
            f"x {p.x_m * 100:.{digits - 1}f} y {p.y_m * 100:.{digits - 1}f} z {p.z_m * 100:.{digits - 1}f} cm")


def _fmt_error(e: PoseError) -> str:
    return (f"{e.rotation_deg:.3f} deg, {e.translation_cm:.2f} cm (roll {e.roll_deg:+.3f} pitch {e.pitch_deg:+.3f} "
            f"yaw {e.yaw_deg:+.3f} deg; x {e.x_cm:+.2f} y {e.y_cm:+.2f} z {e.z_cm:+.2f} cm)")


def _fmt_sigma(values: list[float]) -> str:
    return f"{', '.join(f'{v:.2f}' for v in values[:3])} deg; {', '.join(f'{v:.1f}' for v in values[3:])} cm"


def summary_lines(outcome: EvaluationOutcome) -> list[str]:
    """The human summary printed after a run (every number is also in the YAML report)."""
    stats, report = outcome.stats, outcome.report
    s = report["settings"]
    if report["protocol"] == "convergence":
        axes = "roll/pitch/yaw" if s["start_axes"] == StartAxes.RPY.value else "the LiDAR's x/y/z"
        what = (f"{s['trials']} starts within +-{s['rot_deg']} deg (about {axes}) / +-{s['trans_m'] * 100:g} cm "
                f"of the {outcome.reference_source.label}")
    else:
        what = f"{s['subsets']} random subsets of size {s['size']}, started at the {Source(s['start']).label}"
    times = report["summary"]["calibration_time_s"]
    lines = [
        f"{report['protocol']} on {report['dataset']} ({report['pairs_in_dataset']} pairs): {what}, "
        f"{_where(s)}, seed {s['seed']}" + (", with rig.yaml's prior" if "prior" in s else ""),
        f"converged: {stats.converged_count}/{stats.runs} ({stats.converged_percent:.1f} %), "
        f"{stats.runs - stats.finished} failed to run; rule {stats.rule.value} "
        f"({stats.rot_tol_deg} deg / {stats.trans_tol_m * 100:g} cm from the median)",
        f"std of converged runs: {_fmt_params(stats.std_converged, 4)}",
        f"std of all finished runs: {_fmt_params(stats.std, 4)}",
    ]
    usable = report["summary"].get("std_not_failed")
    if usable is not None:
        lines.append(f"std of the runs not failed (trusted or weak): {_fmt_params(Params6(**usable), 4)}")
    err = report["summary"].get("error_vs_ground_truth")
    if err is not None and stats.solution_error is not None and stats.run_error_median is not None:
        med = stats.run_error_median
        lines.append(f"converged solution vs ground truth: {_fmt_error(stats.solution_error)}")
        lines.append(f"median error of converged runs: {med.rotation_deg:.3f} deg, {med.translation_cm:.2f} cm")
    vs_ref = report["summary"].get("vs_reference")
    if vs_ref is not None and vs_ref.get("runs"):
        z = "" if vs_ref["median_z"] is None else "; median difference in its sigmas: " + ", ".join(
            f"{k} {v:+.2f}" for k, v in vs_ref["median_z"].items())
        lines.append(f"vs the published reference: {vs_ref['within']}/{vs_ref['runs']} runs {vs_ref['rule']}; median "
                     f"{vs_ref['median_rotation_deg']:.3f} deg, {vs_ref['median_translation_cm']:.2f} cm{z}")
    check = report["summary"].get("uncertainty_check")
    if check is not None:
        axes = ", ".join(f"{k} {v * 100:.0f} %" for k, v in check["within_3_sigma_per_axis"].items())
        ref_sigma = check.get("reference_sigma_deg_cm")
        if ref_sigma is None:
            lines.append(f"uncertainty check vs the {check['against'].replace('_', ' ')}: truth within 3 sigma on "
                         f"{check['within_3_sigma'] * 100:.1f} % of axes (target 95 %; {axes})")
            lines.append(f"verdicts: {check['verdicts']}; trusted but beyond the tolerance: "
                         f"{check['trusted_but_wrong']}")
        else:
            lines.append(f"uncertainty check vs the published reference, with its own sigmas ({_fmt_sigma(ref_sigma)}):"
                         f" within 3 of both sigmas on {check['within_3_sigma'] * 100:.1f} % of axes ({axes})")
            lines.append(f"verdicts: {check['verdicts']}; trusted but beyond the tolerance plus 2.5 of the "
                         f"reference's sigmas: {check['trusted_but_wrong']}")
    lines.append(f"time: {report['wall_time_s']:.0f} s wall; per calibration median {times['median']:.1f} s, "
                 f"max {times['max']:.1f} s")
    lines.append(f"written: {outcome.yaml_path}, {outcome.plot_path}")
    return lines


def run_drift_command(args: argparse.Namespace) -> int:
    settings = evaluation_settings(args)
    if args.tolerance is not None:
        raise RigdError("rigd evaluate drift: give rigd check's thresholds with --threshold (no verdicts here)")
    opts = parse_threshold(args.threshold)
    rot = numbers(args.rot_deg, "--rot-deg", len(args.rot_deg.split(",")))
    trans = numbers(args.trans_cm, "--trans-cm", len(args.trans_cm.split(",")))
    request = DriftRequest(settings, args.trials, tuple(rot), tuple(trans), opts, args.size)
    outcome = run_drift(request)
    rep = outcome.report
    size = "all" if args.size is None else f"{args.size} random"
    print(f"drift on {rep['dataset']} ({rep['pairs']} pairs, {size} per trial): {rep['settings']['trials']} trials, "
          f"thresholds {opts.threshold_rot_deg:g} deg / {opts.threshold_trans_cm:g} cm; {_where(rep['settings'])}")
    for label, row in rep["summary"].items():
        print(f"  {label:>14}: ok {row['ok']}/{row['trials']} ({row['ok_share'] * 100:.0f} %), drifted "
              f"{row['drifted']} ({row['drifted_share'] * 100:.0f} %), unknown {row['unknown']}, error "
              f"{row['error']}; median " + ("n/a" if row["median_time_s"] is None else f"{row['median_time_s']:.1f} s"))
    print(f"ok at zero error: {rep['ok_rate_at_zero_error'] * 100:.1f} %; false alarms (drifted at zero error): "
          f"{rep['false_alarm_rate'] * 100:.1f} %; {rep['wall_time_s']:.0f} s wall")
    print(f"written: {outcome.yaml_path}")
    return 0


def run(args: argparse.Namespace) -> int:
    settings = evaluation_settings(args)
    if args.protocol == "convergence":
        outcome = run_convergence(ConvergenceRequest(settings, args.trials, args.rot_deg, args.trans_m,
                                                     StartAxes(args.start_axes)))
    else:
        outcome = run_precision(PrecisionRequest(settings, args.subsets, args.size))
    print("\n".join(summary_lines(outcome)))
    return 0
