"""The locks of rigd, each an ``flock`` on a lock file that names its holder: one ``rigd serve`` per data
directory (:class:`DataDirLock`, ``DATA_DIR/rigd.lock``, for the process's lifetime), and one writer or many
readers per dataset (:class:`DatasetLock`, ``DATASET/.rigd.lock``: exclusive while a process writes the dataset,
shared while one calibrates or checks it).

Two services on one data directory would each take the other's jobs for leftovers of a crash (marking a running
job failed while its worker still stores a version) and run two calibrations at once. Two captures into one folder
would both take the next pair index from the folder and delete each other's ``pairs/.NNNN.tmp`` as a leftover; a
capture into a dataset being calibrated would change the pairs under the calibration, whose version would then
claim data it was not made from. A capture holds the exclusive lock for its whole run; :func:`writing` lets
``write_pair`` run under the lock its caller holds, or take it for the one write; :func:`reading` holds the shared
one for a calibration or a check. The kernel drops a ``flock`` when its process dies, however it dies, so a stale
lock file never blocks a restart; the file is never deleted (a process could be locking the inode being unlinked).
"""

from __future__ import annotations

import fcntl
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rigd.errors import DataDirLockedError, DatasetError, DatasetLockedError, LockHeldError, RigdError


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


DATA_DIR_LOCK_FILE = "rigd.lock"


class DataDirLock:
    """Held from :meth:`acquire` to :meth:`release` (or the end of the process)."""

    def __init__(self, path: Path, fd: int) -> None:
        self.path = path
        self._fd = fd

    @classmethod
    def acquire(cls, data_dir: Path) -> DataDirLock:
        """Lock ``data_dir`` (created if missing); DataDirLockedError naming the holder's pid if it is taken."""
        path = Path(data_dir) / DATA_DIR_LOCK_FILE
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd = take(path, str(os.getpid()))  # not inherited by the calibration workers
        except LockHeldError as held:
            pid = held.holder if held.holder.isdigit() else "unknown"
            raise DataDirLockedError(
                f"data directory {data_dir} is in use by another rigd serve (pid {pid}); stop that one "
                "or give this one another --data-dir") from held
        except OSError as exc:
            raise RigdError(f"{path}: cannot lock the data directory ({exc.strerror})") from exc
        return cls(path, fd)

    def release(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)  # closing the only descriptor drops the flock
            self._fd = -1


DATASET_LOCK_FILE = ".rigd.lock"

_held: dict[Path, DatasetLock] = {}  # datasets this process holds the lock of, by resolved folder
_held_guard = threading.Lock()


def _describe_self() -> str:
    try:
        argv = Path("/proc/self/cmdline").read_bytes().split(b"\0")
    except OSError:  # not Linux: the pid alone
        return f"pid {os.getpid()}"
    return f"pid {os.getpid()}: {' '.join(a.decode('utf-8', 'replace') for a in argv if a)}"[:400]


def _only_readers(path: Path) -> bool:
    """Whether the holders of ``path``'s lock share it (calibrations, checks) rather than one writer having it."""
    try:
        fd = take_shared(path)
    except (LockHeldError, OSError):
        return False
    if fd is not None:
        os.close(fd)
    return fd is not None


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
        path = root / DATASET_LOCK_FILE
        try:
            root.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DatasetError(f"{root}: cannot create the dataset folder ({exc.strerror})") from exc
        try:
            fd = take(path, _describe_self())
        except LockHeldError as held:
            if _only_readers(path):
                raise DatasetLockedError(
                    f"dataset {root} is being calibrated or checked: write into it when that has finished, or "
                    "into another folder") from held
            raise DatasetLockedError(
                f"dataset {root} is being written by another process ({held.holder or 'pid unknown'}): wait for "
                "it to finish, stop it, or write into another folder") from held
        except OSError as exc:  # a read-only or full file system, mostly
            raise DatasetError(f"{root}: cannot write into the dataset folder ({exc.strerror}: "
                               f"{DATASET_LOCK_FILE})") from exc
        lock = cls(root, fd)
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


@contextmanager
def reading(root: Path) -> Iterator[None]:
    """Hold ``root``'s lock shared while the block reads the dataset (a calibration, a check): DatasetLockedError
    at once while a process writes it, and a capture into it is refused until the block ends. A dataset whose
    lock file cannot be made (read-only medium) is read without it: nothing can write it either."""
    path = Path(root) / DATASET_LOCK_FILE
    try:
        fd = take_shared(path) if Path(root).is_dir() else None
    except LockHeldError as held:
        raise DatasetLockedError(
            f"dataset {root} is being written by another process ({held.holder or 'pid unknown'}): calibrate or "
            "check it when that has finished") from held
    except OSError as exc:
        raise DatasetError(f"{path}: cannot lock the dataset for reading ({exc.strerror})") from exc
    try:
        yield
    finally:
        if fd is not None:
            os.close(fd)
