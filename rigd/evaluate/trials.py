"""What every evaluation protocol shares: its settings, one calibration's task and result, and the state a worker
keeps for all its trials: one dataset's features, extracted once for the calibration request every trial solves
(the request `rigd calibrate` would build, read against the dataset by the same rigd.calibration.request.resolve;
a trial replaces only the start and the pairs). Where the trials run is :mod:`rigd.evaluate.pools`."""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TypeVar

from tqdm import tqdm

from calib.errors import CalibError
from calib.evaluate import OutlierRule
from calib.geometry import Transform
from calib.methods import Method, SolveRequest, solve
from calib.pipeline import CalibResult
from rigd.calibration.features import Features, features_for
from rigd.calibration.job import prepare
from rigd.calibration.request import CalibrationRequest, Resolved, Start, TransformIn
from rigd.dataset import Dataset
from rigd.errors import RigdError
from rigd.outdir import claim_output_files


@dataclass(frozen=True)
class EvaluationSettings:
    """What the protocols share. ``request``: what every run solves (its dataset, options and ``assess``; its
    start, ``Start.GIVEN`` with a transform or the rig file's, is the start of the reference calibration
    (convergence without ground truth) or of every run (precision))."""

    request: CalibrationRequest
    seed: int = 0
    out_dir: Path | None = None  # None: DATASET/evaluation
    outlier_rule: OutlierRule = OutlierRule.PER_PARAMETER
    progress: bool = True  # a tqdm bar on stderr
    cluster: str | None = None  # a Dask scheduler's address (tcp://host:8786): run there instead of `workers`
    cluster_timeout_s: float = 10.0  # for connecting to it and for its first worker
    overwrite: bool = False  # write over an earlier run's report and plot of the same protocol in the same folder

    @property
    def dataset(self) -> Path:
        return self.request.dataset

    @property
    def workers(self) -> int:
        return self.request.workers

    def out(self, dataset: Dataset, *names: str) -> Path:
        """The output folder (``out_dir``, default DATASET/evaluation), once no earlier run's ``names`` there stand
        in the way (rigd.outdir.claim_output_files: refused unless ``overwrite``)."""
        out = Path(self.out_dir) if self.out_dir is not None else dataset.root / "evaluation"
        claim_output_files([out / n for n in names], overwrite=self.overwrite)
        return out

    def initial(self, dataset: Dataset) -> Transform | None:
        """The start the settings give: the request's transform, else the rig file's guess."""
        if self.request.initial is not None:
            return self.request.initial.transform
        return dataset.rig.initial_guess


def runs_request(request: CalibrationRequest) -> CalibrationRequest:
    """``request`` as its runs solve it: every run starts from a start of its own, so the request is read as one
    given a start (the method a start allows, rigd.calibration.request._method), at the working width."""
    start = request.initial or TransformIn.of(Transform.identity())
    return request.model_copy(update={"start": Start.GIVEN, "initial": start})


def gmm_request(request: CalibrationRequest) -> CalibrationRequest:
    """``request`` with the GMM and no assessment: what a check (rigd check) and the global search work on."""
    options = request.options.model_copy(update={"method": Method.GMM})
    return request.model_copy(update={"options": options, "assess": False})


@dataclass(frozen=True)
class Task:
    """One calibration to run: its start and the pairs it uses."""

    index: int
    start: Transform
    pairs: tuple[int, ...]


@dataclass(frozen=True)
class Run:
    """One calibration: its pairs, start and result (None with ``error`` when it raised)."""

    index: int
    pairs: tuple[int, ...]
    start: Transform
    result: Transform | None
    error: str | None
    final_cost: float | None
    iterations: int
    wall_s: float
    sigma: tuple[float, ...] | None = None  # per-axis sigma, deg x3 and cm x3 (calib.assess)
    verdict: str | None = None
    # nid-assessed: the edges' disagreement d / sqrt(2), deg x3 and cm x3 (calib.assess.with_cross_check)
    cross_check: tuple[float, ...] | None = None


@dataclass(frozen=True)
class WorkerState:
    """What a worker keeps for all its trials: the request read against the dataset (``solve``), the features it
    needs of every pair (one per view of each pair, view by view), the dataset's pair count, or why there are
    none (raised by every task, so the parent reports it)."""

    solve: SolveRequest | None
    features: Features
    n_pairs: int
    error: str | None = None

    def checked(self) -> WorkerState:
        """``self``, or the feature extraction's error raised."""
        if self.error is not None:
            raise RigdError(self.error)
        return self

    def calibrate(self, start: Transform | None, pairs: Sequence[int], **changes: Any) -> CalibResult:
        """The request solved from ``start`` on ``pairs`` (``changes``: other fields of the solve replaced)."""
        assert self.solve is not None
        gmm, photo = self.features.gmm, self.features.photo
        return solve(replace(self.solve, initial=start, **changes),
                     feats=None if gmm is None else of_pairs(gmm, self.n_pairs, pairs),
                     photo=None if photo is None else of_pairs(photo, self.n_pairs, pairs))


def extract_state(request: CalibrationRequest) -> WorkerState:
    """The features ``request``'s runs need (:func:`runs_request`), or the reason there are none."""
    try:
        dataset, resolved = prepare(runs_request(request))
        features = features_for(dataset, resolved.solve)
    except (RigdError, CalibError) as exc:
        return WorkerState(None, Features(None, None, None), 0, f"{request.dataset}: {exc}")
    return WorkerState(resolved.solve, features, len(dataset))


def open_for(settings: EvaluationSettings) -> tuple[Dataset, Resolved]:
    """The dataset and the request its runs solve, as the workers read them."""
    return prepare(runs_request(settings.request))


def run_task(state: WorkerState, task: Task) -> Run:
    """One calibration of ``task``: a start that sees nothing is a failed run, counted as not converged."""
    started = time.monotonic()
    try:
        result = state.calibrate(task.start, task.pairs)
    except CalibError as exc:
        return Run(task.index, task.pairs, task.start, None, str(exc), None, 0, time.monotonic() - started)
    iterations = sum(level.iterations for level in result.optim.levels)
    a = result.assessment
    return Run(task.index, task.pairs, task.start, result.T_camera_lidar, None, result.optim.final_cost, iterations,
               time.monotonic() - started, None if a is None else tuple(float(v) for v in a.uncertainty.sigma),
               None if a is None else a.verdict.status.value,
               None if a is None or a.uncertainty.cross_check is None else tuple(map(float, a.uncertainty.cross_check)))


Item = TypeVar("Item")


def of_pairs(items: Sequence[Item], n_pairs: int, pairs: Sequence[int]) -> list[Item]:
    """Every view of ``pairs`` from a dataset's per-view list ``items`` (``n_pairs`` pairs, view by view), in the
    same order."""
    views = len(items) // n_pairs
    return [items[v * n_pairs + i] for v in range(views) for i in pairs]


def collect(done: Iterable[Any], total: int, desc: str, progress: bool) -> list[Any]:
    """The results of futures as ``done`` yields them, with a progress bar on stderr."""
    return [f.result() for f in tqdm(done, total=total, desc=desc, unit="run", file=sys.stderr,
                                     disable=not progress)]
