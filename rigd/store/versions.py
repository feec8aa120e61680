"""Immutable extrinsics versions: store, list, activate. Exactly one is active once any exists."""

from __future__ import annotations

import builtins
import dataclasses
import json
import sqlite3
from collections.abc import Callable, Collection

import numpy as np

from calib.geometry import Transform, rotation_angle_deg
from rigd.dataset.records import transform_to_yaml
from rigd.report import verdict_of
from rigd.results import JobResult
from rigd.store.db import Database, utc_now
from rigd.store.errors import ConflictError, NotFoundError, StoreError
from rigd.store.jobs import JobEnd, finish_in
from rigd.store.jsonsafe import json_safe
from rigd.store.records import Change, ExtrinsicsVersion, JobStatus, NewVersion, VersionStatus

# Decides, inside the storing transaction, whether a new version becomes active, from its change against
# the active one (None when there is none; the first version is activated unless its verdict distrusts it).
ActivationPolicy = Callable[[Change | None], bool]

_SELECT = """
    SELECT v.*, (SELECT max(a.activated_at) FROM activations a WHERE a.version = v.number) AS activated_at
    FROM versions v
"""


def change_between(active: ExtrinsicsVersion, T: Transform) -> Change:
    A = active.T_camera_lidar
    return Change(
        against=active.number,
        rotation_deg=rotation_angle_deg(A.rotation, T.rotation),
        translation_cm=float(np.linalg.norm(T.translation_m - A.translation_m) * 100.0),
    )


_VERSION_COLUMNS = ("number", "created_at", "method", "code_version", "dataset_id", "dataset_hash", "job_id",
                    "supersedes", "activated_at")  # stored as they are


def _row_to_version(row: sqlite3.Row) -> ExtrinsicsVersion:
    change = json.loads(row["change"]) if row["change"] else None
    return ExtrinsicsVersion(
        T_camera_lidar=Transform.from_matrix(np.asarray(json.loads(row["transform"])["matrix"])),
        quality=json.loads(row["quality"]), parameters=json.loads(row["parameters"]),
        change=Change(**change) if change else None, status=VersionStatus(row["status"]),
        **{column: row[column] for column in _VERSION_COLUMNS})


class VersionStore:
    def __init__(self, db: Database) -> None:
        self.db = db

    def add(self, new: NewVersion, activate: ActivationPolicy,
            job_result: Callable[[ExtrinsicsVersion], JobResult] | None = None,
            comparable: Callable[[ExtrinsicsVersion], bool] | None = None) -> ExtrinsicsVersion:
        """Store ``new`` as the next version; make it active if ``activate`` says so, or if none is active and
        ``new`` is not a calibration its own verdict distrusts (docs/trust.md: an untrusted result is never
        activated without a person asking for it). ``job_result``: the job ``new.job_id`` succeeds with this
        result of the stored version in the same transaction, so a crash leaves both or neither (ConflictError,
        and nothing stored, when that job has ended already). ``comparable(active)``: whether ``new`` may be compared
        with the active version (two rigs' versions differ by their mounts: no change is recorded between them)."""
        with self.db.write("versions.add") as conn:
            active = self._active(conn)
            compared = active is not None and (comparable is None or comparable(active))
            change = change_between(active, new.T_camera_lidar) if active is not None and compared else None
            cursor = conn.execute(
                "INSERT INTO versions (created_at, transform, quality, dataset_id, dataset_hash, method, parameters,"
                " code_version, supersedes, change, job_id, status) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (utc_now(), json.dumps(transform_to_yaml(new.T_camera_lidar)), json.dumps(json_safe(new.quality)),
                 new.dataset_id, new.dataset_hash, new.method, json.dumps(json_safe(new.parameters)), new.code_version,
                 active.number if active else None, json.dumps(dataclasses.asdict(change)) if change else None,
                 new.job_id, VersionStatus.CANDIDATE.value),
            )
            number = int(cursor.lastrowid or 0)
            verdict = verdict_of(new.quality)
            trusted = verdict is None or verdict["status"] == "trusted"  # a manual version has no verdict
            if (active is None and trusted) or activate(change):
                self._activate(conn, number)
            version = self._get(conn, number)
            if job_result is not None:
                if new.job_id is None:
                    raise StoreError("a version without a job cannot end one")
                if not finish_in(conn, new.job_id, JobEnd(JobStatus.SUCCEEDED, "done", job_result(version))):
                    raise ConflictError(f"job {new.job_id} has ended already: its version is not stored")
            return version

    def get(self, number: int) -> ExtrinsicsVersion:
        with self.db.read() as conn:
            return self._get(conn, number)

    def list(self) -> list[ExtrinsicsVersion]:
        with self.db.read() as conn:
            return [_row_to_version(r) for r in conn.execute(_SELECT + " ORDER BY v.number")]

    def newest(self, limit: int) -> builtins.list[ExtrinsicsVersion]:  # (``list`` is the method below)
        """The ``limit`` newest versions, newest first (a page of the list, not all of it)."""
        with self.db.read() as conn:
            return [_row_to_version(r) for r in conn.execute(_SELECT + " ORDER BY v.number DESC LIMIT ?", (limit,))]

    def numbered(self, numbers: Collection[int]) -> dict[int, ExtrinsicsVersion]:
        """The versions of ``numbers`` that exist, by number."""
        if not numbers:
            return {}
        marks = ", ".join("?" * len(numbers))
        with self.db.read() as conn:
            rows = conn.execute(_SELECT + f" WHERE v.number IN ({marks})", tuple(numbers))
            return {row["number"]: _row_to_version(row) for row in rows}

    def newest_calibration(self) -> ExtrinsicsVersion | None:
        """The newest version a calibration job stored (one with overlays), or None."""
        with self.db.read() as conn:
            row = conn.execute(_SELECT + " WHERE v.job_id IS NOT NULL ORDER BY v.number DESC LIMIT 1").fetchone()
            return _row_to_version(row) if row else None

    def count(self) -> int:
        with self.db.read() as conn:
            return int(conn.execute("SELECT count(*) FROM versions").fetchone()[0])

    def active(self) -> ExtrinsicsVersion | None:
        with self.db.read() as conn:
            return self._active(conn)

    def activate(self, number: int) -> ExtrinsicsVersion:
        """Make ``number`` the active version (the previous one becomes superseded); idempotent."""
        with self.db.write("versions.activate") as conn:
            version = self._get(conn, number)
            if version.status is not VersionStatus.ACTIVE:
                self._activate(conn, number)
            return self._get(conn, number)

    @staticmethod
    def _activate(conn: sqlite3.Connection, number: int) -> None:
        conn.execute("UPDATE versions SET status = ? WHERE status = ?",
                     (VersionStatus.SUPERSEDED.value, VersionStatus.ACTIVE.value))
        conn.execute("UPDATE versions SET status = ? WHERE number = ?", (VersionStatus.ACTIVE.value, number))
        conn.execute("INSERT INTO activations (version, activated_at) VALUES (?, ?)", (number, utc_now()))

    @staticmethod
    def _get(conn: sqlite3.Connection, number: int) -> ExtrinsicsVersion:
        row = conn.execute(_SELECT + " WHERE v.number = ?", (number,)).fetchone()
        if row is None:
            raise NotFoundError(f"extrinsics version {number} does not exist")
        return _row_to_version(row)

    @staticmethod
    def _active(conn: sqlite3.Connection) -> ExtrinsicsVersion | None:
        row = conn.execute(_SELECT + " WHERE v.status = ?", (VersionStatus.ACTIVE.value,)).fetchone()
        return _row_to_version(row) if row else None
