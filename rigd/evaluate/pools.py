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
from typing import Any, TypeVar

import cv2

from rigd.calibration.request import CalibrationRequest
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


def _init_worker(request: CalibrationRequest) -> None:
    global _STATE
    cv2.setNumThreads(1)  # one trial per core: the workers already occupy the cores
    _STATE = extract_state(request)


def _in_pool(fn: Callable[[WorkerState, T], R], task: T) -> R:
    if _STATE is None:
        raise RigdError("evaluation worker was not initialised")
    return fn(_STATE.checked(), task)


class LocalPool:
    """``workers`` processes on this machine, each extracting the features once in its initializer."""

    def __init__(self, request: CalibrationRequest) -> None:
        # spawn, not fork: a child forked from a process whose OpenCV/BLAS threads hold locks can deadlock on
        # its first cv2 call (seen: the test suite's process hung in cv2.setNumThreads in every forked worker).
        self._executor = ProcessPoolExecutor(max_workers=request.workers, initializer=_init_worker,
                                             initargs=(request,), mp_context=multiprocessing.get_context("spawn"))
        self.workers = request.workers

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


class InProcess:
    """One worker: this process, with the features extracted once (no spawn, no copy: ``--workers 1``)."""

    workers = 1

    def __init__(self, request: CalibrationRequest) -> None:
        self._state = extract_state(request)

    def run(self, fn: Callable[[WorkerState, T], R], tasks: Sequence[T], desc: str, progress: bool) -> list[R]:
        state = self._state.checked()
        return collect((_Done(fn(state, t)) for t in tasks), len(tasks), desc, progress)

    def close(self) -> None:
        del self._state


class _Done:
    """A result as :func:`collect` takes a finished future's."""

    def __init__(self, value: Any) -> None:
        self._value = value

    def result(self) -> Any:
        return self._value


@contextmanager
def trial_runner(s: EvaluationSettings, request: CalibrationRequest | None = None) -> Iterator[TrialRunner]:
    """The local process pool, or with ``s.cluster`` the Dask cluster at that address; every run solves
    ``request`` (default ``s.request``)."""
    request = s.request if request is None else request
    runner: TrialRunner
    if s.cluster is None:
        runner = InProcess(request) if request.workers == 1 else LocalPool(request)
    else:
        try:
            from rigd.evaluate.cluster import DaskCluster  # distributed is the [cluster] extra: imported only here
        except ModuleNotFoundError as exc:
            if exc.name not in ("distributed", "dask"):
                raise
            raise RigdError(f"--cluster needs Dask distributed ({exc}): pip install 'rigd[cluster]'") from exc
        runner = DaskCluster(s.cluster, s.cluster_timeout_s, request.model_copy(
            update={"dataset": request.dataset.resolve()}))
    try:
        yield runner
    finally:
        runner.close()


def where_run(s: EvaluationSettings, runner: TrialRunner) -> dict[str, Any]:
    """The report's record of the workers: their number and the cluster's address (None: local processes)."""
    return {"workers": runner.workers, "cluster": s.cluster}
