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

import functools
import itertools
import multiprocessing
import os
import threading
from collections.abc import Callable
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from typing import Any, NamedTuple

from calib.gmm import PairFeatures
from rigd.lifetime import exit_with_parent

EXIT_PARENT_GONE = 3  # a pool worker's exit code when its parent died

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


def _call(fn: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    return fn(*(_resolve(a) for a in args), **kwargs)


def _is_features(arg: Any) -> bool:
    """A whole set's features: the global search's one-pair lists are made per task and never come back, so
    holding them would only fill the workers (a one-pair set is sent each time, as before)."""
    return isinstance(arg, list) and len(arg) > 1 and all(isinstance(f, PairFeatures) for f in arg)


class FeaturePool(Executor):
    """``workers`` spawned single-process executors. A task goes to the least busy worker, except that a
    task with a features list (``list[PairFeatures]``) some free worker already holds goes there."""

    def __init__(self, workers: int, initializer: Callable[..., None] | None = None,
                 initargs: tuple[Any, ...] = ()) -> None:
        context = multiprocessing.get_context("spawn")
        start = (os.getpid(), initializer, initargs)
        self._workers = [ProcessPoolExecutor(1, mp_context=context, initializer=_start_worker, initargs=start)
                         for _ in range(workers)]
        self._busy = [0] * workers
        self._held: dict[int, tuple[list[PairFeatures], dict[int, int]]] = {}  # id -> (list, worker -> token)
        self._tokens = itertools.count()
        self._lock = threading.Lock()  # completions are counted on the executors' threads

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        feats_at = next((i for i, a in enumerate(args) if _is_features(a)), None)
        holders = {} if feats_at is None else self._held.get(id(args[feats_at]), (None, {}))[1]
        with self._lock:
            free_holders = [w for w in holders if self._busy[w] == 0]
            worker = free_holders[0] if free_holders else min(range(len(self._workers)), key=self._busy.__getitem__)
            self._busy[worker] += 1
        sent = list(args)
        if feats_at is not None:
            feats = args[feats_at]
            if worker in holders:
                sent[feats_at] = _Held(holders[worker])
            else:
                token = next(self._tokens)
                sent[feats_at] = _Send(token, feats)
                self._held.setdefault(id(feats), (feats, {}))[1][worker] = token  # keeps feats alive: ids stay
        future = self._workers[worker].submit(_call, fn, tuple(sent), kwargs)
        future.add_done_callback(functools.partial(self._done, worker))
        return future

    def _done(self, worker: int, _: Future[Any]) -> None:
        with self._lock:
            self._busy[worker] -= 1

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        for w in self._workers:
            w.shutdown(wait=wait, cancel_futures=cancel_futures)
