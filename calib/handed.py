"""Calls handed to the application's process pool that this process takes back rather than wait for them.

The independent solves of a calibration (the alternative schedules, the global search's runner-up, the
search's per-pair grids) are submitted to the pool's workers while this process does its own share. When it
is done and a call is still queued behind a busy worker, waiting would leave a core idle: it cancels the call
and runs it here instead. Each call is deterministic, so where it ran never changes its result (the field
bands give the same values whichever process built them: calib.fields).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future, as_completed
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

T = TypeVar("T")


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
