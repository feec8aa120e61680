"""One writer per dataset: an exclusive ``flock`` on ``DATASET/.rigd.lock`` while a process writes it.

Two captures into one folder would both take the next pair index from the folder and delete each other's
``pairs/.NNNN.tmp`` as a leftover. A capture holds the lock for its whole run; :func:`writing` lets
``write_pair`` run under the lock its caller holds, or take it for the one write. The kernel drops a
``flock`` when its process dies, however it dies, so a stale lock file never blocks a rerun; the file is
never deleted (a process could be locking the inode being unlinked).
"""

from __future__ import annotations

import fcntl
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rigd.errors import DatasetError, DatasetLockedError

LOCK_FILE = ".rigd.lock"

_held: dict[Path, DatasetLock] = {}  # datasets this process holds the lock of, by resolved folder
_held_guard = threading.Lock()


def _holder(fd: int) -> str:
    """What the holder wrote into the lock file: "pid N: command line", or "" if it cannot be read."""
    try:
        return os.pread(fd, 512, 0).decode("utf-8", "replace").strip()
    except OSError:
        return ""


def _describe_self() -> str:
    try:
        argv = Path("/proc/self/cmdline").read_bytes().split(b"\0")
    except OSError:  # not Linux: the pid alone
        return f"pid {os.getpid()}"
    return f"pid {os.getpid()}: {' '.join(a.decode('utf-8', 'replace') for a in argv if a)}"[:400]


class DatasetLock:
    """The writer lock of one dataset, held from :meth:`acquire` to :meth:`release` (or the process's end)."""

    def __init__(self, root: Path, fd: int) -> None:
        self.root = root
        self._key = root.resolve()  # as registered: the folder may be renamed while held
        self._fd = fd

    @classmethod
    def acquire(cls, root: Path) -> DatasetLock:
        """Lock ``root`` (created if missing), or raise DatasetLockedError naming the holder at once."""
        root = Path(root)
        path = root / LOCK_FILE
        try:
            root.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DatasetError(f"{root}: cannot create the dataset folder ({exc.strerror})") from exc
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)  # not inherited by children
        except OSError as exc:
            raise DatasetError(f"{root}: cannot write into the dataset folder ({exc.strerror}: {path.name})") from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = _holder(fd)
            os.close(fd)
            if isinstance(exc, BlockingIOError):
                raise DatasetLockedError(
                    f"dataset {root} is being written by another process ({holder or 'pid unknown'}): wait for it "
                    "to finish, stop it, or write into another folder") from exc
            raise DatasetError(f"{path}: cannot lock the dataset ({exc.strerror})") from exc
        lock = cls(root, fd)
        try:  # written once the lock is ours, so the file names the live holder
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{_describe_self()}\n".encode(), 0)
        except OSError as exc:
            lock.release()
            raise DatasetError(f"{path}: cannot write the lock file ({exc.strerror})") from exc
        with _held_guard:
            _held[lock._key] = lock
        return lock

    def release(self) -> None:
        if self._fd < 0:
            return
        with _held_guard:
            if _held.get(self._key) is self:
                del _held[self._key]
        os.close(self._fd)  # closing the only descriptor drops the flock
        self._fd = -1

    def __enter__(self) -> DatasetLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


@contextmanager
def writing(root: Path) -> Iterator[None]:
    """Run a write under ``root``'s lock: the one this process holds, else one taken for the write."""
    with _held_guard:
        held = Path(root).resolve() in _held
    if held:
        yield
        return
    with DatasetLock.acquire(root):
        yield
