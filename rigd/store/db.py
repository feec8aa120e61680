"""The embedded SQLite database in the data directory: WAL journal, schema migrations by user_version.

Writes share one connection behind a lock, each one ``BEGIN IMMEDIATE`` transaction, so a process killed
mid-write leaves the database as it was before that transaction. Reads use a connection per thread: in WAL
mode readers never wait for a writer (``GET /status`` stays fast while a job writes its progress).
"""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

from rigd.space import free_bytes, megabytes
from rigd.store import faults
from rigd.store.errors import StorageError, StoreError, StoreUnavailableError

_VERSION_COLUMNS = ("number", "created_at", "transform", "quality", "dataset_id", "dataset_hash", "method",
                    "parameters", "code_version", "supersedes", "change", "job_id")

# Migration i (1-based) brings the schema from user_version i-1 to i. Append, never edit a released one.
MIGRATIONS: tuple[str, ...] = (
    f"""
    CREATE TABLE versions (
        number INTEGER PRIMARY KEY,
        created_at TEXT NOT NULL,
        transform TEXT NOT NULL,
        quality TEXT NOT NULL,
        dataset_id TEXT,
        dataset_hash TEXT,
        method TEXT NOT NULL,
        parameters TEXT NOT NULL,
        code_version TEXT NOT NULL,
        supersedes INTEGER REFERENCES versions(number),
        change TEXT,
        job_id INTEGER,
        status TEXT NOT NULL CHECK (status IN ('candidate', 'active', 'superseded'))
    );
    CREATE UNIQUE INDEX versions_one_active ON versions(status) WHERE status = 'active';
    CREATE TRIGGER versions_immutable BEFORE UPDATE OF {", ".join(_VERSION_COLUMNS)} ON versions
    BEGIN SELECT RAISE(ABORT, 'extrinsics versions are immutable'); END;
    CREATE TRIGGER versions_kept BEFORE DELETE ON versions
    BEGIN SELECT RAISE(ABORT, 'extrinsics versions are never deleted'); END;
    CREATE TABLE activations (
        id INTEGER PRIMARY KEY,
        version INTEGER NOT NULL REFERENCES versions(number),
        activated_at TEXT NOT NULL
    );
    CREATE TABLE jobs (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        kind TEXT NOT NULL,
        status TEXT NOT NULL,
        params TEXT NOT NULL,
        stage TEXT NOT NULL DEFAULT '',
        fraction REAL NOT NULL DEFAULT 0,
        created_at TEXT NOT NULL,
        started_at TEXT,
        finished_at TEXT,
        result TEXT,
        error TEXT
    );
    CREATE INDEX jobs_by_status ON jobs(status);
    """,
)


def utc_now() -> str:
    """Now as ISO 8601 UTC with milliseconds, e.g. ``2025-01-31T12:00:00.123+00:00``."""
    return datetime.now(UTC).isoformat(timespec="milliseconds")


