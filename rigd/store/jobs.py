"""Jobs (captures, calibrations, checks): persisted state and progress, plus a folder per job with its log.

A job's row and its folder are made in one transaction: a folder that cannot be made rolls the row back, and one
left by a create that never committed is cleared by the next create of that id. So every job can log, and none
exists that the runner did not take. A job's end that the database cannot take (a full or read-only file system)
is kept in memory, shown by every read, and written as soon as the database takes writes again (before any later
write of this store, and every second).
"""

from __future__ import annotations

import builtins
import dataclasses
import json
import logging
import shutil
import sqlite3
import threading
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

from rigd.results import JobResult
from rigd.space import free_bytes, is_storage_error, megabytes, os_reason, write_failure
from rigd.store import faults
from rigd.store.db import Database, utc_now
from rigd.store.errors import ConflictError, NotFoundError, StorageError, StoreError
from rigd.store.jsonsafe import json_safe
from rigd.store.records import Job, JobKind, JobStatus

_UNFINISHED = (JobStatus.QUEUED.value, JobStatus.RUNNING.value)
PENDING_RETRY_S = 1.0  # how often an end the database could not take is tried again
LOG = logging.getLogger(__name__)


def _stored(params: dict[str, Any]) -> str:
    return json.dumps(json_safe(params))


_JOB_COLUMNS = ("id", "stage", "fraction", "created_at", "started_at", "finished_at", "error")  # stored as they are


def _row_to_job(row: sqlite3.Row) -> Job:
    # Unchecked: the result reads back as JobStore.finish wrote it (a JobResult of the job's kind, through JSON);
    # the API's JobOut validates it.
    result = cast(JobResult, json.loads(row["result"])) if row["result"] else None
    return Job(kind=JobKind(row["kind"]), status=JobStatus(row["status"]), params=json.loads(row["params"]),
               result=result, **{column: row[column] for column in _JOB_COLUMNS})


@dataclass(frozen=True)
class JobEnd:
    """How a job ended: a final ``status``, its last ``stage``, and its result or error."""

    status: JobStatus
    stage: str
    result: JobResult | None = None
    error: str | None = None
    finished_at: str = field(default_factory=utc_now)

    def __post_init__(self) -> None:
        if not self.status.finished:
            raise StoreError(f"{self.status.value} is not a final status")

    def applied(self, job: Job) -> Job:
        """``job`` as this end leaves it (an end never replaces an earlier one)."""
        if job.status.finished:
            return job
        fraction = 1.0 if self.status is JobStatus.SUCCEEDED else job.fraction
        return dataclasses.replace(job, status=self.status, stage=self.stage, fraction=fraction,
                                   finished_at=self.finished_at, result=self.result, error=self.error)


def finish_in(conn: sqlite3.Connection, job_id: int, end: JobEnd) -> bool:
    """Write ``end`` into job ``job_id``'s row inside the caller's transaction; False when it had ended already
    (the first end stays)."""
    cursor = conn.execute(
        "UPDATE jobs SET status = ?, stage = ?, fraction = CASE WHEN ? THEN 1.0 ELSE fraction END, "
        "finished_at = ?, result = ?, error = ? WHERE id = ? AND status IN (?, ?)",
        (end.status.value, end.stage, end.status is JobStatus.SUCCEEDED, end.finished_at,
         json.dumps(json_safe(end.result)) if end.result is not None else None, end.error, job_id, *_UNFINISHED),
    )
    return cursor.rowcount == 1


