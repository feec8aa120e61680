"""``rigd evaluate drift``: how well ``rigd check`` tells drift from none (docs/check.md).

Trials inject a known error into the ground truth (a random direction in rotation or in translation, at
each magnitude of ``rot_deg`` / ``trans_cm``, and none at all), run :func:`calib.drift.check_drift` from the
erroneous extrinsics, and count the answers per magnitude: ``ok`` at zero error (a good calibration passes),
``drifted`` at each magnitude (detection), and drifted at zero error (false alarms). With ``size`` each trial
checks that many pairs drawn at random from the dataset, so the pairs' own errors vary between trials too
(with all pairs every zero-error trial is the same check). The worker processes and their features are those
of :mod:`rigd.evaluate.pools`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from calib.drift import DriftOptions, DriftStatus, check_drift
from calib.errors import CalibError
from calib.evaluate import random_subsets
from calib.geometry import Transform
from calib.uncertainty import tau_at
from rigd.calibration.check_job import with_rig_tolerance
from rigd.dataset.store import write_yaml
from rigd.errors import RigdError
from rigd.evaluate.pools import trial_runner, where_run
from rigd.evaluate.trials import EvaluationSettings, WorkerState, gmm_request, of_pairs, open_for

ERROR = "error"  # a trial whose checked pose sees nothing: counted apart, not as an answer
ANSWERS = (*(s.value for s in DriftStatus), ERROR)


@dataclass(frozen=True)
class DriftRequest:
    """``size``: pairs per trial, drawn at random (None: all of the dataset's)."""

    settings: EvaluationSettings
    trials: int = 120
    rot_deg: tuple[float, ...] = (0.3, 0.5, 1.0)
    trans_cm: tuple[float, ...] = (2.0, 5.0)
    options: DriftOptions = DriftOptions()
    size: int | None = None


@dataclass(frozen=True)
class _DriftTask:
    index: int
    injected: str  # "none", "rot 0.5 deg", "trans 2 cm"
    checked: Transform
    pairs: tuple[int, ...]


@dataclass(frozen=True)
class DriftTrial:
    """One check: its answer (ok | drifted | unknown | error), and per group (rotation deg, translation cm) the
    change's length and its upper bound at the ok confidence (None where not judged)."""

    index: int
    injected: str
    status: str
    wall_s: float
    pairs: tuple[int, ...]
    length: tuple[float, float] | None = None
    upper: tuple[float, float] | None = None


@dataclass(frozen=True)
class DriftOutcome:
    trials: tuple[DriftTrial, ...]
    report: dict[str, Any]
    yaml_path: Path


def _classes(request: DriftRequest) -> list[tuple[str, float, bool]]:
    """(label, magnitude in rad or m, is_rotation) per class; zero error first."""
    return ([("none", 0.0, True)] + [(f"rot {r:g} deg", float(np.radians(r)), True) for r in request.rot_deg]
            + [(f"trans {t:g} cm", t / 100.0, False) for t in request.trans_cm])


def _tasks(truth: Transform, n_pairs: int, request: DriftRequest) -> list[_DriftTask]:
    rng = np.random.default_rng(request.settings.seed)
    classes = _classes(request)
    all_pairs = tuple(range(n_pairs))
    subsets = ([all_pairs] * request.trials if request.size is None
               else random_subsets(n_pairs, request.size, request.trials, request.settings.seed))
    tasks = []
    for i, pairs in enumerate(subsets):
        label, size, rotation = classes[i % len(classes)]
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        xi = np.concatenate([direction * size, np.zeros(3)] if rotation else [np.zeros(3), direction * size])
        tasks.append(_DriftTask(i, label, Transform.from_tau(tau_at(truth.tau, xi)), pairs))
    return tasks


def _run_drift_task(state: WorkerState, task: tuple[_DriftTask, DriftOptions]) -> DriftTrial:
    t, opts = task
    started = time.monotonic()
    assert state.solve is not None and state.solve.gmm is not None and state.features.gmm is not None
    feats = of_pairs(state.features.gmm, state.n_pairs, t.pairs)
    try:
        result = check_drift(feats, t.checked, state.solve.gmm, opts, state.solve.prior)
    except CalibError:
        return DriftTrial(t.index, t.injected, ERROR, time.monotonic() - started, t.pairs)
    groups = result.judgement.groups
    length = (groups[0].length, groups[1].length) if groups else None
    upper = (groups[0].upper, groups[1].upper) if groups else None
    return DriftTrial(t.index, t.injected, result.status.value, time.monotonic() - started, t.pairs, length, upper)


def _row(mine: list[DriftTrial]) -> dict[str, Any]:
    """One magnitude's counts and shares."""
    counts = {k: sum(t.status == k for t in mine) for k in ANSWERS}
    n = max(len(mine), 1)
    return {"trials": len(mine), **counts, "ok_share": counts["ok"] / n, "drifted_share": counts["drifted"] / n,
            "median_time_s": float(np.median([t.wall_s for t in mine])) if mine else None}


def _trial_yaml(t: DriftTrial, size: int | None) -> dict[str, Any]:
    out: dict[str, Any] = {"index": t.index, "injected": t.injected, "status": t.status,
                           "wall_time_s": round(t.wall_s, 2)}
    if size is not None:
        out["pairs"] = list(t.pairs)
    if t.length is not None and t.upper is not None:
        out["length"] = {"rotation_deg": t.length[0], "translation_cm": t.length[1]}
        out["upper"] = {"rotation_deg": t.upper[0], "translation_cm": t.upper[1]}
    return out


def run_drift(request: DriftRequest) -> DriftOutcome:
    """Writes OUT/drift.yaml; needs a dataset with ground truth."""
    started = time.monotonic()
    s = request.settings
    checks = gmm_request(s.request)
    dataset, _ = open_for(replace(s, request=checks))
    if dataset.ground_truth is None:
        raise RigdError(f"{dataset.root}: drift evaluation needs ground_truth.yaml (a simulated dataset)")
    out = s.out(dataset, "drift.yaml")
    if request.size is not None and not 1 <= request.size <= len(dataset):
        raise RigdError(f"--size must be between 1 and the dataset's {len(dataset)} pairs, got {request.size}")
    opts = with_rig_tolerance(request.options, dataset)
    tasks = [(t, opts) for t in _tasks(dataset.ground_truth, len(dataset), request)]
    with trial_runner(s, checks) as workers:
        where = where_run(s, workers)
        trials = tuple(sorted(workers.run(_run_drift_task, tasks, "drift", s.progress), key=lambda r: r.index))
    summary = {label: _row([t for t in trials if t.injected == label]) for label, _, _ in _classes(request)}
    o = request.options
    report = {
        "protocol": "drift", "dataset": str(dataset.root), "pairs": len(dataset),
        "settings": {"trials": request.trials, "seed": s.seed, "size": request.size, **where,
                     "threshold_rot_deg": o.threshold_rot_deg, "threshold_trans_cm": o.threshold_trans_cm,
                     "ok_confidence": o.ok_confidence, "drift_confidence": o.drift_confidence},
        "summary": summary,
        "false_alarm_rate": summary["none"]["drifted_share"],
        "ok_rate_at_zero_error": summary["none"]["ok_share"],
        "wall_time_s": round(time.monotonic() - started, 2),
        "trials": [_trial_yaml(t, request.size) for t in trials],
    }
    out.mkdir(parents=True, exist_ok=True)
    write_yaml(out / "drift.yaml", report)
    return DriftOutcome(trials, report, out / "drift.yaml")