class Database:
    """The service's SQLite file. Use :meth:`read` for queries and :meth:`write` for transactions."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._lock = threading.RLock()
        self._local = threading.local()
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StoreError(f"{self.path.parent}: cannot create the data directory ({exc.strerror})") from exc
        self._conn = self._connect(check_same_thread=False)
        self._identity = self._file_identity()
        try:
            mode = self._conn.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            # FULL: a committed version survives a power cut too (the rig runs on batteries); writes are rare.
            self._conn.execute("PRAGMA synchronous=FULL")
        except sqlite3.Error as exc:  # e.g. a truncated or overwritten rigd.db: "file is not a database"
            self._conn.close()
            raise self._error("cannot open the database", exc) from exc
        if mode.lower() != "wal":
            raise StoreError(f"{self.path}: the file system does not support SQLite's WAL mode (got {mode})")
        self._migrate()

    def _error(self, what: str, exc: sqlite3.Error) -> StoreError:
        """``exc`` as the store's error: StorageError when the file system is full or read-only (with the free
        space), a damaged file named as such, else StoreError with SQLite's message."""
        code = getattr(exc, "sqlite_errorcode", 0) & 0xFF  # the primary code of an extended one
        if code in (sqlite3.SQLITE_FULL, sqlite3.SQLITE_READONLY, sqlite3.SQLITE_IOERR, sqlite3.SQLITE_CANTOPEN):
            return StorageError(f"{self.path}: {what} ({exc}); {megabytes(free_bytes(self.path))} free on its file "
                                "system: free some space (or make it writable); nothing was stored")
        if code in (sqlite3.SQLITE_NOTADB, sqlite3.SQLITE_CORRUPT):
            return StoreError(f"{self.path}: {what}: the file is damaged or not rigd's database ({exc}); restore it "
                              "from a backup, or move it away to start an empty store")
        return StoreError(f"{self.path}: {what} ({exc})")

    def _file_identity(self) -> tuple[int, int]:
        try:
            st = self.path.stat()
        except OSError as exc:
            raise StoreUnavailableError(
                f"{self.path}: the database was deleted or replaced while the service ran ({exc.strerror}; was "
                f"the data directory {self.path.parent} removed?): nothing is stored; restore it and restart "
                "rigd serve") from exc
        return st.st_dev, st.st_ino

    def check(self) -> None:
        """StoreUnavailableError unless the file opened at start is still at its path.

        SQLite keeps writing to a deleted (unlinked) file without complaint, and would go on reading a
        replaced one's predecessor: a write "stored" there is lost when the service stops.
        """
        if self._file_identity() != self._identity:
            raise StoreUnavailableError(
                f"{self.path}: the database was deleted or replaced while the service ran (another file is at its "
                f"path now): nothing is stored; restore it and restart rigd serve")

    def _connect(self, check_same_thread: bool) -> sqlite3.Connection:
        try:
            conn = sqlite3.connect(self.path, isolation_level=None, check_same_thread=check_same_thread,
                                   timeout=10.0)
            conn.row_factory = sqlite3.Row
            conn.execute("PRAGMA foreign_keys=ON")
        except sqlite3.Error as exc:
            raise StoreError(f"{self.path}: cannot open the database ({exc})") from exc
        return conn

    def _migrate(self) -> None:
        with self._lock:
            try:
                current = self._conn.execute("PRAGMA user_version").fetchone()[0]
            except sqlite3.Error as exc:
                raise self._error("cannot read the schema version", exc) from exc
            if current > len(MIGRATIONS):
                raise StoreError(f"{self.path}: schema version {current} is newer than this rigd "
                                 f"({len(MIGRATIONS)}); upgrade rigd")
            for number in range(current + 1, len(MIGRATIONS) + 1):
                try:
                    # executescript commits first; the script runs as one transaction with its version bump.
                    self._conn.executescript(f"BEGIN IMMEDIATE; {MIGRATIONS[number - 1]}; "
                                             f"PRAGMA user_version = {number}; COMMIT;")
                except sqlite3.Error as exc:
                    if self._conn.in_transaction:
                        self._conn.execute("ROLLBACK")
                    raise self._error(f"migration to schema {number} failed", exc) from exc

    @contextmanager
    def read(self) -> Iterator[sqlite3.Connection]:
        """This thread's read connection (each statement sees the last committed state)."""
        self.check()
        conn = getattr(self._local, "conn", None)
        if conn is None:
            conn = self._local.conn = self._connect(check_same_thread=True)
        try:
            yield conn
        except sqlite3.Error as exc:
            raise self._error("query failed", exc) from exc

    @contextmanager
    def write(self, label: str = "write") -> Iterator[sqlite3.Connection]:
        """One transaction: committed when the block ends, rolled back if it raises; StoreUnavailableError when
        the database file is gone before or after it (so that no caller acknowledges a write that is lost),
        StorageError when the file system is full or read-only. ``label`` names the transaction's fault points
        (``LABEL:commit`` just before the commit, ``LABEL:committed`` just after: rigd.store.faults)."""
        with self._lock:
            self.check()
            try:
                self._conn.execute("BEGIN IMMEDIATE")
            except sqlite3.Error as exc:
                raise self._error("cannot start a transaction", exc) from exc
            try:
                yield self._conn
                faults.at(f"{label}:commit")
                self._conn.execute("COMMIT")
            except BaseException as exc:
                # SQLite itself rolls back after some errors (a full disk): a second ROLLBACK would fail.
                if self._conn.in_transaction:
                    self._conn.execute("ROLLBACK")
                if isinstance(exc, sqlite3.Error):
                    raise self._error("write failed", exc) from exc
                raise
            faults.at(f"{label}:committed")
            self.check()  # deleted while the transaction ran: it committed into a file nobody will read

    def close(self) -> None:
        """Close the write connection (a thread's read connection closes when the thread ends)."""
        with self._lock:
            self._conn.close()
