"""rigd package."""

import os
import tempfile
from importlib.util import find_spec
from pathlib import Path


def _can_create(folder: Path) -> bool:
    """Whether this process can write ``folder``, or create it in its nearest existing parent."""
    for candidate in (folder, *folder.parents):
        if candidate.exists():
            return candidate.is_dir() and os.access(candidate, os.W_OK | os.X_OK)
    return False


def numba_cache_dir() -> Path | None:
    """Where numba must cache calib's compiled kernels, when neither of its own places can be written: None
    when one can (or NUMBA_CACHE_DIR is set).

    calib compiles its kernels with ``cache=True``, and numba then refuses to import them (RuntimeError "no
    locator available") unless it can write a cache beside calib's source or in the user's cache folder: a
    system install run by a service user without a writable HOME could not even print ``rigd --version``."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    spec = find_spec("calib")
    beside = Path(spec.origin).parent / "__pycache__" if spec is not None and spec.origin else None
    home = os.environ.get("HOME")
    user = Path(os.environ.get("XDG_CACHE_HOME") or (Path(home) / ".cache" if home else "/nonexistent")) / "numba"
    if any(folder is not None and _can_create(folder) for folder in (beside, user)):
        return None
    return Path(tempfile.gettempdir()) / f"rigd-numba-cache-{os.getuid()}"


if (_cache := numba_cache_dir()) is not None:  # before anything imports calib's kernels
    os.environ["NUMBA_CACHE_DIR"] = str(_cache)
