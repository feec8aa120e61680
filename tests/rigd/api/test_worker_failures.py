"""The job runner without HTTP: a worker that fails in a way it did not foresee, or is killed, fails its job
with the cause (issue 33: the job said only "exited with code 1"), and leaves no process behind."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from api_helpers import RIG_GUESS, process_group, simulated_dataset, worker_pid

from calib.geometry import Transform
from rigd.api.runner import ActivationBounds, CalibrationPlan, JobRunner, Start
from rigd.store import Database, Job, JobStatus, JobStore, VersionStore
from rigd.store.datasets import DatasetCatalog

GUESS = Transform.from_rpy_xyz(np.array(RIG_GUESS["rpy_deg"]), np.array(RIG_GUESS["xyz_m"]))
PLAN = CalibrationPlan(dataset_id="ds", initial=GUESS, init=Start.EXPLICIT, init_version=None, sigmas_deg=None,
                       auto_activate=False)


@pytest.fixture
def runner(tmp_path: Path) -> Iterator[JobRunner]:
    simulated_dataset(tmp_path, "ds", pairs=2)
    db = Database(tmp_path / "rigd.db")
    runner = JobRunner(JobStore(db, tmp_path / "jobs"), VersionStore(db), DatasetCatalog(tmp_path / "datasets"),
                       ActivationBounds(), "test")
    runner.start()
    yield runner
    runner.shutdown()
    db.close()


def wait_for(runner: JobRunner, job_id: int, log_text: str | None = None, timeout_s: float = 180.0) -> Job:
    """The job once it has finished, or (``log_text``) once its log tail holds that."""
    deadline = time.monotonic() + timeout_s
    while True:
        job = runner.jobs.get(job_id)
        if (log_text is None and job.status.finished) or (
                log_text is not None and any(log_text in line for line in runner.jobs.log_tail(job_id))):
            return job
        assert time.monotonic() < deadline and not (log_text and job.status.finished), job
        time.sleep(0.05)


def test_an_unforeseen_exception_in_the_worker_is_the_jobs_error(runner):
    # A tolerance the API refuses now (422) but the worker could still be given: it killed the verdict's
    # arithmetic with numpy's LinAlgError.
    job, _ = runner.submit_calibration(replace(PLAN, tolerance={"rotation_deg": 1e-300, "translation_cm": 2.0},
                                               sigmas_deg=(4.0, 2.0)))  # a short ladder: to the verdict sooner
    done = wait_for(runner, job.id)
    assert done.status is JobStatus.FAILED, done
    assert done.error is not None and "LinAlgError" in done.error, done.error
    assert "traceback in the job log" in done.error
    assert any("Traceback" in line for line in (runner.jobs.job_dir(job.id) / "job.log").read_text().splitlines())


def test_a_killed_worker_is_reported_with_its_signal_and_its_pool_goes_with_it(runner):
    job, _ = runner.submit_calibration(PLAN)
    pid = worker_pid(runner.jobs.log_tail(wait_for(runner, job.id, "worker process").id))
    wait_for(runner, job.id, "edges of")  # its pool processes run
    assert len(process_group(pid)) >= 3
    os.kill(pid, signal.SIGKILL)  # the worker alone, as the out-of-memory killer would
    done = wait_for(runner, job.id, timeout_s=10)
    assert done.status is JobStatus.FAILED
    assert done.error == "the calibrate worker was killed by SIGKILL (the out-of-memory killer?)", done.error
    assert process_group(pid) == []
    again, _ = runner.submit_calibration(replace(PLAN, sigmas_deg=(5.0, 2.5)))  # the queue goes on
    assert wait_for(runner, again.id).status is JobStatus.SUCCEEDED


def test_one_worker_calibrates_in_the_worker_process_alone(tmp_path):
    """RIGD_WORKERS=1 (the runner's ``workers``) reaches the job: no pool processes beside the worker."""
    simulated_dataset(tmp_path, "ds", pairs=2)
    db = Database(tmp_path / "rigd.db")
    runner = JobRunner(JobStore(db, tmp_path / "jobs"), VersionStore(db), DatasetCatalog(tmp_path / "datasets"),
                       ActivationBounds(), "test", workers=1)
    runner.start()
    try:
        job, _ = runner.submit_calibration(replace(PLAN, sigmas_deg=(4.0, 2.0)))
        pid = worker_pid(runner.jobs.log_tail(wait_for(runner, job.id, "worker process").id))
        wait_for(runner, job.id, "edges of pair")  # one process extracts pair after pair
        assert process_group(pid) in ([pid], [])  # the worker alone (or already done)
        assert wait_for(runner, job.id).status is JobStatus.SUCCEEDED
    finally:
        runner.shutdown()
        db.close()
