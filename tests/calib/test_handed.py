"""calib.handed: calls still queued behind a busy worker are taken back and run here; running ones are
awaited, never run twice; results come in the order the calls were handed."""

import threading
from concurrent.futures import ThreadPoolExecutor

from calib.handed import collect, hand


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
