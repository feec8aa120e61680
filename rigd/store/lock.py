"""One service per data directory: an exclusive ``flock`` on ``DATA_DIR/rigd.lock`` for the process lifetime.

Two services on one data directory would each take the other's jobs for leftovers of a crash (marking a
running job failed while its worker still stores a version) and run two calibrations at once. The kernel
drops the lock when the process dies, however it dies, so a stale lock file never blocks a restart.
"""

from __future__ import annotations

import os
from pathlib import Path

from rigd.errors import LockHeldError
from rigd.flock import take
from rigd.store.errors import DataDirLockedError, StoreError

LOCK_FILE = "rigd.lock"


class DataDirLock:
    """Held from :meth:`acquire` to :meth:`release` (or the end of the process)."""

    def __init__(self, path: Path, fd: int) -> None:
        self.path = path
        self._fd = fd

    @classmethod
    def acquire(cls, data_dir: Path) -> DataDirLock:
        """Lock ``data_dir`` (created if missing); DataDirLockedError naming the holder's pid if it is taken."""
        path = Path(data_dir) / LOCK_FILE
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd = take(path, str(os.getpid()))  # not inherited by the calibration workers
        except LockHeldError as held:
            pid = held.holder if held.holder.isdigit() else "unknown"
            raise DataDirLockedError(
                f"data directory {data_dir} is in use by another rigd serve (pid {pid}); stop that one "
                "or give this one another --data-dir") from held
        except OSError as exc:
            raise StoreError(f"{path}: cannot lock the data directory ({exc.strerror})") from exc
        return cls(path, fd)

    def release(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)  # closing the only descriptor drops the flock
            self._fd = -1
