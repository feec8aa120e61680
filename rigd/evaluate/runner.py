"""Where an evaluation's trials run: worker processes on this machine, or a Dask cluster
(:mod:`rigd.evaluate.cluster`).

Each worker process extracts the dataset's edge features once (with the field evaluator's filtered maps about
170 MB per 1024x512 pair: sending them with every task would cost more than a calibration), then runs
calibrations on them. Memory therefore grows with the worker processes times the pairs.
"""

from __future__ import annotations

import multiprocessing
import typing
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

from calib.assess import TrustOptions
from calib.methods import Method
from calib.pipeline import CalibParams
from rigd.errors import RigdError
from rigd.evaluate.trials import EvaluationSettings, WorkerState, collect, extract_state

T = TypeVar("T")
R = TypeVar("R")


class TrialRunner(typing.Protocol):
    """Where the trials run. Every worker holds one dataset's features (a :class:`WorkerState`, extracted once)
    and runs ``fn(state, task)``; only tasks and results travel."""

    workers: int  # how many workers, for the report

    def run(self, fn: Callable[[WorkerState, T], R], tasks: Sequence[T], desc: str, progress: bool) -> list[R]:
        """``fn`` over ``tasks``, results in completion order."""
        ...

    def close(self) -> None: ...


_STATE: WorkerState | None = None  # one per local pool process, set by _init_worker


def _init_worker(root: Path, params: CalibParams, trust: TrustOptions | None, method: Method) -> None:
    global _STATE
    _STATE = extract_state(root, params, trust, method)


def _in_pool(fn: Callable[[WorkerState, T], R], task: T) -> R:
    if _STATE is None:
        raise RigdError("evaluation worker was not initialised")
    return fn(_STATE.checked(), task)


class LocalPool:
    """``workers`` processes on this machine, each extracting the features once in its initializer."""

    def __init__(self, root: Path, params: CalibParams, workers: int, trust: TrustOptions | None,
                 method: Method = Method.RIGD) -> None:
        # spawn, not fork: a child forked from a process whose OpenCV/BLAS threads hold locks can deadlock on
        # its first cv2 call (seen: the test suite's process hung in cv2.setNumThreads in every forked worker).
        self._executor = ProcessPoolExecutor(max_workers=workers, initializer=_init_worker,
                                             initargs=(root, params, trust, method),
                                             mp_context=multiprocessing.get_context("spawn"))
        self.workers = workers

    def run(self, fn: Callable[[WorkerState, T], R], tasks: Sequence[T], desc: str, progress: bool) -> list[R]:
        futures = [self._executor.submit(_in_pool, fn, t) for t in tasks]
        try:
            return collect(as_completed(futures), len(futures), desc, progress)
        except BrokenProcessPool as exc:
            raise RigdError(f"{desc}: a worker process died ({exc}); fewer --workers need less memory") from exc
        finally:
            for fut in futures:
                fut.cancel()

    def close(self) -> None:
        self._executor.shutdown(cancel_futures=True)


@contextmanager
def trial_runner(s: EvaluationSettings, root: Path, params: CalibParams, trust: TrustOptions | None,
                 method: Method = Method.RIGD) -> Iterator[TrialRunner]:
    """The local process pool, or with ``s.cluster`` the Dask cluster at that address; every run solves with
    ``method``."""
    runner: TrialRunner
    if s.cluster is None:
        runner = LocalPool(root, params, s.workers, trust, method)
    else:
        try:
            from rigd.evaluate.cluster import DaskCluster  # distributed is the [cluster] extra: imported only here
        except ModuleNotFoundError as exc:
            if exc.name not in ("distributed", "dask"):
                raise
            raise RigdError(f"--cluster needs Dask distributed ({exc}): pip install 'rigd[cluster]'") from exc
        runner = DaskCluster(s.cluster, s.cluster_timeout_s, root.resolve(), params, trust, method)
    try:
        yield runner
    finally:
        runner.close()


def where_run(s: EvaluationSettings, runner: TrialRunner) -> dict[str, Any]:
    """The report's record of the workers: their number and the cluster's address (None: local processes)."""
    return {"workers": runner.workers, "cluster": s.cluster}
