"""The service's store: jobs and immutable extrinsics versions in SQLite (WAL) in the data directory.

It raises only :mod:`rigd.store.errors` (never anything HTTP); the API maps them to status codes.
"""

from rigd.locks import DataDirLock
from rigd.store.db import Database
from rigd.store.errors import (
    ConflictError,
    DataDirLockedError,
    NotFoundError,
    StorageError,
    StoreError,
    StoreUnavailableError,
)
from rigd.store.jobs import JobStore
from rigd.store.records import (
    Change,
    ExtrinsicsVersion,
    Job,
    JobKind,
    JobStatus,
    NewVersion,
    VersionStatus,
)
from rigd.store.versions import ActivationPolicy, VersionStore, change_between

__all__ = [
    "ActivationPolicy",
    "Change",
    "ConflictError",
    "DataDirLock",
    "DataDirLockedError",
    "Database",
    "ExtrinsicsVersion",
    "Job",
    "JobKind",
    "JobStatus",
    "JobStore",
    "NewVersion",
    "NotFoundError",
    "StorageError",
    "StoreError",
    "StoreUnavailableError",
    "VersionStatus",
    "VersionStore",
    "change_between",
]
