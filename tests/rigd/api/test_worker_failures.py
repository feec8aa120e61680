"""The job runner without HTTP: a worker that fails in a way it did not foresee, or is killed, fails its job
with the cause (issue 33: the job said only "exited with code 1"), and leaves no process behind."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from api_helpers import RIG_GUESS, process_group, simulated_dataset, worker_pid

from calib.geometry import Transform
from rigd.api.calibration_result import ActivationBounds
from rigd.api.job_runner import CalibrationPlan, JobRunner
from rigd.calibration import CalibrationRequest, Options, Start, TransformIn
from rigd.calibration.request import ToleranceIn
from rigd.store import Database, Job, JobStatus, JobStore, VersionStore
from rigd.store.datasets import DatasetCatalog

GUESS = Transform.from_rpy_xyz(np.array(RIG_GUESS["rpy_deg"]), np.array(RIG_GUESS["xyz_m"]))


def plan(dataset: Path, options: Options | None = None) -> CalibrationPlan:
    request = CalibrationRequest(dataset=dataset, start=Start.GIVEN, initial=TransformIn.of(GUESS),
                                 options=options or Options())
    return CalibrationPlan("ds", request, auto_activate=False)


def ladder(*sigmas_deg: float) -> Options:
    return Options(sigmas_deg=list(sigmas_deg))


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


def test_an_unforeseen_exception_in_the_worker_is_the_jobs_error(runner, tmp_path):
    # A tolerance the API refuses (422) stored unvalidated, as a record written by hand could be: the worker's
    # validation raises what it does not foresee.
    bad = Options.model_construct(tolerance=ToleranceIn.model_construct(rotation_deg=1e-300, translation_cm=2.0))
    job, _ = runner.submit_calibration(plan(tmp_path / "datasets" / "ds", bad))
    done = wait_for(runner, job.id)
    assert done.status is JobStatus.FAILED, done
    assert done.error is not None and "ValidationError" in done.error, done.error
    assert "traceback in the job log" in done.error
    assert any("Traceback" in line for line in (runner.jobs.job_dir(job.id) / "job.log").read_text().splitlines())


def test_a_killed_worker_is_reported_with_its_signal_and_its_pool_goes_with_it(runner, tmp_path):
    job, _ = runner.submit_calibration(plan(tmp_path / "datasets" / "ds"))
    pid = worker_pid(runner.jobs.log_tail(wait_for(runner, job.id, "worker process").id))
    wait_for(runner, job.id, "edges of the pairs")  # its pool processes run
    assert len(process_group(pid)) >= 3
    os.kill(pid, signal.SIGKILL)  # the worker alone, as the out-of-memory killer would
    done = wait_for(runner, job.id, timeout_s=10)
    assert done.status is JobStatus.FAILED
    assert done.error == "the calibrate worker was killed by SIGKILL (the out-of-memory killer?)", done.error
    assert process_group(pid) == []
    again, _ = runner.submit_calibration(plan(tmp_path / "datasets" / "ds", ladder(5.0, 2.5)))  # the queue goes on
    assert wait_for(runner, again.id).status is JobStatus.SUCCEEDED


def test_one_worker_calibrates_in_the_worker_process_alone(tmp_path):
    """RIGD_WORKERS=1 (the runner's ``workers``) reaches the job: no pool processes beside the worker."""
    simulated_dataset(tmp_path, "ds", pairs=2)
    db = Database(tmp_path / "rigd.db")
    runner = JobRunner(JobStore(db, tmp_path / "jobs"), VersionStore(db), DatasetCatalog(tmp_path / "datasets"),
                       ActivationBounds(), "test", workers=1)
    runner.start()
    try:
        job, _ = runner.submit_calibration(plan(tmp_path / "datasets" / "ds", ladder(4.0, 2.0)))
        pid = worker_pid(runner.jobs.log_tail(wait_for(runner, job.id, "worker process").id))
        wait_for(runner, job.id, "edges of the pairs")  # one process extracts pair after pair
        assert process_group(pid) in ([pid], [])  # the worker alone (or already done)
        assert wait_for(runner, job.id).status is JobStatus.SUCCEEDED
    finally:
        runner.shutdown()
        db.close()
