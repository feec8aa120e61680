"""Where a write failed for lack of room: the errors a full or read-only file system gives, and the message that
names the path and the free space (the CLI's exit code 74, the service's 507)."""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

# A full file system or quota, or one mounted read-only (a rig's SD card remounted after errors), or a folder
# this process may not write: nothing the request could change, only the operator.
STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG})


def is_storage_error(exc: BaseException) -> bool:
    """Whether ``exc`` (or its cause) is an OSError of a full or read-only file system."""
    while exc is not None:
        if isinstance(exc, OSError) and exc.errno in STORAGE_ERRNOS:
            return True
        exc = exc.__cause__  # type: ignore[assignment]
    return False


def free_bytes(path: Path) -> int | None:
    """Free bytes (for this user) on the file system of ``path`` or of its nearest existing parent; None when
    even that cannot be read."""
    path = Path(os.path.abspath(path))
    for candidate in (path, *path.parents):
        try:
            return shutil.disk_usage(candidate).free
        except OSError:
            continue
    return None


def megabytes(n: int | None) -> str:
    return "unknown" if n is None else f"{n / 1e6:.1f} MB"


def write_failure(path: Path, reason: str) -> str:
    """``PATH: cannot write (REASON); N MB free on its file system``."""
    return f"{path}: cannot write ({reason}); {megabytes(free_bytes(path))} free on its file system"


def os_reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def os_error_text(exc: OSError) -> str:
    """``PATH: REASON``, with the free space when the file system refused a write."""
    where = Path(exc.filename) if exc.filename else Path.cwd()
    text = f"{where}: {os_reason(exc)}"
    return f"{text}; {megabytes(free_bytes(where))} free on its file system" if is_storage_error(exc) else text
