"""Errors of the store layer; the HTTP layer maps them to status codes (the store knows nothing of HTTP)."""

from rigd.errors import DataDirLockedError, DiskError, RigdError


class StoreError(RigdError):
    """Base of the store's errors: the database file cannot be opened, migrated or written."""


class NotFoundError(StoreError):
    """A version, job or dataset that does not exist; the message names it."""


class ConflictError(StoreError):
    """The request contradicts the current state (a finished job cancelled, no active version, ...)."""


class StoreUnavailableError(StoreError):
    """The database file is gone or was replaced under the running service: nothing can be read or stored."""


class StorageError(StoreError, DiskError):
    """The data directory takes no write: its file system is full or read-only (the message names the path and
    the free space). Nothing was stored; the same request succeeds once there is room again."""


__all__ = ["ConflictError", "DataDirLockedError", "NotFoundError", "StorageError", "StoreError",
           "StoreUnavailableError"]
