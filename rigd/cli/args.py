"""What more than one command reads from its arguments: the value types argparse checks, the texts of
``--init``, ``--sigmas``, ``--prior``, ``--tolerance`` and ``--threshold``, and the options every protocol of
``rigd evaluate`` takes. A command's own options stay in its module."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from pydantic import BaseModel, ValidationError
from tqdm import tqdm

from calib.drift import DriftOptions
from calib.evaluate import OutlierRule, StartAxes
from calib.methods import Method
from rigd.calibration.progress import Stage
from rigd.calibration.request import CalibrationRequest, Options, Start, ToleranceIn, TransformIn
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


def print_progress(stage: Stage, done: int, total: int) -> None:
    """A calibration's or check's progress on stderr, one line a step."""
    of = f" {done}/{total}" if total > 1 else ""
    print(f"[{stage.words}{of}]", file=sys.stderr, flush=True)


# Texts read after parsing: a refused one is a RigdError (rigd: error: ..., exit 2).


def numbers(text: str, option: str, count: int | None) -> list[float]:
    """``count`` (None: one or more) finite comma-separated numbers of ``option``."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as exc:
        raise RigdError(f"{option} must be {count or 'one or more'} comma-separated numbers, got {text!r}") from exc
    if (count is not None and len(values) != count) or not values or not np.all(np.isfinite(values)):
        raise RigdError(f"{option} must be {count or 'one or more'} finite comma-separated numbers, got {text!r}")
    return values


def parse_init(text: str, option: str = "--init") -> TransformIn:
    """'roll,pitch,yaw,x,y,z' (degrees, metres) -> the request's transform."""
    values = numbers(text, f"{option} ROLL,PITCH,YAW,X,Y,Z (deg, m)", 6)
    return validated(TransformIn, option, rpy_deg=values[:3], xyz_m=values[3:])


M = TypeVar("M", bound=BaseModel)


def validated(model: type[M], option: str, **fields: Any) -> M:
    """``model(**fields)``, its validation error as a RigdError naming ``option`` and each refused field (the
    service refuses the same values, in the same words)."""
    try:
        return model(**fields)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(map(str, e['loc'])) or 'value'}: {e['msg']}" for e in exc.errors())
        raise RigdError(f"{option}: {problems}") from None


class ExpertHelp(argparse.Action):
    """``--help-expert``: the command's help with its expert options (:func:`expert`) shown too."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        for action in parser._actions:
            shown = getattr(action, "expert_help", None)
            if shown is not None:
                action.help = shown
        parser.print_help()
        parser.exit()


def expert(parser: argparse.ArgumentParser, *names: str, help: str, **kwargs: Any) -> None:
    """An option that ``--help`` leaves out and ``--help-expert`` lists (tuning and research, not field work)."""
    action = parser.add_argument(*names, help=argparse.SUPPRESS, **kwargs)
    action.expert_help = f"(expert) {help}"  # type: ignore[attr-defined]


def parse_threshold(text: str | None) -> DriftOptions:
    """``--threshold`` 'rotation_deg,translation_cm' (positive numbers) -> rigd check's options (None: its
    defaults)."""
    if text is None:
        return DriftOptions()
    rot, trans = numbers(text, "--threshold", 2)
    if rot <= 0 or trans <= 0:
        raise RigdError(f"--threshold must be positive 'rotation_deg,translation_cm', got {text!r}")
    return DriftOptions(threshold_rot_deg=rot, threshold_trans_cm=trans)


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
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an earlier run's report and plot of this protocol there (default: refused)")
    parser.add_argument("--sigmas-deg", type=str, default=None, metavar="S1,S2,...",
                        help="the GMM's sigma_in per coarse-to-fine level, deg at 1 m (default: the method's)")
    parser.add_argument("--init", type=str, default=None, metavar="ROLL,PITCH,YAW,X,Y,Z",
                        help="initial guess in deg and m (default: rig.yaml initial_guess)")
    parser.add_argument("--outlier-rule", choices=[r.value for r in OutlierRule],
                        default=OutlierRule.PER_PARAMETER.value,
                        help="per-parameter (paper Fig. 19: any of roll/pitch/yaw > 0.5 deg or x/y/z > 2.5 cm from "
                        "its median) or pose (rotation angle > 0.5 deg or distance > 2.5 cm from the median pose)")
    parser.add_argument("--no-uncertainty", action="store_true",
                        help="skip each run's uncertainty and verdict (faster; no coverage check)")
    parser.add_argument("--tolerance", type=str, default=None, metavar="ROT_DEG,TRANS_CM",
                        help="field tolerance of the verdicts (default 0.2,2)")


def add_start_axes_option(parser: argparse.ArgumentParser) -> None:
    """``--start-axes`` for the protocols that draw random starts (convergence, compare)."""
    parser.add_argument("--start-axes", choices=[a.value for a in StartAxes], default=StartAxes.AUTO.value,
                        help="turn the reference about these axes to draw a start: rpy (roll, pitch, yaw, the "
                        "paper's), lidar (the LiDAR's x, y, z), auto (rpy unless pitch is beyond 45 deg, as for "
                        "a pinhole camera, where roll and yaw turn about one axis; default)")


def add_method_option(parser: argparse.ArgumentParser) -> None:
    """``--method`` for the protocols that run calibrations from starts (convergence, precision)."""
    parser.add_argument("--method", choices=[m.value for m in Method], default=None,
                        help="what every run solves with: rigd calibrate's methods and the research ones (the "
                        "paper's settings, the ablations, the photometric baselines; default: what `rigd calibrate` "
                        "picks, nid-assessed on a single pinhole camera with intensity and no prior, else gmm)")


def evaluation_settings(args: argparse.Namespace) -> EvaluationSettings:
    """The options of :func:`add_evaluation_options` (and ``--method``), read into the request every run solves."""
    options: dict[str, Any] = {"method": Method(args.method) if getattr(args, "method", None) else None}
    if args.sigmas_deg:
        options["sigmas_deg"] = numbers(args.sigmas_deg, "--sigmas-deg", None)
    if args.tolerance:
        rot, trans = numbers(args.tolerance, "--tolerance", 2)
        options["tolerance"] = validated(ToleranceIn, "--tolerance ROT_DEG,TRANS_CM", rotation_deg=rot,
                                         translation_cm=trans)
    initial = parse_init(args.init) if getattr(args, "init", None) else None
    request = validated(CalibrationRequest, "rigd evaluate", dataset=args.dataset,
                        start=Start.GIVEN if initial is not None else Start.RIG, initial=initial,
                        options=validated(Options, "rigd evaluate", **options), workers=args.workers,
                        assess=not getattr(args, "no_uncertainty", False))
    return EvaluationSettings(request, seed=args.seed, out_dir=args.out, outlier_rule=OutlierRule(args.outlier_rule),
                              cluster=args.cluster, cluster_timeout_s=args.cluster_timeout, overwrite=args.overwrite)
