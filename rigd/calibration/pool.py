"""The worker processes of one calibration, which keep the pairs' features they were sent.

A solve in a worker (the alternative schedule, half the trust restarts) samples the field maps of every pair,
and those are built on demand where the samples land: seconds of work that pickling leaves behind (an
``EdgeFields`` travels without its bands). This pool sends a features list to a worker once; a later task
with the same list goes to a worker that holds it, if one is free, and uses that copy with the bands it
built. Results do not depend on where a task runs: a band's values do not depend on what was sampled before.
A worker holds what it was sent until the pool closes, at the end of the calibration, or until its parent is
gone: a worker whose parent was killed exits rather than finish a solve nobody will read.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import importlib
import itertools
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable
from concurrent.futures import CancelledError, Executor, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, NamedTuple

from calib.gmm import PairFeatures
from rigd.errors import WorkerLostError
from rigd.lifetime import exit_with_parent

EXIT_PARENT_GONE = 3  # a pool worker's exit code when its parent died
_START_S = 30.0  # abort() waits this long for a worker still starting to say its pid

_HELD: dict[int, list[PairFeatures]] = {}  # in a worker: the features lists it was sent, by token


class _Send(NamedTuple):
    token: int
    feats: list[PairFeatures]


class _Held(NamedTuple):
    token: int


def _resolve(arg: Any) -> Any:
    if isinstance(arg, _Send):
        _HELD[arg.token] = arg.feats
        return arg.feats
    if isinstance(arg, _Held):
        return _HELD[arg.token]
    return arg


def _start_worker(parent_pid: int, initializer: Callable[..., None] | None, initargs: tuple[Any, ...]) -> None:
    exit_with_parent(parent_pid, EXIT_PARENT_GONE)
    if initializer is not None:
        initializer(*initargs)


def preload(*modules: str) -> None:
    """A worker initializer: import ``modules`` (what the worker's tasks will need) before any task arrives."""
    for module in modules:
        importlib.import_module(module)


def _call(fn: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    return fn(*(_resolve(a) for a in args), **kwargs)


def _is_features(arg: Any) -> bool:
    """A whole set's features: the global search's one-pair lists are made per task and never come back, so
    holding them would only fill the workers (a one-pair set is sent each time, as before)."""
    return isinstance(arg, list) and len(arg) > 1 and all(isinstance(f, PairFeatures) for f in arg)


class _Task(NamedTuple):
    fn: Callable[..., Any]
    args: tuple[Any, ...]
    kwargs: dict[str, Any]
    future: Future[Any]  # the caller's


class FeaturePool(Executor):
    """``workers`` spawned single-process executors. Tasks wait here, in order, until a worker is free (a task
    is never queued behind another in a busy worker while a second worker idles: ten places' edges split
    in fixed halves left one core idle ~3 s of 17 on the Ford head); a task with a features list
    (``list[PairFeatures]``) goes to a free worker that already holds it, if there is one."""

    def __init__(self, workers: int, initializer: Callable[..., None] | None = None,
                 initargs: tuple[Any, ...] = ()) -> None:
        context = multiprocessing.get_context("spawn")
        start = (os.getpid(), initializer, initargs)
        self._workers = [ProcessPoolExecutor(1, mp_context=context, initializer=_start_worker, initargs=start)
                         for _ in range(workers)]
        # Spawned now, not at the first task: their imports overlap the caller's work. Their pids, for abort().
        self._pids = [w.submit(os.getpid) for w in self._workers]
        self._busy = [False] * workers
        self._queue: collections.deque[_Task] = collections.deque()
        self._held: dict[int, tuple[list[PairFeatures], dict[int, int]]] = {}  # id -> (list, worker -> token)
        self._tokens = itertools.count()
        self._lock = threading.Lock()  # completions arrive on the executors' threads
        self._settled = threading.Condition(self._lock)  # notified when a task ends
        self._closed = False

    @property
    def workers(self) -> int:
        """How many processes take tasks (calib.assess feeds each of them restarts)."""
        return len(self._workers)

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        future: Future[Any] = Future()
        with self._lock:
            if self._closed:
                raise RuntimeError("cannot submit to a pool that is shut down")
            self._queue.append(_Task(fn, args, kwargs, future))
        self._dispatch()
        return future

    def _dispatch(self) -> None:
        """Start queued tasks, in order, while a worker is free."""
        while True:
            with self._lock:
                free = [w for w, busy in enumerate(self._busy) if not busy]
                if not self._queue or not free:
                    self._settled.notify_all()  # a shutdown waits for an empty queue
                    return
                task = self._queue.popleft()
                if not task.future.set_running_or_notify_cancel():
                    continue  # cancelled while it waited
                worker, sent = self._route(task.args, free)
                self._busy[worker] = True
            try:
                inner = self._workers[worker].submit(_call, task.fn, sent, task.kwargs)
            except BrokenProcessPool:  # its process died after its last task: this one fails, the worker is free
                with self._lock:
                    self._busy[worker] = False
                task.future.set_exception(_lost(worker))
                continue
            inner.add_done_callback(functools.partial(self._done, worker, task.future))

    def _route(self, args: tuple[Any, ...], free: list[int]) -> tuple[int, tuple[Any, ...]]:
        """The free worker for a task with ``args``, and the arguments to send it (a features list it holds
        travels as a token)."""
        feats_at = next((i for i, a in enumerate(args) if _is_features(a)), None)
        if feats_at is None:
            return free[0], args
        feats = args[feats_at]
        holders = self._held.get(id(feats), (None, {}))[1]
        worker = next((w for w in free if w in holders), free[0])
        sent = list(args)
        if worker in holders:
            sent[feats_at] = _Held(holders[worker])
        else:
            token = next(self._tokens)
            sent[feats_at] = _Send(token, feats)
            self._held.setdefault(id(feats), (feats, {}))[1][worker] = token  # keeps feats alive: ids stay
        return worker, tuple(sent)

    def _done(self, worker: int, outer: Future[Any], inner: Future[Any]) -> None:
        """Count the worker free, then complete the caller's future (a task submitted as soon as a result
        arrives finds the worker that holds its features free) and start the next queued task."""
        with self._lock:
            self._busy[worker] = False
        if inner.cancelled():  # the workers were shut down with cancel_futures: the caller's task is running
            outer.set_exception(CancelledError(f"worker {worker} was shut down before the task ran"))
        elif isinstance(error := inner.exception(), BrokenProcessPool):
            outer.set_exception(_lost(worker))
        elif error is not None:
            outer.set_exception(error)
        else:
            outer.set_result(inner.result())
        self._dispatch()

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        with self._lock:
            self._closed = True
            if cancel_futures or not wait:  # nothing would start the queued tasks once the workers are down
                while self._queue:
                    self._queue.popleft().future.cancel()
            while wait and (self._queue or any(self._busy)):
                self._settled.wait()
        for w in self._workers:
            w.shutdown(wait=wait, cancel_futures=cancel_futures)

    def abort(self) -> None:
        """Stop at once: queued tasks cancelled, the workers killed mid-task (the caller has failed or been
        interrupted and will read no result; a shutdown would wait for each running task to end, 22 s on the
        Ford head after a SIGINT to this process alone)."""
        for started in self._pids:
            with contextlib.suppress(TimeoutError, BrokenProcessPool, ProcessLookupError):  # never started, or gone
                pid = started.result(timeout=_START_S)
                if _is_child(pid):  # not a stranger that took a dead worker's pid
                    os.kill(pid, signal.SIGKILL)
        self.shutdown(wait=False, cancel_futures=True)


def _is_child(pid: int) -> bool:
    """Whether ``pid`` is still this process's unreaped child (as rigd.api.worker_process asks it)."""
    try:
        os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
    except ChildProcessError:  # reaped: the pid may be a stranger's now
        return False
    return True


def _lost(worker: int) -> WorkerLostError:
    return WorkerLostError(f"worker process {worker + 1} of the calibration ended abruptly (killed, or by the kernel "
                           "for want of memory: its log says which); nothing was written: run it again")
