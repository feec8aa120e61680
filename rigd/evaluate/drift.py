"""``rigd evaluate drift``: how well ``rigd check`` tells drift from none (docs/check.md).

Trials inject a known error into the ground truth (a random direction in rotation or in translation, at
each magnitude of ``rot_deg`` / ``trans_cm``, and none at all), run :func:`calib.check.check_drift` from the
erroneous extrinsics, and count the outcomes: detection rate per magnitude, and the false-alarm rate (drifted
at zero error). The worker processes and their features are those of :mod:`rigd.evaluate.runner`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calib.check import DriftOptions, check_drift
from calib.errors import CalibError
from calib.geometry import Transform
from calib.uncertainty import tau_at
from rigd.dataset.store import write_yaml
from rigd.errors import RigdError
from rigd.evaluate.runner import trial_runner, where_run
from rigd.evaluate.trials import EvaluationSettings, WorkerState, calib_params, open_for


@dataclass(frozen=True)
class DriftRequest:
    settings: EvaluationSettings
    trials: int = 120
    rot_deg: tuple[float, ...] = (0.3, 0.5, 1.0)
    trans_cm: tuple[float, ...] = (2.0, 5.0)
    options: DriftOptions = DriftOptions()


@dataclass(frozen=True)
class _DriftTask:
    index: int
    injected: str  # "none", "rot 0.5 deg", "trans 2 cm"
    checked: Transform


@dataclass(frozen=True)
class DriftTrial:
    index: int
    injected: str
    status: str  # ok | drifted | unknown | error
    wall_s: float


@dataclass(frozen=True)
class DriftOutcome:
    trials: tuple[DriftTrial, ...]
    report: dict[str, Any]
    yaml_path: Path



def _classes(request: DriftRequest) -> list[tuple[str, float, bool]]:
    """(label, magnitude in rad or m, is_rotation) per class; zero error first."""
    return ([("none", 0.0, True)] + [(f"rot {r:g} deg", float(np.radians(r)), True) for r in request.rot_deg]
            + [(f"trans {t:g} cm", t / 100.0, False) for t in request.trans_cm])


def _tasks(truth: Transform, request: DriftRequest) -> list[_DriftTask]:
    rng = np.random.default_rng(request.settings.seed)
    classes = _classes(request)
    tasks = []
    for i in range(request.trials):
        label, size, rotation = classes[i % len(classes)]
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        xi = np.concatenate([direction * size, np.zeros(3)] if rotation else [np.zeros(3), direction * size])
        tasks.append(_DriftTask(i, label, Transform.from_tau(tau_at(truth.tau, xi))))
    return tasks


def _run_drift_task(state: WorkerState, task: tuple[_DriftTask, DriftOptions]) -> DriftTrial:
    t, opts = task
    started = time.monotonic()
    try:
        status = check_drift(list(state.feats), t.checked, state.params, opts).status.value
    except CalibError:  # the checked pose sees nothing: counted apart, not as a detection
        status = "error"
    return DriftTrial(t.index, t.injected, status, time.monotonic() - started)


def run_drift(request: DriftRequest) -> DriftOutcome:
    """Writes OUT/drift.yaml; needs a dataset with ground truth."""
    started = time.monotonic()
    s = request.settings
    dataset = open_for(s)
    if dataset.ground_truth is None:
        raise RigdError(f"{dataset.root}: drift evaluation needs ground_truth.yaml (a simulated dataset)")
    params = calib_params(s.sigmas_deg)
    tasks = [(t, request.options) for t in _tasks(dataset.ground_truth, request)]
    with trial_runner(s, dataset.root, params, None) as workers:
        where = where_run(s, workers)
        trials = tuple(sorted(workers.run(_run_drift_task, tasks, "drift", s.progress), key=lambda r: r.index))
    summary = {}
    for label, _, _ in _classes(request):
        mine = [t for t in trials if t.injected == label]
        counts = {k: sum(t.status == k for t in mine) for k in ("ok", "drifted", "unknown", "error")}
        summary[label] = {"trials": len(mine), **counts,
                          "drifted_share": counts["drifted"] / max(len(mine), 1),
                          "median_time_s": float(np.median([t.wall_s for t in mine])) if mine else None}
    o = request.options
    report = {
        "protocol": "drift", "dataset": str(dataset.root), "pairs": len(dataset),
        "settings": {"trials": request.trials, "seed": s.seed, **where,
                     "threshold_rot_deg": o.threshold_rot_deg, "threshold_trans_cm": o.threshold_trans_cm},
        "summary": summary,
        "false_alarm_rate": summary["none"]["drifted_share"],
        "wall_time_s": round(time.monotonic() - started, 2),
        "trials": [{"index": t.index, "injected": t.injected, "status": t.status, "wall_time_s": round(t.wall_s, 2)}
                   for t in trials],
    }
    out = Path(s.out_dir) if s.out_dir is not None else dataset.root / "evaluation"
    out.mkdir(parents=True, exist_ok=True)
    write_yaml(out / "drift.yaml", report)
    return DriftOutcome(trials, report, out / "drift.yaml")
