"""``rigd evaluate initial``: does the global search find the start without any guess? (docs/evaluation.md)

Each trial mounts the camera at random (yaw uniform in +-``yaw_deg``, roll and pitch uniform in +-``tilt_deg``
as ``R = R_base Rz Ry Rx``, lever arm uniform in +-``lever_m`` per axis) and calibrates with no initial guess:
the global search of :mod:`calib.search`, then the usual coarse-to-fine from its best start. A random mount
is made from the dataset's own sweeps by expressing each cloud in the LiDAR frame the new mount implies,
``p' = R'^T (R p + t - t')`` with (R, t) the ground truth and (R', t') the new mount: the camera sees every
point where it saw it before. (The ranges |p'| then differ from the sensor's by up to the lever-arm change,
which eq. 23's sigma uses; decimetres against edges metres away.)

Each trial runs what ``rigd calibrate`` runs: with the settings' trust options (the default) the runner-up of
the search is solved in full too and the lower of the two kept, and the verdict is recorded; a wrong run
that is not called ``trusted`` is a failure of the search but not a lie (``trusted_but_wrong`` counts those).

A trial succeeds when it ends as close to its mount as a run started 5 deg / 10 cm from the ground truth on
the unchanged dataset (the ``reference`` run), within the field tolerance: rotation error <= reference + 0.2
deg and translation error <= reference + 2 cm.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from calib.errors import CalibError
from calib.evaluate import random_starts
from calib.geometry import Transform, rotation_angle_deg, rpy_deg_to_matrix
from calib.gmm import PairFeatures
from calib.methods import Method, solve
from calib.search import SearchOptions, base_rotation
from rigd.dataset.store import write_yaml
from rigd.errors import RigdError
from rigd.evaluate.pools import trial_runner, where_run
from rigd.evaluate.trials import EvaluationSettings, WorkerState, open_for


@dataclass(frozen=True)
class InitialRequest:
    settings: EvaluationSettings
    trials: int = 100
    yaw_deg: float = 180.0
    tilt_deg: float = 30.0
    lever_m: float = 0.3
    tolerance_rot_deg: float = 0.2
    tolerance_trans_cm: float = 2.0


@dataclass(frozen=True)
class _Task:
    index: int
    mount: Transform | None  # None: the reference run (start 5 deg / 10 cm from the ground truth)
    start: Transform | None
    truth: Transform


@dataclass(frozen=True)
class InitialTrial:
    index: int
    mount_rpy_deg: tuple[float, ...]
    rotation_err_deg: float | None
    translation_err_cm: float | None
    search_s: float
    total_s: float
    runner_up_deg: float | None  # how far the search's second distinct start was from its first
    verdict: str | None = None  # trusted / weak / failed; None without the trust assessment
    error: str | None = None


def remount(feats: list[PairFeatures], truth: Transform, mount: Transform) -> list[PairFeatures]:
    """The pairs' edge points in the LiDAR frame of ``mount``: p' = R'^T (R p + t - t')."""
    moved = mount.inverse().compose(truth)
    return [replace(f, points=replace(f.points, points_lidar=moved.apply(f.points.points_lidar))) for f in feats]


def _mounts(request: InitialRequest, base: np.ndarray) -> list[Transform]:
    rng = np.random.default_rng(request.settings.seed)
    out = []
    for _ in range(request.trials):
        rpy = np.r_[rng.uniform(-request.tilt_deg, request.tilt_deg, 2), rng.uniform(-request.yaw_deg, request.yaw_deg)]
        out.append(Transform(base @ rpy_deg_to_matrix(rpy), rng.uniform(-request.lever_m, request.lever_m, 3)))
    return out


def _run_trial(state: WorkerState, task: _Task) -> InitialTrial:
    started = time.monotonic()
    target = task.mount or task.truth
    assert state.solve is not None and state.features.gmm is not None
    feats = state.features.gmm
    feats = list(feats) if task.mount is None else remount(list(feats), task.truth, task.mount)
    searched: list[float] = []
    try:  # no prior: a remount moves the lever arm away from the drawing's
        result = solve(replace(state.solve, initial=task.start, prior=None), feats=feats,
                       on_search=lambda d, n: searched.append(time.monotonic()) if d == n else None)
    except CalibError as exc:
        return InitialTrial(task.index, (), None, None, 0.0, time.monotonic() - started, None, str(exc))
    T = result.T_camera_lidar
    runner_up = None
    if result.search is not None and len(result.search.candidates) > 1:
        best, second = result.search.candidates[:2]
        runner_up = rotation_angle_deg(Transform.from_tau(best.tau).rotation, Transform.from_tau(second.tau).rotation)
    return InitialTrial(
        task.index, tuple(float(v) for v in target.rpy_deg), rotation_angle_deg(T.rotation, target.rotation),
        float(np.linalg.norm(T.translation_m - target.translation_m) * 100.0),
        (searched[-1] - started) if searched else 0.0, time.monotonic() - started, runner_up,
        None if result.assessment is None else result.assessment.verdict.status.value)


def _success(t: InitialTrial, ref: InitialTrial, request: InitialRequest) -> bool:
    if t.rotation_err_deg is None or t.translation_err_cm is None or ref.rotation_err_deg is None \
            or ref.translation_err_cm is None:
        return False
    return (t.rotation_err_deg <= ref.rotation_err_deg + request.tolerance_rot_deg
            and t.translation_err_cm <= ref.translation_err_cm + request.tolerance_trans_cm)


def run_initial(request: InitialRequest) -> dict[str, Any]:
    """Writes OUT/initial.yaml and returns its content; needs a dataset with ground truth."""
    started = time.monotonic()
    s = request.settings
    searches = s.request.model_copy(update={"options": s.request.options.model_copy(update={"method": Method.GMM})})
    dataset, _ = open_for(replace(s, request=searches))
    truth = dataset.ground_truth
    if truth is None:
        raise RigdError(f"{dataset.root}: the initial-guess evaluation needs ground_truth.yaml (a simulated dataset)")
    out = s.out(dataset, "initial.yaml")
    base = base_rotation(dataset.rig.camera.models()[0])
    ref_start = random_starts(truth, 1, 5.0, 0.1, s.seed + 1)[0]
    mounts = _mounts(request, base)
    tasks = [_Task(-1, None, ref_start, truth)] + [_Task(i, m, None, truth) for i, m in enumerate(mounts)]
    with trial_runner(s, searches) as workers:
        where = where_run(s, workers)
        done = sorted(workers.run(_run_trial, tasks, "initial guess", s.progress), key=lambda r: r.index)
    ref, trials = done[0], done[1:]
    ok = [_success(t, ref, request) for t in trials]
    search_s = [t.search_s for t in trials if t.error is None]
    verdicts = [t.verdict for t in trials if t.verdict is not None]
    report = {
        "protocol": "initial", "dataset": str(dataset.root), "pairs": len(dataset),
        "settings": {"trials": request.trials, "seed": s.seed, **where, "yaw_deg": request.yaw_deg,
                     "tilt_deg": request.tilt_deg, "lever_m": request.lever_m,
                     "tolerance_rot_deg": request.tolerance_rot_deg,
                     "tolerance_trans_cm": request.tolerance_trans_cm, "grid": SearchOptions().__dict__},
        "reference": {"rotation_err_deg": ref.rotation_err_deg, "translation_err_cm": ref.translation_err_cm,
                      "wall_time_s": round(ref.total_s, 2), "error": ref.error},
        "success": int(sum(ok)), "success_rate": float(np.mean(ok)) if ok else 0.0,
        "verdicts": {v: verdicts.count(v) for v in sorted(set(verdicts))},
        "trusted_but_wrong": sum(1 for t, good in zip(trials, ok, strict=True) if not good and t.verdict == "trusted"),
        "median_search_s": float(np.median(search_s)) if search_s else None,
        "max_search_s": float(np.max(search_s)) if search_s else None,
        "median_total_s": float(np.median([t.total_s for t in trials])) if trials else None,
        "wall_time_s": round(time.monotonic() - started, 2),
        "trials": [{"index": t.index, "mount_rpy_deg": list(t.mount_rpy_deg), "rotation_err_deg": t.rotation_err_deg,
                    "translation_err_cm": t.translation_err_cm, "search_s": round(t.search_s, 2),
                    "total_s": round(t.total_s, 2), "runner_up_deg": t.runner_up_deg, "success": good,
                    "verdict": t.verdict, "error": t.error} for t, good in zip(trials, ok, strict=True)],
    }
    out.mkdir(parents=True, exist_ok=True)
    write_yaml(out / "initial.yaml", report)
    return report
