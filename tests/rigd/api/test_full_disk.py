"""A full or read-only data directory: requests answer 507 naming the path and the free space, nothing is queued
that cannot run, no job stays running, and the service serves again once there is room, without a restart.

The full disk is SQLite's own (``PRAGMA max_page_count``: the database cannot grow), a free-space floor above
what the disk has, or a write that fails at a store's fault point (rigd.store.faults) as a full disk makes it.
"""

from __future__ import annotations

import sqlite3
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from api_helpers import App

from calib.geometry import Transform
from rigd.api.calibration_result import ActivationBounds
from rigd.api.job_runner import CalibrationPlan, JobRunner
from rigd.calibration import CalibrationRequest, Start, TransformIn
from rigd.capture import DiskFullError
from rigd.dataset import CameraConfig, CameraKind, Cloud, RigConfig, write_pair, write_rig
from rigd.store import Database, JobKind, JobStatus, JobStore, NewVersion, StorageError, VersionStore, faults
from rigd.store.datasets import DatasetCatalog

GUESS = Transform.from_rpy_xyz(np.array([0.0, 10.0, -50.0]), np.array([0.1, 0.0, -0.1]))


def full_at(point: str) -> None:
    """Fail the write reaching ``point`` as SQLite fails one on a full disk."""

    def hook(reached: str) -> None:
        if reached == point:
            error = sqlite3.OperationalError("database or disk is full")
            error.sqlite_errorcode = sqlite3.SQLITE_FULL  # type: ignore[attr-defined]
            raise error

    faults.install(hook)


@pytest.fixture(autouse=True)
def no_faults() -> Iterator[None]:
    yield
    faults.install(None)


def tiny_dataset(data_dir: Path, name: str = "ds") -> None:
    root = data_dir / "datasets" / name
    write_rig(root, RigConfig(CameraConfig(CameraKind.EQUIRECTANGULAR, 64, 32)))
    points = np.random.default_rng(0).uniform(-5, 5, (200, 3))
    write_pair(root, 0, np.zeros((32, 64), np.uint8), Cloud(points), {})


def test_a_full_database_is_storage_error_and_takes_writes_again(tmp_path):
    db = Database(tmp_path / "rigd.db")
    versions = VersionStore(db)
    versions.add(NewVersion(GUESS, {}, "manual", {}, "test"), lambda change: True)
    pages = db._conn.execute("PRAGMA page_count").fetchone()[0]
    db._conn.execute(f"PRAGMA max_page_count = {pages}")  # the disk is full: the file cannot grow
    big = NewVersion(GUESS, {}, "manual", {"note": "x" * 100_000}, "test")
    with pytest.raises(StorageError, match=r"rigd\.db: write failed \(database or disk is full\); .* MB free"):
        versions.add(big, lambda change: True)
    assert versions.count() == 1  # nothing half written, and the connection still works
    db._conn.execute(f"PRAGMA max_page_count = {pages * 100}")  # room again
    assert versions.add(big, lambda change: True).number == 2
    db.close()


def test_a_damaged_database_is_named(tmp_path):
    (tmp_path / "rigd.db").write_bytes(b"SQLite format 3\x00" + b"\x00" * 84)  # a header, then nothing
    with pytest.raises(Exception, match=r"rigd\.db: .*damaged or not rigd's database") as error:
        Database(tmp_path / "rigd.db")
    assert type(error.value).__name__ == "StoreError"


def test_an_end_the_database_cannot_take_is_shown_and_written_later(tmp_path):
    db = Database(tmp_path / "rigd.db")
    jobs = JobStore(db, tmp_path / "jobs")
    job = jobs.create(JobKind.CAPTURE, {}, running=True)
    full_at("jobs.finish:commit")
    ended = jobs.finish(job.id, JobStatus.FAILED, "failed", error="disk full")
    assert ended.status is JobStatus.FAILED and jobs.unfinished() == []
    with db.read() as conn:  # not written yet
        assert conn.execute("SELECT status FROM jobs").fetchone()[0] == "running"
    faults.install(None)  # room again: the next write of the store writes it first
    jobs.create(JobKind.CAPTURE, {})
    with db.read() as conn:
        assert conn.execute("SELECT status FROM jobs WHERE id = ?", (job.id,)).fetchone()[0] == "failed"
    db.close()


def test_a_recorded_version_of_an_unfinished_job_is_its_result_at_restart(tmp_path):
    """A database from a release that committed a version and its job's end apart, killed between the two."""
    db = Database(tmp_path / "rigd.db")
    jobs, versions = JobStore(db, tmp_path / "jobs"), VersionStore(db)
    job = jobs.start(jobs.create(JobKind.CALIBRATE, {"auto_activate": False}).id, "x")
    versions.add(NewVersion(GUESS, {}, "rigd", {}, "test", job_id=job.id), lambda change: False)
    jobs.fail_unfinished("interrupted: test")
    assert jobs.get(job.id).status is JobStatus.SUCCEEDED and jobs.get(job.id).result["version"] == 1
    db.close()


