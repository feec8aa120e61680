"""rigd.calibration.pool: workers keep the features they were sent; a later task with them goes to a free
worker that holds them, and ends where a serial run does; workers whose parent is killed exit."""

import json
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import CancelledError
from pathlib import Path

import numpy as np
import pytest

from calib.assess import TrustOptions
from calib.geometry import Transform
from calib.pipeline import CalibParams, calibrate, with_sigmas
from calib.search import SearchOptions, search_initial
from rigd.calibration.pool import FeaturePool
from rigd.errors import WorkerLostError
from tests.calib.synthetic import TRUTH, make_pair


def _wait_for(path: Path | None, timeout_s: float = 60.0) -> None:
    """Return once ``path`` exists (None: at once): a task held busy until the test lets it go, whatever the
    machine's load, instead of a sleep it might outlast."""
    deadline = time.monotonic() + timeout_s
    while path is not None and not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.01)


def _probe(feats, release: Path | None = None):
    """(worker pid, band bytes the features held when the task began); then builds a band (and waits for
    ``release``)."""
    held = sum(f.fields.nbytes for f in feats)
    feats[0].fields.sample(np.array([[100.0, 100.0]]), np.array([3.0]))
    _wait_for(release)
    return os.getpid(), held


@pytest.fixture(scope="module")
def pairs():
    return [make_pair(1), make_pair(2)]


@pytest.fixture(scope="module")
def pool():
    """One pool of two workers for the tests that keep it running (each worker's start imports calib: ~1 s
    CPU): what they check holds for a pool that has run other tasks, as a calibration's runs many."""
    with FeaturePool(2) as pool:
        yield pool


def test_a_task_with_the_same_features_reuses_the_worker_copy_and_its_bands(pool, tmp_path):
    pairs = [make_pair(1), make_pair(2)]  # a list of its own: the module's pool has not been sent it
    release = tmp_path / "release"
    first_pid, first_held = pool.submit(_probe, pairs).result()
    again_pid, again_held = pool.submit(_probe, pairs).result()
    assert first_held == 0  # pickled without bands
    assert again_pid == first_pid and again_held > 0  # the same copy, with the band the first task built
    slow = pool.submit(_probe, pairs, release)  # the holder is busy: the next goes to the other worker
    other_pid, other_held = pool.submit(_probe, pairs).result()
    release.touch()
    assert other_pid != first_pid and other_held == 0
    assert slow.result()[0] == first_pid
    fresh_pid, fresh_held = pool.submit(_probe, [make_pair(1), make_pair(2)]).result()
    assert fresh_held == 0  # another list is sent, never confused with a held one


def test_a_calibration_in_the_pool_ends_exactly_where_the_serial_one_does(pairs, pool):
    guess = Transform.from_rpy_xyz(TRUTH.rpy_deg + [1.5, -1.0, 1.0], TRUTH.translation_m + [0.03, -0.02, 0.02])
    trust = TrustOptions(restarts=2)  # one here, one in the worker that ran the alternative schedule
    params = with_sigmas(CalibParams(), (4.0, 2.0))  # two levels: an alternative schedule still, in half the time
    serial = calibrate(pairs, guess, params, trust=trust)
    pooled = calibrate(pairs, guess, params, trust=trust, executor=pool)
    assert serial.assessment is not None and pooled.assessment is not None
    assert np.array_equal(serial.T_camera_lidar.tau, pooled.T_camera_lidar.tau)
    assert serial.optim.final_cost == pooled.optim.final_cost
    for a, b in zip(serial.assessment.restarts, pooled.assessment.restarts, strict=True):
        assert np.array_equal(a.offset, b.offset) and a.delta_nll == b.delta_nll
    assert serial.assessment.verdict == pooled.assessment.verdict


