"""``rigd evaluate compare``: the paper's comparison (Table 1 and Fig. 19) for several methods side by side.

For each method (calib.methods), on the same dataset, subsets and starts:
- precision (paper 8.2.2, Table 1): ``subsets`` random subsets of ``size`` pairs, each calibrated from the
  reference; the standard deviation of each parameter (skipped when the dataset has no more than ``size`` pairs);
- convergence (paper 8.5, Fig. 19): ``trials`` random starts within +-rot_deg / +-trans_m of the reference,
  all pairs.
The reference is the dataset's ground truth (else its rig.yaml initial guess). One YAML report, one table
(markdown, printed) and one plot (convergence: the error of every run by method). Each method runs in its own
pool of worker processes that extract that method's features once.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from calib.evaluate import OutlierRule, RunStats, StartAxes, pose_error, random_starts, random_subsets, run_stats
from calib.geometry import Transform
from calib.methods import Method
from rigd.calibration.request import CalibrationRequest, Options
from rigd.dataset import open_dataset
from rigd.dataset.records import transform_to_yaml
from rigd.dataset.store import write_yaml
from rigd.dataset.working import WORKING_WIDTH_PX
from rigd.errors import RigdError
from rigd.evaluate.pools import trial_runner
from rigd.evaluate.trials import EvaluationSettings, Run, Task, run_task
from rigd.outdir import claim_output_files

AXES6 = ("roll_deg", "pitch_deg", "yaw_deg", "x_m", "y_m", "z_m")


@dataclass(frozen=True)
class CompareRequest:
    dataset: Path
    methods: tuple[Method, ...]
    subsets: int = 10
    size: int = 12
    trials: int = 10
    rot_deg: float = 5.0
    trans_m: float = 0.1
    seed: int = 0
    workers: int = 2
    out_dir: Path | None = None
    start_axes: StartAxes = StartAxes.AUTO  # about which axes the starts are turned (calib.evaluate.StartAxes)
    progress: bool = True
    target_rot_deg: float = 0.5  # a run is "near the reference" within these (issue 10's real-data target)
    target_trans_cm: float = 5.0
    overwrite: bool = False  # write over an earlier compare's report, table and plot in the same folder


@dataclass(frozen=True)
class MethodRows:
    method: Method
    precision: RunStats | None
    convergence: RunStats
    precision_runs: tuple[Run, ...]
    convergence_runs: tuple[Run, ...]
    errors: tuple[tuple[float, float] | None, ...]  # per convergence run: rotation deg, translation cm


@dataclass(frozen=True)
class CompareOutcome:
    rows: tuple[MethodRows, ...]
    report: dict[str, Any]
    table: str
    yaml_path: Path
    plot_path: Path


def _run(req: CompareRequest, method: Method, tasks: Sequence[Task]) -> tuple[Run, ...]:
    """``tasks`` solved as `rigd calibrate --method METHOD` would, without its assessment, in the evaluation's pool:
    the features are extracted once per worker for both protocols."""
    if not tasks:
        return ()
    request = CalibrationRequest(dataset=req.dataset, options=Options(method=method), workers=req.workers,
                                 assess=False)
    with trial_runner(EvaluationSettings(request, progress=req.progress)) as workers:
        return tuple(sorted(workers.run(run_task, tasks, method.value, req.progress), key=lambda r: r.index))


def parse_methods(text: str) -> tuple[Method, ...]:
    """'gmm,mi,nid,gom,...' -> methods ('gmm' is rigd's GMM); raises RigdError naming an unknown one."""
    names = {m.value: m for m in Method}
    out = []
    for name in (n.strip() for n in text.split(",") if n.strip()):
        if name not in names:
            raise RigdError(f"--methods: unknown method {name!r}; known: {', '.join(m.value for m in Method)}")
        out.append(names[name])
    if not out:
        raise RigdError("--methods: give at least one method")
    return tuple(dict.fromkeys(out))


def _errors(reference: Transform, runs: Sequence[Run]) -> tuple[tuple[float, float] | None, ...]:
    out: list[tuple[float, float] | None] = []
    for r in runs:
        if r.result is None:
            out.append(None)
            continue
        e = pose_error(r.result, reference)
        out.append((e.rotation_deg, e.translation_cm))
    return tuple(out)


def _fmt_std(stats: RunStats | None) -> str:
    if stats is None or stats.std is None:
        return "n/a | n/a | n/a | n/a | n/a | n/a"
    s = stats.std
    return " | ".join([f"{s.roll_deg:.3f}", f"{s.pitch_deg:.3f}", f"{s.yaw_deg:.3f}",
                       f"{s.x_m * 100:.2f}", f"{s.y_m * 100:.2f}", f"{s.z_m * 100:.2f}"])


def _near(errors: Sequence[tuple[float, float] | None], req: CompareRequest) -> int:
    return sum(1 for e in errors if e is not None and e[0] <= req.target_rot_deg and e[1] <= req.target_trans_cm)


def _median_error(errors: Sequence[tuple[float, float] | None]) -> tuple[float, float] | None:
    done = np.array([e for e in errors if e is not None])
    return None if done.size == 0 else (float(np.median(done[:, 0])), float(np.median(done[:, 1])))


def _median_time(runs: Sequence[Run]) -> float | None:
    """Median wall seconds per run; None for a protocol that was not run (a single-frame dataset)."""
    return float(np.median([r.wall_s for r in runs])) if runs else None


def _fmt_time(runs: Sequence[Run]) -> str:
    t = _median_time(runs)
    return "—" if t is None else f"{t:.1f}"


def table(rows: Sequence[MethodRows], req: CompareRequest) -> str:
    """Markdown: per method the precision std per axis (deg, cm), convergence share, error vs the reference
    and time per run."""
    head = ("| method | std roll | std pitch | std yaw (deg) | std x | std y | std z (cm) | converged | "
            f"within {req.target_rot_deg:g}°/{req.target_trans_cm:g} cm of ref. | median error vs ref. | "
            "s/run (prec. / conv.) |")
    lines = [head, "|" + "---|" * 11]
    for r in rows:
        med = _median_error(r.errors)
        err = "n/a" if med is None else f"{med[0]:.3f}° / {med[1]:.2f} cm"
        c = r.convergence
        lines.append(f"| {r.method.value} | {_fmt_std(r.precision)} | {c.converged_count}/{c.runs} | "
                     f"{_near(r.errors, req)}/{len(r.errors)} | {err} | "
                     f"{_fmt_time(r.precision_runs)} / {_fmt_time(r.convergence_runs)} |")
    return "\n".join(lines)


def plot(path: Path, rows: Sequence[MethodRows], req: CompareRequest) -> None:
    """Fig. 19 side by side: per method, each convergence run's rotation error (deg) and translation error (cm)
    against the reference, the start range dotted, the target dashed."""
    fig = Figure(figsize=(12, 5.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax_r, ax_t = fig.subplots(1, 2)
    for k, r in enumerate(rows):
        errs = np.array([e if e is not None else (np.nan, np.nan) for e in r.errors])
        x = k + np.linspace(-0.3, 0.3, len(errs)) if len(errs) > 1 else np.array([float(k)])
        ax_r.plot(x, errs[:, 0], "o", mfc="none", ms=4)
        ax_t.plot(x, errs[:, 1], "o", mfc="none", ms=4)
    for ax, target, unit in ((ax_r, req.target_rot_deg, "deg"), (ax_t, req.target_trans_cm, "cm")):
        ax.axhline(target, color="tab:red", ls="--", lw=1, label="target")
        ax.set_yscale("log")
        ax.set_xticks(range(len(rows)), [r.method.value for r in rows], rotation=30, ha="right")
        ax.set_ylabel(f"error vs reference ({unit})")
    ax_r.set_title("rotation error")
    ax_t.set_title("translation error")
    fig.suptitle(f"Convergence from {req.trials} starts within ±{req.rot_deg:g}° / ±{req.trans_m * 100:g} cm")
    fig.savefig(path, dpi=110)


def _pose_yaml(t: Transform | None) -> dict[str, list[float]] | None:
    return None if t is None else {"rpy_deg": t.rpy_deg.tolist(), "xyz_m": t.translation_m.tolist()}


def _runs_yaml(runs: Sequence[Run]) -> list[dict[str, Any]]:
    return [{"index": r.index, "start": _pose_yaml(r.start), "result": _pose_yaml(r.result), "error": r.error,
             "final_cost": r.final_cost, "wall_time_s": round(r.wall_s, 3)} for r in runs]


def _stats_yaml(stats: RunStats | None) -> dict[str, Any] | None:
    if stats is None:
        return None
    return {"runs": stats.runs, "finished": stats.finished, "converged": stats.converged_count,
            "std": None if stats.std is None else dict(zip(AXES6, stats.std, strict=True)),
            "std_converged": None if stats.std_converged is None else dict(zip(AXES6, stats.std_converged,
                                                                                strict=True))}


def _write(out: Path, header: dict[str, Any], rows: Sequence[MethodRows], req: CompareRequest,
           wall_s: float) -> dict[str, Any]:
    """compare.yaml, compare.md and compare.png of the methods run so far."""
    text = table(rows, req)
    plot(out / "compare.png", rows, req)
    report: dict[str, Any] = {
        **header,
        "methods": {r.method.value: {
            "precision": _stats_yaml(r.precision),
            "convergence": _stats_yaml(r.convergence),
            "near_reference": _near(r.errors, req),
            "median_error_vs_reference": _median_error(r.errors),
            "errors_vs_reference": [None if e is None else list(e) for e in r.errors],
            "time_per_run_s": {"precision": _median_time(r.precision_runs),
                               "convergence": _median_time(r.convergence_runs)},
            "convergence_runs": _runs_yaml(r.convergence_runs),
        } for r in rows},
        "table": text,
        "wall_time_s": round(wall_s, 1),
        "plot": "compare.png",
    }
    write_yaml(out / "compare.yaml", report)
    (out / "compare.md").write_text(text + "\n")
    return report


def run_compare(req: CompareRequest) -> CompareOutcome:
    """Both protocols for every method of ``req``; writes OUT/compare.yaml, compare.md and compare.png."""
    started = time.monotonic()
    if req.workers < 1:
        raise RigdError(f"--workers must be at least 1, got {req.workers}")
    dataset = open_dataset(req.dataset, WORKING_WIDTH_PX)
    if len(dataset) == 0:
        raise RigdError(f"{dataset.root}: dataset has no pairs (pairs/NNNN)")
    published = dataset.reference.T_camera_lidar if dataset.reference is not None else None
    reference = dataset.ground_truth or published or dataset.rig.initial_guess
    if reference is None:
        raise RigdError(f"{dataset.root}: compare needs ground_truth.yaml, reference.yaml or an initial_guess in "
                        "rig.yaml")
    source = "ground_truth" if dataset.ground_truth is not None else "reference" if published is not None \
        else "initial_guess"
    all_pairs = tuple(range(len(dataset)))
    subsets = random_subsets(len(dataset), req.size, req.subsets, req.seed) if len(dataset) > req.size else ()
    axes = req.start_axes.resolve(reference)
    starts = random_starts(reference, req.trials, req.rot_deg, req.trans_m, req.seed, axes)
    out = Path(req.out_dir) if req.out_dir is not None else dataset.root / "evaluation"
    claim_output_files([out / f"compare.{x}" for x in ("yaml", "md", "png")], overwrite=req.overwrite)
    out.mkdir(parents=True, exist_ok=True)
    header = {"protocol": "compare", "dataset": str(dataset.root), "pairs_in_dataset": len(dataset),
              "reference": {"source": source, "T_camera_lidar": transform_to_yaml(reference)},
              "settings": {"methods": [m.value for m in req.methods], "subsets": len(subsets), "size": req.size,
                           "trials": req.trials, "rot_deg": req.rot_deg, "trans_m": req.trans_m,
                           "start_axes": axes.value, "seed": req.seed, "workers": req.workers}}
    rows: list[MethodRows] = []
    report: dict[str, Any] = {}
    for method in req.methods:
        tasks = [Task(i, reference, s) for i, s in enumerate(subsets)]
        tasks += [Task(len(subsets) + i, t, all_pairs) for i, t in enumerate(starts)]
        runs = _run(req, method, tasks)
        prec, conv = runs[:len(subsets)], runs[len(subsets):]
        errors = [r.error for r in runs if r.error is not None]
        if errors and all(r.result is None for r in runs):
            raise RigdError(f"method {method.value}: every run failed: {errors[0]}")
        p_stats = run_stats(reference, [r.result for r in prec], OutlierRule.PER_PARAMETER) if prec else None
        c_stats = run_stats(reference, [r.result for r in conv], OutlierRule.PER_PARAMETER)
        rows.append(MethodRows(method, p_stats, c_stats, prec, conv, _errors(reference, conv)))
        # written after each method, so a long run that is stopped keeps what it measured
        report = _write(out, header, rows, req, time.monotonic() - started)
    text = table(rows, req)
    yaml_path, plot_path = out / "compare.yaml", out / "compare.png"
    return CompareOutcome(tuple(rows), report, text, yaml_path, plot_path)
