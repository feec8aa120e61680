"""An exclusive, non-blocking ``flock`` on a lock file that names its holder.

Used for one ``rigd serve`` per data directory (rigd.store.lock), and for one writer or many readers per
dataset (rigd.dataset.lock). The kernel drops a ``flock`` when its process dies, however it dies, so a stale lock file
never blocks a restart; the file is never deleted (a process could be locking the inode being unlinked).
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

from rigd.errors import LockHeldError


def _read_holder(fd: int) -> str:
    try:
        return os.pread(fd, 512, 0).decode("utf-8", "replace").strip()
    except OSError:
        return ""


def _lock(fd: int, operation: int) -> None:
    """``flock(fd, operation)`` without waiting; LockHeldError naming the holder, ``fd`` closed on any failure."""
    try:
        fcntl.flock(fd, operation | fcntl.LOCK_NB)
    except BlockingIOError:
        text = _read_holder(fd)
        os.close(fd)
        raise LockHeldError(text) from None
    except OSError:
        os.close(fd)
        raise


def take_shared(path: Path) -> int | None:
    """A shared ``flock`` on ``path`` (created if it can be): many readers hold it at once, a writer's
    exclusive lock excludes them and they it. None when the file can neither be created nor opened (a dataset
    on a read-only medium, which no process can write anyway). Raises :class:`LockHeldError` naming the
    writer when one holds it; the descriptor is not inherited by child processes: closing it releases."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError:
        try:
            fd = os.open(path, os.O_RDONLY)
        except OSError:
            return None
    _lock(fd, fcntl.LOCK_SH)
    return fd


def take(path: Path, holder: str) -> int:
    """Open ``path`` (created), lock it and write ``holder`` into it once the lock is ours (so the file always
    names the live holder); returns the descriptor, not inherited by child processes: closing it releases.
    Raises :class:`LockHeldError` when another process has the lock, OSError when the file cannot be used."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    _lock(fd, fcntl.LOCK_EX)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{holder}\n".encode(), 0)
    except OSError:
        os.close(fd)
        raise
    return fd
