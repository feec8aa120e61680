"""Jobs (captures, calibrations): persisted state and progress, plus a log file per job."""

from __future__ import annotations

import builtins
import json
import sqlite3
from collections import deque
from pathlib import Path
from typing import Any, cast

from rigd.results import JobResult
from rigd.store.db import Database, utc_now
from rigd.store.errors import ConflictError, NotFoundError, StoreError
from rigd.store.jsonsafe import json_safe
from rigd.store.records import Job, JobKind, JobStatus

_UNFINISHED = (JobStatus.QUEUED.value, JobStatus.RUNNING.value)


def _stored(params: dict[str, Any]) -> str:
    return json.dumps(json_safe(params))


def _row_to_job(row: sqlite3.Row) -> Job:
    # Unchecked: the result reads back as JobStore.finish wrote it (a JobResult of the job's kind, through JSON);
    # the API's JobOut validates it.
    result = cast(JobResult, json.loads(row["result"])) if row["result"] else None
    return Job(
        id=row["id"],
        kind=JobKind(row["kind"]),
        status=JobStatus(row["status"]),
        params=json.loads(row["params"]),
        stage=row["stage"],
        fraction=row["fraction"],
        created_at=row["created_at"],
        started_at=row["started_at"],
        finished_at=row["finished_at"],
        result=result,
        error=row["error"],
    )


class JobStore:
    """Job records in the database; job ``i``'s files (log, outputs) live in ``jobs_dir/i``."""

    def __init__(self, db: Database, jobs_dir: Path) -> None:
        self.db = db
        self.jobs_dir = Path(jobs_dir)

    def create(self, kind: JobKind, params: dict[str, Any], stage: str = "queued") -> Job:
        with self.db.write() as conn:
            cursor = conn.execute(
                "INSERT INTO jobs (kind, status, params, stage, created_at) VALUES (?, ?, ?, ?, ?)",
                (kind.value, JobStatus.QUEUED.value, _stored(params), stage, utc_now()),
            )
            job = self._get(conn, int(cursor.lastrowid or 0))
        self.job_dir(job.id).mkdir(parents=True, exist_ok=True)
        return job

    def get(self, job_id: int) -> Job:
        with self.db.read() as conn:
            return self._get(conn, job_id)

    # In this class's annotations ``list`` is this method, so the ones below say ``builtins.list``.
    def list(self, limit: int = 100, kind: JobKind | None = None, status: JobStatus | None = None) -> list[Job]:
        """Newest first."""
        where, args = [], []
        if kind is not None:
            where.append("kind = ?")
            args.append(kind.value)
        if status is not None:
            where.append("status = ?")
            args.append(status.value)
        sql = "SELECT * FROM jobs" + (" WHERE " + " AND ".join(where) if where else "") + " ORDER BY id DESC LIMIT ?"
        with self.db.read() as conn:
            return [_row_to_job(r) for r in conn.execute(sql, (*args, limit))]

    def unfinished(self, kind: JobKind | None = None) -> builtins.list[Job]:
        """Queued and running jobs, oldest first."""
        with self.db.read() as conn:
            rows = conn.execute("SELECT * FROM jobs WHERE status IN (?, ?) ORDER BY id", _UNFINISHED)
            jobs = [_row_to_job(r) for r in rows]
        return [j for j in jobs if kind is None or j.kind is kind]

    def unfinished_with(self, kind: JobKind, params: dict[str, Any]) -> builtins.list[Job]:
        """Queued and running jobs of ``kind`` with exactly these parameters (as stored), oldest first."""
        wanted = json.loads(_stored(params))
        return [j for j in self.unfinished(kind) if j.params == wanted]

    def start(self, job_id: int, stage: str) -> Job:
        """queued -> running; ConflictError if the job is no longer queued (cancelled meanwhile)."""
        with self.db.write() as conn:
            job = self._get(conn, job_id)
            if job.status is not JobStatus.QUEUED:
                raise ConflictError(f"job {job_id} is {job.status.value}, not queued")
            conn.execute("UPDATE jobs SET status = ?, stage = ?, started_at = ? WHERE id = ?",
                         (JobStatus.RUNNING.value, stage, utc_now(), job_id))
            return self._get(conn, job_id)

    def progress(self, job_id: int, stage: str, fraction: float) -> None:
        with self.db.write() as conn:
            conn.execute("UPDATE jobs SET stage = ?, fraction = ? WHERE id = ? AND status = ?",
                         (stage, min(max(fraction, 0.0), 1.0), job_id, JobStatus.RUNNING.value))

    def finish(self, job_id: int, status: JobStatus, stage: str, result: JobResult | None = None,
               error: str | None = None) -> Job:
        """Mark an unfinished job finished; a job already finished is left as it is and returned."""
        if not status.finished:
            raise StoreError(f"job {job_id}: {status.value} is not a final status")
        with self.db.write() as conn:
            conn.execute(
                "UPDATE jobs SET status = ?, stage = ?, fraction = CASE WHEN ? THEN 1.0 ELSE fraction END, "
                "finished_at = ?, result = ?, error = ? WHERE id = ? AND status IN (?, ?)",
                (status.value, stage, status is JobStatus.SUCCEEDED, utc_now(),
                 json.dumps(json_safe(result)) if result is not None else None, error, job_id, *_UNFINISHED),
            )
            return self._get(conn, job_id)

    def fail_unfinished(self, reason: str) -> builtins.list[Job]:
        """Mark every queued or running job failed with ``reason`` (at start-up: the last run died)."""
        failed = []
        for job in self.unfinished():
            failed.append(self.finish(job.id, JobStatus.FAILED, "interrupted", error=reason))
            self.log(job.id, f"failed: {reason}")
        return failed

    # -- files ------------------------------------------------------------------------------------------------
    def job_dir(self, job_id: int) -> Path:
        return self.jobs_dir / str(job_id)

    def log(self, job_id: int, line: str) -> None:
        path = self.job_dir(job_id) / "job.log"
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with path.open("a") as fh:
                fh.write(f"{utc_now()} {line.rstrip()}\n")
        except OSError as exc:
            raise StoreError(f"{path}: cannot append to the job log ({exc.strerror})") from exc

    def log_tail(self, job_id: int, lines: int = 20) -> builtins.list[str]:
        path = self.job_dir(job_id) / "job.log"
        try:
            with path.open(errors="replace") as fh:
                return [line.rstrip("\n") for line in deque(fh, maxlen=lines)]
        except FileNotFoundError:
            return []
        except OSError as exc:
            raise StoreError(f"{path}: cannot read the job log ({exc.strerror})") from exc

    @staticmethod
    def _get(conn: sqlite3.Connection, job_id: int) -> Job:
        row = conn.execute("SELECT * FROM jobs WHERE id = ?", (job_id,)).fetchone()
        if row is None:
            raise NotFoundError(f"job {job_id} does not exist")
        return _row_to_job(row)