class JobStore:
    """Job records in the database; job ``i``'s files (log, outputs) live in ``jobs_dir/i``. ``min_free_bytes``:
    a new job is refused (StorageError) while the data directory's file system has less free."""

    def __init__(self, db: Database, jobs_dir: Path, min_free_bytes: int = 0) -> None:
        self.db = db
        self.jobs_dir = Path(jobs_dir)
        self.min_free_bytes = min_free_bytes
        self._pending: dict[int, JobEnd] = {}  # ends the database could not take yet, by job id
        self._pending_lock = threading.Lock()
        self._retry: threading.Timer | None = None
        self._unlogged: set[int] = set()  # jobs whose log or progress could not be written (warned once)

    def space_problem(self) -> str | None:
        """Why the data directory cannot take a job now (too little free space), or None."""
        free = free_bytes(self.jobs_dir)
        if free is None or free >= self.min_free_bytes:
            return None
        return (f"{self.jobs_dir}: {megabytes(free)} free on its file system, a job needs at least "
                f"{megabytes(self.min_free_bytes)} (RIGD_MIN_FREE_MB): free some space")

    def create(self, kind: JobKind, params: dict[str, Any], stage: str = "queued", *, running: bool = False) -> Job:
        """A new job, queued (``running``: started at once, as a capture is), with its folder and an empty log;
        StorageError, and no job, when the data directory is short of space or takes no write."""
        problem = self.space_problem()
        if problem is not None:
            raise StorageError(f"{problem}; nothing was started")
        self._flush_pending()
        status = JobStatus.RUNNING if running else JobStatus.QUEUED
        with self.db.write("jobs.create") as conn:
            now = utc_now()
            cursor = conn.execute(
                "INSERT INTO jobs (kind, status, params, stage, created_at, started_at) VALUES (?, ?, ?, ?, ?, ?)",
                (kind.value, status.value, _stored(params), stage, now, now if running else None),
            )
            job = self._get(conn, int(cursor.lastrowid or 0))
            self._make_folder(job.id)
        return job

    def _make_folder(self, job_id: int) -> None:
        """Job ``job_id``'s folder with an empty log, inside the transaction that creates its row."""
        folder = self.job_dir(job_id)
        try:
            if folder.exists():  # no row has this id: a create that never committed left it (an empty log)
                self._clear_leftover(folder)
            folder.mkdir(parents=True)
            (folder / "job.log").touch()
        except OSError as exc:
            message = write_failure(folder, os_reason(exc)) + "; nothing was started"
            raise (StorageError(message) if is_storage_error(exc) else StoreError(message)) from exc
        faults.at("jobs.create:folder")

    @staticmethod
    def _clear_leftover(folder: Path) -> None:
        """Remove the folder of a create that never committed; one holding more than an empty log (a restored
        database's missing job) is kept aside as ``N.orphaned.STAMP`` rather than deleted."""
        log = folder / "job.log"
        if [p.name for p in folder.iterdir()] == ["job.log"] and log.stat().st_size == 0:
            shutil.rmtree(folder)
            return
        aside = folder.with_name(f"{folder.name}.orphaned.{utc_now().replace(':', '')}")
        folder.rename(aside)
        LOG.warning("rigd: %s held files of a job the database does not have: moved to %s", folder, aside)

    def get(self, job_id: int) -> Job:
        with self.db.read() as conn:
            return self._shown(self._get(conn, job_id))

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
            return [self._shown(_row_to_job(r)) for r in conn.execute(sql, (*args, limit))]

    def unfinished(self, kind: JobKind | None = None) -> builtins.list[Job]:
        """Queued and running jobs, oldest first."""
        with self.db.read() as conn:
            rows = conn.execute("SELECT * FROM jobs WHERE status IN (?, ?) ORDER BY id", _UNFINISHED)
            jobs = [self._shown(_row_to_job(r)) for r in rows]
        return [j for j in jobs if not j.status.finished and (kind is None or j.kind is kind)]

    def unfinished_with(self, kind: JobKind, params: dict[str, Any]) -> builtins.list[Job]:
        """Queued and running jobs of ``kind`` with exactly these parameters (as stored), oldest first."""
        wanted = json.loads(_stored(params))
        return [j for j in self.unfinished(kind) if j.params == wanted]

    def start(self, job_id: int, stage: str) -> Job:
        """queued -> running; ConflictError if the job is no longer queued (cancelled meanwhile)."""
        self._flush_pending()
        with self.db.write("jobs.start") as conn:
            job = self._get(conn, job_id)
            if job.status is not JobStatus.QUEUED:
                raise ConflictError(f"job {job_id} is {job.status.value}, not queued")
            conn.execute("UPDATE jobs SET status = ?, stage = ?, started_at = ? WHERE id = ?",
                         (JobStatus.RUNNING.value, stage, utc_now(), job_id))
            return self._get(conn, job_id)

    def progress(self, job_id: int, stage: str, fraction: float) -> None:
        """Record a running job's stage; on a full or read-only file system the job goes on without it."""
        try:
            self._flush_pending()
            with self.db.write("jobs.progress") as conn:
                conn.execute("UPDATE jobs SET stage = ?, fraction = ? WHERE id = ? AND status = ?",
                             (stage, min(max(fraction, 0.0), 1.0), job_id, JobStatus.RUNNING.value))
        except StorageError as exc:
            self._warn_once(job_id, f"its progress is not recorded: {exc}")

    def finish(self, job_id: int, status: JobStatus, stage: str, result: JobResult | None = None,
               error: str | None = None) -> Job:
        """Mark an unfinished job finished; a job already finished is left as it is and returned. When the
        database takes no write, the end is kept and shown until it can be written (see the module)."""
        return self.end(job_id, JobEnd(status, stage, result, error))

    def end(self, job_id: int, end: JobEnd) -> Job:
        """:meth:`finish` with the end as a record."""
        try:
            self._flush_pending()
            with self.db.write("jobs.finish") as conn:
                finish_in(conn, job_id, end)
                return self._get(conn, job_id)
        except StorageError as exc:
            LOG.error("rigd: job %d ended %s, which cannot be written yet (kept until it can): %s", job_id,
                      end.status.value, exc)
            with self._pending_lock:
                self._pending.setdefault(job_id, end)
            self._retry_later()
            return self.get(job_id)

    def _shown(self, job: Job) -> Job:
        end = self._pending.get(job.id)
        return job if end is None else end.applied(job)

    def _flush_pending(self) -> None:
        """Write the ends kept in memory (StorageError while the database still takes no write)."""
        with self._pending_lock:
            pending = dict(self._pending)
        if not pending:
            return
        with self.db.write("jobs.finish") as conn:
            for job_id, end in pending.items():
                finish_in(conn, job_id, end)
        with self._pending_lock:
            for job_id, end in pending.items():
                if self._pending.get(job_id) is end:
                    del self._pending[job_id]
        LOG.warning("rigd: the ends of jobs %s are written now", sorted(pending))

    def _retry_later(self) -> None:
        with self._pending_lock:
            if self._retry is not None or not self._pending:
                return
            self._retry = threading.Timer(PENDING_RETRY_S, self._retry_pending)
            self._retry.daemon = True
            self._retry.start()

    def _retry_pending(self) -> None:
        with self._pending_lock:
            self._retry = None
        try:
            self._flush_pending()
        except StorageError:
            self._retry_later()
        except StoreError as exc:  # closed or deleted: the next start marks those jobs interrupted
            LOG.error("rigd: the ends of jobs %s cannot be written: %s", sorted(self._pending), exc)

    def fail_unfinished(self, reason: str) -> builtins.list[Job]:
        """Mark every queued or running job failed with ``reason`` (at start-up: the last run died). A calibration
        whose version was stored (by a release that committed the two apart) gets that version as its result."""
        ended = []
        for job in self.unfinished():
            stored = self._stored_version(job)
            if stored is None:
                ended.append(self.finish(job.id, JobStatus.FAILED, "interrupted", error=reason))
                self.log(job.id, f"failed: {reason}")
            else:
                ended.append(self.end(job.id, stored[1]))
                self.log(job.id, f"its version {stored[0]} was stored before the service stopped: succeeded")
        return ended

    def _stored_version(self, job: Job) -> tuple[int, JobEnd] | None:
        with self.db.read() as conn:
            row = conn.execute("SELECT number, status, change FROM versions WHERE job_id = ? ORDER BY number",
                               (job.id,)).fetchone()
        if row is None:
            return None
        result = {"version": row["number"], "status": row["status"],
                  "change": json.loads(row["change"]) if row["change"] else None,
                  "auto_activate": {"requested": bool(job.params.get("auto_activate", False))}}
        return row["number"], JobEnd(JobStatus.SUCCEEDED, "done", cast(JobResult, result))

    # -- files ------------------------------------------------------------------------------------------------
    def job_dir(self, job_id: int) -> Path:
        return self.jobs_dir / str(job_id)

    def log(self, job_id: int, line: str) -> None:
        """Append ``line`` to the job's log. On a full or read-only file system the line is dropped (said once in
        the service's log): the job's record is in the database; StoreError for anything else."""
        path = self.job_dir(job_id) / "job.log"
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with path.open("a") as fh:
                fh.write(f"{utc_now()} {line.rstrip()}\n")
        except OSError as exc:
            if is_storage_error(exc):
                self._warn_once(job_id, f"its log lines are dropped: {write_failure(path, os_reason(exc))}")
                return
            raise StoreError(f"{path}: cannot append to the job log ({exc.strerror})") from exc

    def _warn_once(self, job_id: int, message: str) -> None:
        if job_id not in self._unlogged:
            self._unlogged.add(job_id)
            LOG.warning("rigd: job %d: %s", job_id, message)

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
