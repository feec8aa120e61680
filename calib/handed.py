"""Calls handed to the application's process pool, the two ways a calibration shares its independent work.

:func:`hand` / :func:`collect`: the independent solves of a calibration (the alternative schedules, the global
search's runner-up, the search's per-pair grids, the elevation profile) are submitted to the pool's workers while
this process does its own share. When it is done and a call is still queued behind a busy worker, waiting would
leave a core idle: it cancels the call and runs it here instead.

:func:`share`: the restarts of an assessment (the GMM's and NID's), which differ in length: this process and each
worker take the next one not yet taken when they finish one.

Each call is deterministic, so where it ran never changes its result (the field bands give the same values
whichever process built them: calib.fields).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future, as_completed
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

T = TypeVar("T")
Progress = Callable[[int, int], None]  # (done, total) of a set of calls


@dataclass(frozen=True)
class Handed(Generic[T]):
    """One call: ``future`` its submission to a pool (None: no pool, it runs when collected)."""

    future: Future[T] | None
    call: Callable[[], T]


def hand(executor: Executor | None, fn: Callable[..., T], *args: Any) -> Handed[T]:
    """``fn(*args)`` submitted to ``executor`` now (None: kept to run when collected)."""
    future = executor.submit(fn, *args) if executor is not None else None
    return Handed(future, functools.partial(fn, *args))


def collect(handed: Sequence[Handed[T]], on_done: Callable[[int], None] | None = None) -> list[T]:
    """The results of ``handed``, in its order. The calls no worker has started are taken back and run here,
    the last first (workers take them from the front); then the running ones are awaited. Without a pool the
    calls run here in order. ``on_done(count)`` after each result."""
    results: dict[int, T] = {}

    def done(i: int, value: T) -> None:
        results[i] = value
        if on_done is not None:
            on_done(len(results))

    pooled = any(h.future is not None for h in handed)
    for i in reversed(range(len(handed))) if pooled else range(len(handed)):
        future = handed[i].future
        if future is None or future.cancel():
            done(i, handed[i].call())
    running = {h.future: i for i, h in enumerate(handed) if h.future is not None and i not in results}
    for future in as_completed(running):
        done(running[future], future.result())
    return [results[i] for i in range(len(handed))]


def share(executor: Executor | None, calls: Sequence[Callable[[], T]], remote: Sequence[Callable[[], Future[T]]],
          while_waiting: Callable[[], None] | None = None, on_done: Callable[[int], None] | None = None) -> list[T]:
    """The results of ``calls``, in their order. With ``executor``, this process and each of its workers
    (``executor.workers``, else one) take the next call not yet taken when they finish one, so none waits while
    calls remain (restarts differ in length: split in fixed halves, one side waited ~4 s of a 14 s phase on the
    Ford head); ``remote[i]()`` submits call ``i`` to the pool (and may route it to the worker that holds its
    features). The pool has one worker fewer than the cores, so a worker per core takes calls beside this
    process. ``while_waiting`` runs here when no call is left to take but a worker's last one has not ended.
    ``on_done(count)`` after each result, in whichever thread it arrived (one at a time)."""
    results: list[T | None] = [None] * len(calls)
    order = iter(range(len(calls)))
    lock = threading.Lock()

    finished = 0

    def take() -> int | None:
        with lock:
            return next(order, None)

    def keep(i: int, value: T) -> None:
        nonlocal finished
        with lock:
            results[i] = value
            finished += 1
            if on_done is not None:
                on_done(finished)

    def feed() -> None:  # on a thread per worker: one call at a time, each when its previous ended
        while (i := take()) is not None:
            keep(i, remote[i]().result())

    failed: list[BaseException] = []
    n_feeders = 0 if executor is None else max(1, int(getattr(executor, "workers", 1)))
    feeders = [threading.Thread(target=_capturing, args=(feed, failed), daemon=True) for _ in range(n_feeders)]
    for feeder in feeders:
        feeder.start()
    try:
        while (i := take()) is not None:
            keep(i, calls[i]())
        if any(f.is_alive() for f in feeders) and while_waiting is not None:
            while_waiting()
    finally:
        with lock:  # on an error here, the workers take no further call
            for _ in order:
                pass
        for feeder in feeders:
            feeder.join()
    if failed:
        raise failed[0]
    return [r for r in results if r is not None]


def shared_calls(executor: Executor | None, fn: Callable[..., T], args: Sequence[tuple[object, ...]],
                 while_waiting: Callable[[], None] | None = None,
                 on_progress: Progress | None = None) -> list[T]:
    """:func:`share` of ``fn(*a)`` for each ``a`` of ``args``; ``on_progress(done, total)`` as they start (0)
    and end."""
    calls = [functools.partial(fn, *a) for a in args]
    remote = [] if executor is None else [functools.partial(executor.submit, fn, *a) for a in args]
    if on_progress is None:
        return share(executor, calls, remote, while_waiting)
    on_progress(0, len(calls))
    return share(executor, calls, remote, while_waiting, lambda done: on_progress(done, len(calls)))


def _capturing(fn: Callable[[], None], failed: list[BaseException]) -> None:
    """Run ``fn``; an exception is kept in ``failed`` for the thread that waits for it to raise."""
    try:
        fn()
    except BaseException as error:  # re-raised by the thread that waits for this one
        failed.append(error)
