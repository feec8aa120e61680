"""calib.handed: calls still queued behind a busy worker are taken back and run here; running ones are
awaited, never run twice; results come in the order the calls were handed. Shared calls (the assessments'
restarts) are taken one at a time by this process and every worker."""

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from calib.errors import CalibError
from calib.handed import collect, hand, shared_calls


def _record(ran: list[tuple[int, str]], value: int, gate: threading.Event | None = None) -> int:
    if gate is not None:
        assert gate.wait(60), "the test never opened the gate"
    ran.append((value, threading.current_thread().name))
    return value * 10


def test_queued_calls_are_taken_back_and_run_here_the_last_first():
    ran: list[tuple[int, str]] = []
    gate = threading.Event()
    counts: list[int] = []
    with ThreadPoolExecutor(1, thread_name_prefix="worker") as pool:
        busy = hand(pool, _record, ran, 0, gate)  # the only worker waits for the gate: the rest stay queued
        handed = [busy, *(hand(pool, _record, ran, v) for v in (1, 2, 3))]

        def on_done(count: int) -> None:
            counts.append(count)
            if count == 3:  # every queued call ran here while the worker was busy: let it finish
                gate.set()

        results = collect(handed, on_done)
    here = threading.current_thread().name
    assert results == [0, 10, 20, 30]
    assert ran[:3] == [(3, here), (2, here), (1, here)]
    assert ran[3][0] == 0 and ran[3][1].startswith("worker")
    assert counts == [1, 2, 3, 4]


def test_without_a_pool_the_calls_run_here_in_order():
    ran: list[tuple[int, str]] = []
    results = collect([hand(None, _record, ran, v) for v in (1, 2, 3)])
    assert results == [10, 20, 30]
    assert [v for v, _ in ran] == [1, 2, 3]
    assert {name for _, name in ran} == {threading.current_thread().name}


def _timed_call(main_thread_s: float, fail_on_worker: bool = False, worker_s: float = 0.01):
    """A stand-in for one call: its start's first entry as its result, taking ``main_thread_s`` on the
    calling thread and ``worker_s`` on the executor's."""
    def solve(feats, start, *rest):
        on_main = threading.current_thread() is threading.main_thread()
        if not on_main and fail_on_worker:
            raise CalibError("worker call failed")
        time.sleep(main_thread_s if on_main else worker_s)
        return ("main" if on_main else "worker", float(start[0]))
    return solve


def test_calls_are_taken_one_at_a_time_so_the_faster_side_takes_the_rest() -> None:
    solve = _timed_call(0.5)
    starts = [np.full(6, float(i)) for i in range(4)]
    with ThreadPoolExecutor(1) as executor:
        runs = shared_calls(executor, solve, [([], s) for s in starts])
    assert [value for _, value in runs] == [0.0, 1.0, 2.0, 3.0]  # in the starts' order, whoever ran them
    assert [side for side, _ in runs].count("main") == 1  # fixed halves would have given this process two


def test_a_call_that_fails_in_the_worker_raises_here() -> None:
    solve = _timed_call(0.05, fail_on_worker=True)
    starts = [np.full(6, float(i)) for i in range(4)]
    with ThreadPoolExecutor(1) as executor, pytest.raises(CalibError, match="worker call failed"):
        shared_calls(executor, solve, [([], s) for s in starts])


def test_this_process_works_while_the_worker_ends_its_last_call() -> None:
    solve = _timed_call(0.01, worker_s=0.5)
    starts = [np.full(6, float(i)) for i in range(4)]
    waited = []
    with ThreadPoolExecutor(1) as executor:
        runs = shared_calls(executor, solve, [([], s) for s in starts], lambda: waited.append(True))
    assert [side for side, _ in runs].count("worker") == 1 and waited == [True]


class _Workers(ThreadPoolExecutor):
    """A pool that says how many workers it has, as the application's FeaturePool does."""

    @property
    def workers(self) -> int:
        return self._max_workers


def test_every_worker_of_the_pool_takes_calls_beside_this_process() -> None:
    """Four calls, three workers: each call waits until all four run at once, which only happens when
    this process and every worker took one (with one worker fed, the barrier breaks)."""
    together = threading.Barrier(4, timeout=10)

    def solve(feats, start, *rest):
        together.wait()
        return threading.current_thread().name, float(start[0])

    starts = [np.full(6, float(i)) for i in range(4)]
    with _Workers(3, thread_name_prefix="worker") as executor:
        runs = shared_calls(executor, solve, [([], s) for s in starts])
    assert [value for _, value in runs] == [0.0, 1.0, 2.0, 3.0]
    assert len({name for name, _ in runs}) == 4


@pytest.mark.parametrize("pooled", [False, True])
def test_progress_counts_each_call_as_it_ends_wherever_it_ran(pooled) -> None:
    solve = _timed_call(0.01, worker_s=0.05)
    starts = [np.full(6, float(i)) for i in range(4)]
    seen: list[tuple[int, int]] = []
    with ThreadPoolExecutor(1) as executor:
        runs = shared_calls(executor if pooled else None, solve, [([], s) for s in starts],
                            on_progress=lambda done, total: seen.append((done, total)))
    assert len(runs) == 4
    assert seen == [(0, 4), (1, 4), (2, 4), (3, 4), (4, 4)]
