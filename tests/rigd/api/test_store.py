
"""The store without HTTP: immutable versions, one active, job transitions, schema version, dataset ids."""

from __future__ import annotations

import dataclasses
import sqlite3

import numpy as np
import pytest

from calib.geometry import Transform
from rigd.store import (
    ConflictError,
    Database,
    JobKind,
    JobStatus,
    JobStore,
    NewVersion,
    NotFoundError,
    StoreError,
    VersionStatus,
    VersionStore,
)
from rigd.store.datasets import DatasetCatalog
from rigd.store.db import MIGRATIONS


def new(yaw_deg: float = 0.0, x_m: float = 0.0) -> NewVersion:
    return NewVersion(Transform.from_rpy_xyz(np.array([0.0, 0.0, yaw_deg]), np.array([x_m, 0.0, 0.0])),
                      quality={"final_cost": float("nan")}, method="manual", parameters={}, code_version="test")


@pytest.fixture
def db(tmp_path):
    database = Database(tmp_path / "rigd.db")
    yield database
    database.close()


def test_database_is_wal_and_at_the_latest_schema(db):
    with db.read() as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        assert conn.execute("PRAGMA user_version").fetchone()[0] == len(MIGRATIONS)


def test_a_newer_schema_is_refused(tmp_path):
    with sqlite3.connect(tmp_path / "rigd.db") as conn:
        conn.execute(f"PRAGMA user_version = {len(MIGRATIONS) + 1}")
    with pytest.raises(StoreError, match="newer than this rigd"):
        Database(tmp_path / "rigd.db")


def test_versions_are_immutable_and_never_deleted(db):
    store = VersionStore(db)
    store.add(new(), lambda change: False)
    for sql in ("UPDATE versions SET transform = '{}'", "UPDATE versions SET quality = '{}'",
                "DELETE FROM versions"):
        with pytest.raises(StoreError), db.write() as conn:
            conn.execute(sql)
    assert store.get(1).method == "manual"


def test_exactly_one_active_and_the_change_against_it(db):
    store = VersionStore(db)
    first = store.add(new(), lambda change: False)
    assert first.status is VersionStatus.ACTIVE and first.change is None  # nothing else could be active
    assert first.quality == {"final_cost": None}  # NaN is stored as null (JSON has no NaN)
    second = store.add(new(yaw_deg=3.0, x_m=0.04), lambda change: False)
    assert second.status is VersionStatus.CANDIDATE and second.supersedes == 1
    assert second.change.rotation_deg == pytest.approx(3.0) and second.change.translation_cm == pytest.approx(4.0)
    third = store.add(new(yaw_deg=1.0), lambda change: change.rotation_deg < 2.0)
    assert third.status is VersionStatus.ACTIVE and third.change.against == 1
    assert [v.status for v in store.list()] == [VersionStatus.SUPERSEDED, VersionStatus.CANDIDATE,
                                                VersionStatus.ACTIVE]
    assert store.activate(2).status is VersionStatus.ACTIVE
    assert [v.number for v in store.list() if v.status is VersionStatus.ACTIVE] == [2]
    with pytest.raises(StoreError), db.write() as conn:  # the database itself refuses a second active one
        conn.execute("UPDATE versions SET status = 'active' WHERE number = 1")
    with pytest.raises(NotFoundError):
        store.activate(9)


def test_job_transitions(db, tmp_path):
    jobs = JobStore(db, tmp_path / "jobs")
    job = jobs.create(JobKind.CALIBRATE, {"dataset": "a"})
    assert job.status is JobStatus.QUEUED and (tmp_path / "jobs" / str(job.id)).is_dir()
    running = jobs.start(job.id, "working")
    assert running.status is JobStatus.RUNNING and running.started_at is not None
    with pytest.raises(ConflictError):
        jobs.start(job.id, "again")
    jobs.progress(job.id, "half", 0.5)
    assert jobs.get(job.id).fraction == 0.5
    done = jobs.finish(job.id, JobStatus.SUCCEEDED, "done", result={"version": 1})
    assert done.fraction == 1.0 and done.result == {"version": 1}
    # Finishing twice keeps the first outcome.
    assert jobs.finish(job.id, JobStatus.FAILED, "x", error="late").status is JobStatus.SUCCEEDED
    for line in ("a", "b", "c"):
        jobs.log(job.id, line)
    assert [line.split(" ", 1)[1] for line in jobs.log_tail(job.id, 2)] == ["b", "c"]


def test_unfinished_jobs_fail_as_interrupted(db, tmp_path):
    jobs = JobStore(db, tmp_path / "jobs")
    queued = jobs.create(JobKind.CAPTURE, {})
    running = jobs.start(jobs.create(JobKind.CALIBRATE, {}).id, "x")
    finished = jobs.finish(jobs.create(JobKind.CALIBRATE, {}).id, JobStatus.CANCELLED, "cancelled")
    failed = jobs.fail_unfinished("interrupted: test")
    assert sorted(j.id for j in failed) == sorted([queued.id, running.id])
    assert all(jobs.get(j.id).error == "interrupted: test" for j in (queued, running))
    assert jobs.get(finished.id).status is JobStatus.CANCELLED


@pytest.mark.parametrize("bad", ["..", ".", "../x", "a/b", "", "-x", "a" * 65, "a\x00"])
def test_dataset_ids_never_leave_the_datasets_folder(tmp_path, bad):
    with pytest.raises(StoreError):
        DatasetCatalog(tmp_path).path(bad)


@pytest.mark.parametrize("status", ["weak", "failed"])
def test_an_untrusted_first_calibration_is_not_activated_by_itself(db, status):
    store = VersionStore(db)
    untrusted = dataclasses.replace(new(), quality={"verdict": {"status": status, "weak_axes": ["z"]}})
    first = store.add(untrusted, lambda change: False)
    assert first.status is VersionStatus.CANDIDATE and store.active() is None
    trusted = dataclasses.replace(new(yaw_deg=1.0), quality={"verdict": {"status": "trusted", "weak_axes": []}})
    assert store.add(trusted, lambda change: False).status is VersionStatus.ACTIVE
    assert store.activate(1).status is VersionStatus.ACTIVE  # a person may still activate the weak one
