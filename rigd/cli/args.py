"""What more than one command reads from its arguments: the value types argparse checks, the texts of
``--init``, ``--sigmas``, ``--prior``, ``--tolerance`` and ``--threshold``, and the options every protocol of
``rigd evaluate`` takes. A command's own options stay in its module."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm import tqdm

from calib.assess import TrustOptions
from calib.errors import CalibError
from calib.evaluate import OutlierRule, StartAxes
from calib.geometry import Transform, rpy_deg_to_matrix
from calib.methods import Method
from calib.prior import Prior
from rigd.dataset.records import lever_arm_problem
from rigd.errors import RigdError
from rigd.evaluate.trials import EvaluationSettings

# Value types for argparse's ``type=``: a refused value is argparse's usage error (exit 2), naming the option.


def positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def non_negative_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return value


def non_negative_float(text: str) -> float:
    value = float(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def positive_float(text: str) -> float:
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def progress_bar(desc: str, unit: str) -> tuple[tqdm, Callable[[int, int], None]]:
    """A progress bar (use as a context manager) and the ``progress(done, total)`` callback that moves it."""
    bar = tqdm(desc=desc, unit=unit)

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    return bar, progress


# Texts read after parsing: a refused one is a RigdError (rigd: error: ..., exit 2).


def numbers(text: str, option: str, count: int) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as exc:
        raise RigdError(f"{option} must be {count} comma-separated numbers, got {text!r}") from exc
    if len(values) != count or not np.all(np.isfinite(values)):
        raise RigdError(f"{option} must be {count} finite comma-separated numbers, got {text!r}")
    return values


def parse_init(text: str) -> Transform:
    """'roll,pitch,yaw,x,y,z' (degrees, metres) -> Transform."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as exc:
        raise RigdError(f"--init must be 6 comma-separated numbers 'r,p,y,x,y,z', got {text!r}") from exc
    if len(values) != 6 or not np.all(np.isfinite(values)):
        raise RigdError(f"--init must be 6 finite numbers 'r,p,y,x,y,z' (deg, m), got {text!r}")
    return Transform.from_rpy_xyz(np.array(values[:3]), np.array(values[3:]))