@pytest.fixture
def runner(tmp_path: Path) -> Iterator[JobRunner]:
    tiny_dataset(tmp_path)
    db = Database(tmp_path / "rigd.db")
    runner = JobRunner(JobStore(db, tmp_path / "jobs"), VersionStore(db), DatasetCatalog(tmp_path / "datasets"),
                       ActivationBounds(), "test")
    yield runner  # never started: the tests call what its thread would
    db.close()


def ended(runner: JobRunner) -> None:
    """Once the runner's capture thread has gone."""
    deadline = time.monotonic() + 5
    while runner.capturing():
        assert time.monotonic() < deadline
        time.sleep(0.01)


def test_a_capture_failing_on_a_full_disk_ends_and_frees_the_sensors(runner):
    def work(job, stop):
        raise DiskFullError("datasets/ds: disk full while writing pair 0000")

    full_at("jobs.finish:commit")  # its end cannot be written either
    job = runner.submit_capture("ds", {}, work)
    ended(runner)
    assert runner.jobs.get(job.id).status is JobStatus.FAILED and "disk full" in runner.jobs.get(job.id).error
    faults.install(None)
    runner.submit_capture("ds", {}, lambda job, stop: {"dataset": "ds", "pairs_written": 0,
                                                         "pairs_in_dataset": 1, "seconds_per_pair": []})
    ended(runner)
    assert [j.status for j in runner.jobs.list()] == [JobStatus.SUCCEEDED, JobStatus.FAILED]


def test_a_queued_calibration_that_cannot_run_fails_and_leaves_the_queue(runner):
    request = CalibrationRequest(dataset=Path("ds"), start=Start.GIVEN, initial=TransformIn.of(GUESS))
    plan = CalibrationPlan("ds", request, auto_activate=False)
    job, _ = runner.submit_calibration(plan)
    runner.jobs.min_free_bytes = 1 << 60  # the disk filled while it waited
    runner._run_job(job.id)
    failed = runner.jobs.get(job.id)
    assert failed.status is JobStatus.FAILED and failed.error.startswith("not started: ") and "MB free" in failed.error
    assert runner.jobs.unfinished() == []
    with pytest.raises(StorageError, match="nothing was started"):  # and nothing new is queued meanwhile
        runner.submit_calibration(plan)
    runner.jobs.min_free_bytes = 0
    assert runner.submit_calibration(plan)[1]


def test_a_result_that_cannot_be_stored_fails_its_job_and_stores_nothing(runner):
    job = runner.jobs.start(runner.jobs.create(JobKind.CALIBRATE, {"dataset": "ds", "auto_activate": False}).id, "x")
    result = {"pair_numbers": [0], "matrix": GUESS.matrix.tolist(), "dataset_hash": "sha256:0",
              "report": {"quality": {"converged": True}, "uncertainty": {}, "method": {"name": "rigd"},
                         "verdict": {"status": "trusted", "weak_axes": []}, "change_from_initial": {}}}
    full_at("versions.add:commit")
    runner.recorder.store(runner.jobs.get(job.id), result)
    failed = runner.jobs.get(job.id)
    assert failed.status is JobStatus.FAILED and "its result could not be stored" in failed.error
    assert runner.versions.count() == 0


def test_the_service_answers_507_and_serves_again(tmp_path):
    data_dir = tmp_path / "data"
    tiny_dataset(data_dir)
    app = App(data_dir, {"RIGD_MIN_FREE_MB": "1000000000"}).start()  # 1 PB: more than any disk has
    try:
        client = app.client()
        for path, body in (("/calibrate", {"dataset": "ds", "init": "rig"}), ("/capture", {"dataset": "ds"})):
            answer = client.post(path, json=body)
            assert answer.status_code == 507, answer.text
            assert str(data_dir / "jobs") in answer.json()["detail"] and "MB free" in answer.json()["detail"]
        assert client.get("/jobs").json() == []
        full_at("versions.add:commit")
        manual = {"T_camera_lidar": {"rpy_deg": [0, 0, 0], "xyz_m": [0, 0, 0]}}
        answer = client.post("/extrinsics/versions", json=manual)
        assert answer.status_code == 507 and "rigd.db" in answer.json()["detail"], answer.text
        faults.install(None)
        assert client.post("/extrinsics/versions", json=manual).status_code == 201
        assert client.get("/status").status_code == 200
    finally:
        app.stop()