def test_the_search_in_the_pool_finds_what_the_serial_one_does(pairs, pool, tmp_path):
    coarse = SearchOptions(yaw_step_deg=30.0, tilt_step_deg=30.0)
    serial = search_initial(pairs, np.zeros(3), coarse)
    release = tmp_path / "release"
    busy = [pool.submit(_pid_after, 0.0, release) for _ in range(pool.workers)]  # the grid's tasks wait queued
    workers_busy_when_done = []

    def progress(done: int, total: int) -> None:
        if done == total:  # every pair's grid in: the queued ones were taken back by this process
            workers_busy_when_done.append(not any(f.done() for f in busy))
            release.touch()

    taken_back = search_initial(pairs, np.zeros(3), coarse, progress, pool)
    in_workers = search_initial(pairs, np.zeros(3), coarse, None, pool)
    assert workers_busy_when_done == [True]
    for found in (taken_back, in_workers):
        assert [c.cost for c in found.candidates] == [c.cost for c in serial.candidates]
        for a, b in zip(serial.candidates, found.candidates, strict=True):
            assert np.array_equal(a.tau, b.tau)


PARENT = """
import json, time
from rigd.calibration.pool import FeaturePool
pool = FeaturePool(2)
for _ in range(2):
    pool.submit(time.sleep, 600)  # one long task in each worker
print(json.dumps([p.pid for w in pool._workers for p in w._processes.values()]), flush=True)
time.sleep(600)
"""


def _running(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_workers_exit_when_their_parent_is_killed():
    """Issue 33: a killed calibration worker left its pool processes running (each ~200 MB) until their task
    ended."""
    parent = subprocess.Popen([sys.executable, "-c", PARENT], stdout=subprocess.PIPE, text=True)
    assert parent.stdout is not None
    workers = json.loads(parent.stdout.readline())
    assert len(workers) == 2 and all(_running(pid) for pid in workers)
    parent.send_signal(signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 60  # their tasks run 600 s: far sooner is the parent watch, even on a busy machine
    while alive := [pid for pid in workers if _running(pid)]:
        assert time.monotonic() < deadline, f"pool workers {alive} outlived their parent"
        time.sleep(0.1)


def _pid_after(wait_s: float, release: Path | None = None) -> int:
    time.sleep(wait_s)
    _wait_for(release)
    return os.getpid()


def test_tasks_wait_for_a_free_worker_instead_of_queueing_behind_a_busy_one(pool, tmp_path):
    release = tmp_path / "release"
    long = pool.submit(_pid_after, 0.0, release)  # busy until every short task is done
    short = [pool.submit(_pid_after, 0.05) for _ in range(4)]
    pids = [f.result() for f in short]
    release.touch()
    assert long.result() not in pids  # the free worker took every short task; none waited for the long one
    assert len(set(pids)) == 1


def test_a_shutdown_runs_the_queued_tasks_first():
    pool = FeaturePool(1)
    futures = [pool.submit(_pid_after, 0.05) for _ in range(3)]
    pool.shutdown(wait=True)
    assert all(f.done() and not f.cancelled() for f in futures)


def test_a_killed_worker_fails_its_tasks_by_name_and_the_pool_still_shuts_down():
    """A worker killed (kill -9, the kernel's OOM killer): the task it ran, and any sent to it after, fail with
    an error that says so instead of a bug's traceback, and the pool closes instead of waiting for it forever."""
    pool = FeaturePool(1)
    os.kill(pool.submit(os.getpid).result(), signal.SIGKILL)
    for _ in range(2):  # the first may reach the worker before its death is noticed, the second cannot
        with pytest.raises(WorkerLostError, match="ended abruptly"):
            pool.submit(os.getpid).result(timeout=60)
    closing = threading.Thread(target=pool.shutdown, daemon=True)
    closing.start()
    closing.join(60)
    assert not closing.is_alive(), "the pool's shutdown waited for a dead worker"


def test_an_abort_kills_a_busy_worker_instead_of_waiting_for_its_task(tmp_path):
    """A calibration that failed or was interrupted reads no result: its pool stops at once (a shutdown waited
    22 s for a worker's restart on the Ford head after a SIGINT to the command alone)."""
    pool = FeaturePool(1)
    pid = pool.submit(os.getpid).result()
    busy = pool.submit(_pid_after, 0.0, tmp_path / "never")  # runs until its 60 s wait fails
    started = time.monotonic()
    pool.abort()
    while _running(pid):
        assert time.monotonic() - started < 30, "the aborted pool's worker is still running"
        time.sleep(0.05)
    with pytest.raises((WorkerLostError, CancelledError)):
        busy.result(timeout=30)
