"""The paper's evaluation protocols on a dataset (docs/evaluation.md): convergence (Fig. 19) and precision
(Table 1), many calibrations run where :mod:`rigd.evaluate.pools` says (worker processes or a Dask cluster),
their statistics (calib.evaluate), a YAML report and a plot (:mod:`rigd.evaluate.plots`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.evaluate import (
    Coverage,
    Params6,
    RunStats,
    StartAxes,
    coverage,
    parameter_values,
    random_starts,
    random_subsets,
    run_stats,
)
from calib.geometry import Transform
from rigd.calibration.request import Resolved
from rigd.dataset import Dataset
from rigd.dataset.records import prior_to_yaml, transform_to_yaml
from rigd.dataset.reference import AXES, Reference, agreement
from rigd.dataset.store import write_yaml
from rigd.errors import RigdError
from rigd.evaluate.plots import plot_convergence, plot_precision
from rigd.evaluate.pools import TrialRunner, trial_runner, where_run
from rigd.evaluate.trials import EvaluationSettings, Run, Task, open_for, run_task


class Protocol(Enum):
    CONVERGENCE = "convergence"  # paper 8.5, Fig. 19: random starts around a reference, all pairs
    PRECISION = "precision"  # paper 8.2.2, Table 1: random subsets of pairs, one start


class Source(Enum):
    """Where a reference pose or a start came from."""

    GROUND_TRUTH = "ground_truth"  # the dataset's ground_truth.yaml
    REFERENCE = "reference"  # the dataset's reference.yaml: a published calibration of real data
    CALIBRATION = "calibration"  # a calibration with all pairs from the initial guess
    INITIAL_GUESS = "initial_guess"  # --init or rig.yaml's initial_guess

    @property
    def label(self) -> str:
        return self.value.replace("_", " ")


@dataclass(frozen=True)
class ConvergenceRequest:
    settings: EvaluationSettings
    trials: int = 200
    rot_deg: float = 5.0
    trans_m: float = 0.1
    start_axes: StartAxes = StartAxes.AUTO  # about which axes the starts are turned (calib.evaluate.StartAxes)


@dataclass(frozen=True)
class PrecisionRequest:
    settings: EvaluationSettings
    subsets: int = 100
    size: int = 12


@dataclass(frozen=True)
class EvaluationOutcome:
    protocol: Protocol
    stats: RunStats
    runs: tuple[Run, ...]
    reference: Transform
    reference_source: Source
    report: dict[str, Any]
    yaml_path: Path
    plot_path: Path


def _run_all(runner: TrialRunner, tasks: Sequence[Task], desc: str, progress: bool) -> tuple[Run, ...]:
    return tuple(sorted(runner.run(run_task, tasks, desc, progress), key=lambda r: r.index))


def run_convergence(request: ConvergenceRequest) -> EvaluationOutcome:
    """Paper 8.5: calibrate from ``trials`` random starts around the ground truth (or, without one, around a
    first calibration from the initial guess); writes OUT/convergence.yaml and convergence.png."""
    started = time.monotonic()
    s = request.settings
    dataset, resolved = open_for(s)
    s.out(dataset, "convergence.yaml", "convergence.png")
    pairs = tuple(range(len(dataset)))
    with trial_runner(s) as workers:
        where = where_run(s, workers)
        if dataset.ground_truth is not None:
            reference, source = dataset.ground_truth, Source.GROUND_TRUTH
        elif dataset.reference is not None:
            reference, source = dataset.reference.T_camera_lidar, Source.REFERENCE
        else:
            initial = s.initial(dataset)
            if initial is None:
                raise RigdError(f"{dataset.root}: no ground_truth.yaml and no initial_guess in rig.yaml; give a "
                                "start for the reference calibration with --init 'r,p,y,x,y,z'")
            (first,) = _run_all(workers, [Task(-1, initial, pairs)], "reference calibration", s.progress)
            if first.result is None:
                raise RigdError(f"{dataset.root}: the reference calibration failed: {first.error}")
            reference, source = first.result, Source.CALIBRATION
        axes = request.start_axes.resolve(reference)
        starts = random_starts(reference, request.trials, request.rot_deg, request.trans_m, s.seed, axes)
        runs = _run_all(workers, [Task(i, t, pairs) for i, t in enumerate(starts)], "convergence", s.progress)
    stats = run_stats(reference, [r.result for r in runs], s.outlier_rule)
    setup = {"trials": request.trials, "rot_deg": request.rot_deg, "trans_m": request.trans_m,
             "start_axes": axes.value, **where}
    return _finish(Protocol.CONVERGENCE, s, resolved, dataset, setup, runs, stats, reference, source, started)


def run_precision(request: PrecisionRequest) -> EvaluationOutcome:
    """Paper 8.2.2: calibrate ``subsets`` random subsets of ``size`` pairs from one start (``--init``, rig.yaml's
    initial_guess or, failing both, the ground truth); writes OUT/precision.yaml and precision.png."""
    started = time.monotonic()
    s = request.settings
    dataset, resolved = open_for(s)
    s.out(dataset, "precision.yaml", "precision.png")
    subsets = random_subsets(len(dataset), request.size, request.subsets, s.seed)
    initial = s.initial(dataset)
    start, start_source = ((initial, Source.INITIAL_GUESS) if initial is not None
                           else (dataset.ground_truth, Source.GROUND_TRUTH))
    if start is None:
        raise RigdError(f"{dataset.root}: no initial_guess in rig.yaml and no ground_truth.yaml; give the start "
                        "with --init 'r,p,y,x,y,z'")
    with trial_runner(s) as workers:
        where = where_run(s, workers)
        runs = _run_all(workers, [Task(i, start, p) for i, p in enumerate(subsets)], "precision", s.progress)
    truth = dataset.ground_truth
    reference, source = (truth, Source.GROUND_TRUTH) if truth is not None else \
        (dataset.reference.T_camera_lidar, Source.REFERENCE) if dataset.reference is not None else (start, start_source)
    stats = run_stats(reference, [r.result for r in runs], s.outlier_rule)
    setup = {"subsets": request.subsets, "size": request.size, "start": start_source.value,
             "start_T_camera_lidar": transform_to_yaml(start), **where}
    return _finish(Protocol.PRECISION, s, resolved, dataset, setup, runs, stats, reference, source, started)


def _params_yaml(p: Params6 | None) -> dict[str, float] | None:
    return None if p is None else dict(p._asdict())


def _pose_yaml(t: Transform) -> dict[str, list[float]]:
    return {"rpy_deg": t.rpy_deg.tolist(), "xyz_m": t.translation_m.tolist()}


USABLE = ("trusted", "weak")  # verdicts whose result rigd hands over (a failed one is not to be used)


def std_not_failed(stats: RunStats, runs: Sequence[Run]) -> Params6 | None:
    """Sample std of the runs whose verdict is trusted or weak: the spread of the results a user is given.
    None without verdicts (a method without an assessment) or with fewer than two such runs."""
    usable = np.array([r.verdict in USABLE and r.result is not None for r in runs], dtype=bool)
    if usable.sum() < 2:
        return None
    return Params6.from_array(stats.values[usable].std(axis=0, ddof=1))


def _summary_yaml(stats: RunStats, runs: Sequence[Run], with_error: bool) -> dict[str, Any]:
    times = [r.wall_s for r in runs]
    out: dict[str, Any] = {
        "runs": stats.runs,
        "finished": stats.finished,
        "converged": stats.converged_count,
        "converged_percent": stats.converged_percent,
        "outlier_rule": {"rule": stats.rule.value, "rotation_deg": stats.rot_tol_deg,
                         "translation_m": stats.trans_tol_m},
        "median": _params_yaml(stats.median),
        "mean": _params_yaml(stats.mean),
        "std": _params_yaml(stats.std),
        "std_converged": _params_yaml(stats.std_converged),
        "std_not_failed": _params_yaml(std_not_failed(stats, runs)),
        "solution": _params_yaml(stats.solution),
        "calibration_time_s": {"median": float(np.median(times)), "max": float(np.max(times))},
    }
    if with_error:
        err, med = stats.solution_error, stats.run_error_median
        out["error_vs_ground_truth"] = {
            "solution": None if err is None else dict(err._asdict()),
            "run_median": None if med is None else dict(med._asdict()),
        }
    return out


def _vs_reference(ref: Reference, runs: Sequence[Run]) -> dict[str, Any]:
    """How the runs agree with a published reference (rigd.dataset.reference): the share of runs with every axis
    within 2.5 of the reference's sigmas and the whole difference within 0.6 deg / 10 cm, and the median
    difference per axis in those sigmas."""
    done = [agreement(ref, r.result) for r in runs if r.result is not None]
    if not done:
        return {"runs": 0}
    z = np.array([a.z for a in done])
    return {"runs": len(done), "within": sum(a.within() for a in done),
            "rule": "within 0.6 deg / 10 cm" + ("" if ref.sigma is None else ", every axis within 2.5 of its sigmas"),
            "median_z": None if ref.sigma is None else dict(zip(AXES, np.median(z, axis=0).tolist(), strict=True)),
            "median_rotation_deg": float(np.median([a.rotation_deg for a in done])),
            "median_translation_cm": float(np.median([a.translation_cm for a in done]))}


def _coverage_yaml(c: Coverage, source: Source,
                   reference_sigma: NDArray[np.float64] | None = None) -> dict[str, Any]:
    out = {
        "against": source.value,
        "within_3_sigma": c.within_3_sigma,
        "within_3_sigma_per_axis": dict(zip(("roll", "pitch", "yaw", "x", "y", "z"), c.per_axis, strict=True)),
        "target": 0.95,
        "verdicts": c.verdicts,
        "trusted_but_wrong": c.trusted_but_wrong,
        "median_abs_z": [float(v) for v in np.nanmedian(np.abs(c.z), axis=0)] if np.isfinite(c.z).any() else None,
    }
    if reference_sigma is not None:  # a published estimate, not a truth: differences weighed against both sigmas
        out["reference_sigma_deg_cm"] = reference_sigma.tolist()
    return out


def _runs_yaml(runs: Sequence[Run], stats: RunStats, protocol: Protocol) -> list[dict[str, Any]]:
    out = []
    for run, converged in zip(runs, stats.converged.tolist(), strict=True):
        entry: dict[str, Any] = {"index": run.index}
        if protocol is Protocol.PRECISION:
            entry["pairs"] = list(run.pairs)
        else:
            entry["start"] = _pose_yaml(run.start)
        entry["result"] = None if run.result is None else _pose_yaml(run.result)
        entry.update(converged=bool(converged), final_cost=run.final_cost, iterations=run.iterations,
                     wall_time_s=round(run.wall_s, 3), verdict=run.verdict,
                     sigma=None if run.sigma is None else [v if np.isfinite(v) else None for v in run.sigma])
        if run.cross_check is not None:
            entry["cross_check"] = list(run.cross_check)
        if run.error is not None:
            entry["error"] = run.error
        out.append(entry)
    return out


def _finish(protocol: Protocol, s: EvaluationSettings, resolved: Resolved, dataset: Dataset,
            setup: dict[str, Any], runs: tuple[Run, ...], stats: RunStats, reference: Transform, source: Source,
            started: float) -> EvaluationOutcome:
    solve = resolved.solve
    out = Path(s.out_dir) if s.out_dir is not None else dataset.root / "evaluation"
    out.mkdir(parents=True, exist_ok=True)
    plot_path = out / f"{protocol.value}.png"
    if protocol is Protocol.CONVERGENCE:
        starts = parameter_values(reference, [r.start for r in runs])
        plot_convergence(plot_path, starts, stats, parameter_values(reference, [reference])[0],
                         source.label)
    else:
        plot_precision(plot_path, stats)
    report: dict[str, Any] = {
        "protocol": protocol.value,
        "dataset": str(dataset.root),
        "pairs_in_dataset": len(dataset),
        "settings": {**setup, "seed": s.seed, "method": solve.method.value,
                     **({"sigmas_deg": list(solve.gmm.optim.sigmas_deg)} if solve.gmm is not None else {})},
        "reference": {"source": source.value, "T_camera_lidar": transform_to_yaml(reference)},
        "summary": _summary_yaml(stats, runs, with_error=dataset.ground_truth is not None),
        "wall_time_s": round(time.monotonic() - started, 2),
        "plot": plot_path.name,
        "runs": _runs_yaml(runs, stats, protocol),
    }
    if dataset.reference is not None:
        report["summary"]["vs_reference"] = _vs_reference(dataset.reference, runs)
    if solve.prior is not None:  # every run's solve used it, as `rigd calibrate` does
        report["settings"]["prior"] = prior_to_yaml(solve.prior)
    if solve.trust is not None:
        sigmas = [None if r.sigma is None else np.array(r.sigma) for r in runs]
        ref_sigma = dataset.reference.local_sigma() if source is Source.REFERENCE and dataset.reference else None
        check = coverage(reference, [r.result for r in runs], sigmas, [r.verdict for r in runs],
                         solve.trust.tolerance_display, ref_sigma)
        report["summary"]["uncertainty_check"] = _coverage_yaml(check, source, ref_sigma)
    yaml_path = out / f"{protocol.value}.yaml"
    write_yaml(yaml_path, report)
    return EvaluationOutcome(protocol, stats, runs, reference, source, report, yaml_path, plot_path)