def parse_sigmas(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError as exc:
        raise RigdError(f"--sigmas must be comma-separated numbers, got {text!r}") from exc


def parse_prior(xyz_text: str | None, rotation_text: str | None) -> Prior | None:
    """--prior 'x,y,z,sigma_cm' and --prior-rotation 'roll,pitch,yaw,sigma_deg' -> Prior (or None)."""
    if xyz_text is None and rotation_text is None:
        return None
    xyz = sigma_t = rotation = sigma_r = None
    if xyz_text is not None:
        v = numbers(xyz_text, "--prior", 4)
        if (problem := lever_arm_problem(v[:3])) is not None:
            raise RigdError(f"--prior X,Y,Z,SIGMA_CM: {problem}")
        xyz, sigma_t = np.array(v[:3]), np.full(3, v[3] / 100.0)
    if rotation_text is not None:
        v = numbers(rotation_text, "--prior-rotation", 4)
        rotation, sigma_r = rpy_deg_to_matrix(np.array(v[:3])), np.full(3, np.radians(v[3]))
    try:
        return Prior(xyz, sigma_t, rotation, sigma_r)
    except CalibError as exc:
        raise RigdError(str(exc)) from exc


def parse_tolerance(text: str, option: str = "--tolerance") -> TrustOptions:
    """'rotation_deg,translation_cm' -> the verdict's tolerance (positive numbers)."""
    rot, trans = numbers(text, option, 2)
    if rot <= 0 or trans <= 0:
        raise RigdError(f"{option} must be positive 'rotation_deg,translation_cm', got {text!r}")
    return TrustOptions(tolerance_rot_deg=rot, tolerance_trans_cm=trans)


# The options of rigd evaluate convergence, precision, drift and initial (compare has its own).


def add_evaluation_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", type=Path, metavar="DATASET")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="random seed (default 0)")
    parser.add_argument("--workers", type=positive_int, default=2,
                        help="parallel processes, each extracts the features once (default 2)")
    parser.add_argument("--cluster", type=str, default=None, metavar="ADDRESS",
                        help="run the trials on the Dask scheduler at ADDRESS (tcp://host:8786) instead of local "
                        "processes; its workers need the same rigd and the dataset at the same path "
                        "(pip install 'rigd[cluster]', docs/evaluation.md)")
    parser.add_argument("--cluster-timeout", type=positive_float, default=10.0, metavar="S",
                        help="seconds to wait for the cluster's scheduler and its first worker (default 10)")
    parser.add_argument("--out", type=Path, default=None, help="output directory (default DATASET/evaluation)")
    parser.add_argument("--sigmas", type=str, default=None,
                        help="sigma_in per coarse-to-fine level, degrees at 1 m (default: the calibration's)")
    parser.add_argument("--init", type=str, default=None,
                        help="initial guess 'roll,pitch,yaw,x,y,z' in deg and m (default: rig.yaml initial_guess)")
    parser.add_argument("--outlier-rule", choices=[r.value for r in OutlierRule],
                        default=OutlierRule.PER_PARAMETER.value,
                        help="per-parameter (paper Fig. 19: any of roll/pitch/yaw > 0.5 deg or x/y/z > 2.5 cm from "
                        "its median) or pose (rotation angle > 0.5 deg or distance > 2.5 cm from the median pose)")
    parser.add_argument("--no-uncertainty", action="store_true",
                        help="skip each run's uncertainty and verdict (faster; no coverage check)")
    parser.add_argument("--tolerance", type=str, default=None, metavar="ROT_DEG,TRANS_CM",
                        help="field tolerance of the verdicts (default 0.2,2)")


def evaluation_trust(args: argparse.Namespace) -> TrustOptions | None:
    """Each run's trust assessment: None with --no-uncertainty, else with --tolerance (default 0.2,2)."""
    return None if args.no_uncertainty else (parse_tolerance(args.tolerance) if args.tolerance else TrustOptions())


def add_start_axes_option(parser: argparse.ArgumentParser) -> None:
    """``--start-axes`` for the protocols that draw random starts (convergence, compare)."""
    parser.add_argument("--start-axes", choices=[a.value for a in StartAxes], default=StartAxes.AUTO.value,
                        help="turn the reference about these axes to draw a start: rpy (roll, pitch, yaw, the "
                        "paper's), lidar (the LiDAR's x, y, z), auto (rpy unless pitch is beyond 45 deg, as for "
                        "a pinhole camera, where roll and yaw turn about one axis; default)")


def add_method_option(parser: argparse.ArgumentParser) -> None:
    """``--method`` for the protocols that run calibrations from starts (convergence, precision)."""
    parser.add_argument("--method", choices=[m.value for m in Method], default=None,
                        help="what every run solves with, as `rigd calibrate --method` (default: what `rigd "
                        "calibrate` picks, nid-assessed on a single pinhole camera with intensity and no prior, "
                        "else rigd)")


def evaluation_settings(args: argparse.Namespace, trust: TrustOptions | None) -> EvaluationSettings:
    """The options of :func:`add_evaluation_options`, read."""
    return EvaluationSettings(
        dataset=args.dataset,
        seed=args.seed,
        workers=args.workers,
        out_dir=args.out,
        sigmas_deg=parse_sigmas(args.sigmas) if args.sigmas else None,
        initial=parse_init(args.init) if getattr(args, "init", None) else None,
        outlier_rule=OutlierRule(args.outlier_rule),
        trust=trust,
        cluster=args.cluster,
        cluster_timeout_s=args.cluster_timeout,
        method=Method(args.method) if getattr(args, "method", None) else None,
    )
