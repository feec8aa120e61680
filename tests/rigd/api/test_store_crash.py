"""A calibration's records killed (SIGKILL) at every commit boundary of the store: after a restart the job, its
folder, the versions and the active pointer agree. Each kill is a forked copy of this process stopped at one
fault point (rigd.store.faults), so a real kill -9 costs milliseconds, not a service start."""

from __future__ import annotations

import os
import shutil
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from calib.geometry import Transform
from rigd.api.calibration_result import ActivationBounds
from rigd.api.job_runner import CalibrationPlan, JobRunner
from rigd.calibration import CalibrationRequest, Start, TransformIn
from rigd.store import Database, JobKind, JobStatus, JobStore, NewVersion, VersionStatus, VersionStore, faults
from rigd.store.datasets import DatasetCatalog

GUESS = Transform.from_rpy_xyz(np.array([0.0, 10.0, -50.0]), np.array([0.1, 0.0, -0.1]))
PLAN = CalibrationPlan("ds", CalibrationRequest(dataset=Path("ds"), start=Start.GIVEN, initial=TransformIn.of(GUESS)),
                       auto_activate=True)
# What the worker sends back for a trusted, converged result (the fields the runner reads).
RESULT: dict[str, Any] = {
    "pair_numbers": [0, 1, 2, 3, 4, 5], "matrix": GUESS.matrix.tolist(), "dataset_hash": "sha256:0",
    "report": {"quality": {"converged": True}, "uncertainty": {}, "verdict": {"status": "trusted", "weak_axes": []},
               "method": {"name": "gmm"}, "change_from_initial": {}},
}


def open_store(data_dir: Path) -> tuple[Database, JobStore, VersionStore]:
    db = Database(data_dir / "rigd.db")
    return db, JobStore(db, data_dir / "jobs"), VersionStore(db)


def calibrate(data_dir: Path) -> None:
    """The records of one calibration, as the runner writes them: queued, started, progress, version + result."""
    db, jobs, versions = open_store(data_dir)
    runner = JobRunner(jobs, versions, DatasetCatalog(data_dir / "datasets"), ActivationBounds(), "test")
    job, _ = runner.submit_calibration(PLAN)
    job = jobs.start(job.id, "starting the worker")
    jobs.progress(job.id, "optimising", 0.5)
    runner.recorder.store(job, RESULT)
    db.close()


def killed_at(point: str, data_dir: Path) -> int:
    """Run :func:`calibrate` in a forked child that SIGKILLs itself on reaching ``point``; its wait status."""
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        try:
            faults.install(lambda reached: os.kill(os.getpid(), signal.SIGKILL) if reached == point else None)
            calibrate(data_dir)
        finally:
            os._exit(3)  # the point was never reached (or the scenario failed)
    return os.waitpid(pid, 0)[1]


def restarted(data_dir: Path) -> tuple[JobStore, VersionStore]:
    """The store as ``rigd serve`` opens it after a crash (rigd.api.service._open_service)."""
    db, jobs, versions = open_store(data_dir)
    half_done = [(j.id, v.number) for j in jobs.unfinished() for v in versions.list() if v.job_id == j.id]
    assert not half_done, f"versions of unfinished jobs: {half_done}"
    jobs.fail_unfinished("interrupted: test")
    return jobs, versions


def assert_consistent(jobs: JobStore, versions: VersionStore) -> None:
    every = versions.list()
    for job in jobs.list(limit=100):
        assert job.status.finished, job
        assert (jobs.job_dir(job.id) / "job.log").is_file(), f"job {job.id} has no folder"
        stored = [v for v in every if v.job_id == job.id]
        if job.status is JobStatus.SUCCEEDED and job.kind is JobKind.CALIBRATE:
            assert job.result is not None and [v.number for v in stored] == [job.result["version"]], job
        else:
            assert not stored, (job, stored)
    active = [v for v in every if v.status is VersionStatus.ACTIVE]
    assert len(active) == 1
    latest = max((v for v in every if v.activated_at is not None), key=lambda v: v.activated_at)
    assert latest.number == active[0].number  # the pointer is the last activation


@pytest.fixture(scope="module")
def boundaries(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    """A data directory with one manual version active (the calibration supersedes it), and the fault points a
    calibration passes, in order."""
    base = tmp_path_factory.mktemp("base")
    db, _, versions = open_store(base)
    versions.add(NewVersion(GUESS, {}, "manual", {}, "test"), lambda change: True)
    db.close()
    seen: list[str] = []
    probe = tmp_path_factory.mktemp("probe")
    shutil.copytree(base, probe, dirs_exist_ok=True)
    faults.install(seen.append)
    try:
        calibrate(probe)
    finally:
        faults.install(None)
    return base, seen


def test_a_calibration_passes_the_boundaries_of_its_records(boundaries):
    _, seen = boundaries
    assert [p for p in seen if p.startswith(("jobs.create", "versions.add"))] == [
        "jobs.create:folder", "jobs.create:commit", "jobs.create:committed", "versions.add:commit",
        "versions.add:committed"]
    assert "jobs.start:commit" in seen and "jobs.progress:commit" in seen


def test_a_jobs_folder_the_database_does_not_know_is_kept_aside(tmp_path):
    db, jobs, _ = open_store(tmp_path)
    (tmp_path / "jobs" / "1" / "calibration").mkdir(parents=True)  # a restored database lost job 1's row
    (tmp_path / "jobs" / "1" / "calibration" / "extrinsics.yaml").write_text("T_camera_lidar: {}\n")
    job = jobs.create(JobKind.CHECK, {})
    assert job.id == 1 and os.listdir(jobs.job_dir(1)) == ["job.log"]
    aside = [p for p in (tmp_path / "jobs").iterdir() if p.name.startswith("1.orphaned.")]
    assert len(aside) == 1 and (aside[0] / "calibration" / "extrinsics.yaml").is_file()
    db.close()


def test_a_kill_at_any_boundary_leaves_whole_records(boundaries, tmp_path):
    base, seen = boundaries
    for k, point in enumerate(dict.fromkeys(seen)):
        data_dir = tmp_path / str(k)
        shutil.copytree(base, data_dir)
        status = killed_at(point, data_dir)
        assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, (point, status)
        jobs, versions = restarted(data_dir)
        assert_consistent(jobs, versions)
        stored = versions.count() == 2
        assert stored == (point == "versions.add:committed"), point  # the one commit that stores it
        if stored:
            assert versions.active().number == 2 and jobs.get(1).status is JobStatus.SUCCEEDED
        # A create that never committed leaves its folder: the next job of that id starts in an empty one.
        again = jobs.create(JobKind.CHECK, {})
        assert jobs.log_tail(again.id) == [] and os.listdir(jobs.job_dir(again.id)) == ["job.log"]
