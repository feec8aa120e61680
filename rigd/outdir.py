"""What a command writes: never over one of its inputs, never over what another run wrote unless told
(``--overwrite``), and never seen half written.

A folder is written as a temporary folder beside it (``.NAME.XXXX.partial``) and renamed into place once
complete; with ``--overwrite`` the folder it replaces goes as a whole, so no file of an earlier run is left
beside the new ones. A file is written to a temporary name in its folder and renamed over its target.
Refusals are :class:`OutputError` (exit 73); a full or read-only file system is :class:`DiskError` (exit 74).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from rigd.errors import DiskError, OutputError
from rigd.space import is_storage_error, os_reason, write_failure

PARTIAL = ".partial"  # the suffix of a folder or file being written (left behind only by a killed run)


def _overlap(target: Path, inputs: Sequence[Path]) -> str | None:
    """How ``target`` would write over one of ``inputs``, or None."""
    out = Path(os.path.realpath(target))
    for given in inputs:
        source = Path(os.path.realpath(given))
        if out == source:
            return f"it is the input {given}"
        if out.is_relative_to(source):
            return f"it is inside the input {given}"
        if source.is_relative_to(out):
            return f"the input {given} is inside it"
    return None


def write_error(path: Path, exc: OSError) -> DiskError | OutputError:
    """A failed write of ``path`` as rigd's error: DiskError for a full or read-only file system, else OutputError."""
    text = write_failure(path, os_reason(exc))
    return DiskError(text) if is_storage_error(exc) else OutputError(text)


def _check_target(target: Path, inputs: Sequence[Path], overwrite: bool, kind: str) -> None:
    overlap = _overlap(target, inputs)
    if overlap is not None:
        raise OutputError(f"{target}: refusing to write the output there: {overlap}")
    if target.exists() and (target.is_dir() != (kind == "folder")):
        raise OutputError(f"{target}: exists and is not a {kind}")
    if kind == "folder" and target.is_dir():
        held = sorted(p.name for p in target.iterdir())
        if held and not overwrite:
            raise OutputError(f"{target}: the folder holds {len(held)} entries already ({', '.join(held[:3])}"
                              f"{', ...' if len(held) > 3 else ''}): give a new or empty folder, or --overwrite to "
                              "replace it as a whole")
        if held and Path.cwd().resolve().is_relative_to(target.resolve()):
            raise OutputError(f"{target}: refusing to replace the folder this command runs in")
    elif kind == "file" and target.exists() and not overwrite:
        raise OutputError(f"{target}: exists already: give another file, or --overwrite to replace it")


@contextmanager
def claim_output_dir(target: Path, *, inputs: Sequence[Path] = (), overwrite: bool = False) -> Iterator[Path]:
    """A temporary folder to write ``target``'s content into: put in ``target``'s place when the block ends,
    removed if it raises. Refused (OutputError, before anything is written) when ``target`` is, holds or is
    inside one of ``inputs``, or holds anything and ``overwrite`` is False; with ``overwrite`` the old folder is
    replaced as a whole."""
    target = Path(target)
    _check_target(target, inputs, overwrite, "folder")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=PARTIAL, dir=target.parent))
    except OSError as exc:
        raise write_error(target, exc) from exc
    try:
        yield partial
        _put_in_place(partial, target)
    except BaseException:
        with contextlib.suppress(OSError):  # the error that stopped the write is the one to report
            shutil.rmtree(partial)
        raise


def _put_in_place(partial: Path, target: Path) -> None:
    """Rename the complete ``partial`` folder to ``target``, the old ``target`` (if it holds anything) out of
    the way first and then removed."""
    old = None
    try:
        if target.is_dir() and any(target.iterdir()):
            old = target.with_name(f"{partial.name[:-len(PARTIAL)]}.replaced")
            target.rename(old)
        partial.rename(target)  # over an empty folder, or into a free name
        fsync_path(target.parent)
    except OSError as exc:
        if old is not None and not target.exists():
            with contextlib.suppress(OSError):
                old.rename(target)
        raise write_error(target, exc) from exc
    if old is not None:
        shutil.rmtree(old)


def write_output_file(target: Path, text: str, *, inputs: Sequence[Path] = (), overwrite: bool = False) -> None:
    """Write ``text`` to ``target`` through a temporary file renamed over it. Refused (OutputError) when
    ``target`` is one of ``inputs`` (even with ``overwrite``), or exists and ``overwrite`` is False."""
    target = Path(target)
    _check_target(target, inputs, overwrite, "file")
    partial: Path | None = None
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=PARTIAL, dir=target.parent)
        partial = Path(name)
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        partial.replace(target)
    except OSError as exc:
        if partial is not None:
            with contextlib.suppress(OSError):
                partial.unlink(missing_ok=True)
        raise write_error(target, exc) from exc


def claim_output_files(targets: Sequence[Path], *, overwrite: bool = False) -> None:
    """Refuse (OutputError, before any work) files a run would write over that an earlier run wrote, unless
    ``overwrite``: a command that writes several named files into a shared folder (an evaluation's report and plot)
    checks them all at its start rather than after its long run."""
    for target in targets:
        _check_target(Path(target), (), overwrite, "file")


def fsync_path(path: Path) -> None:
    """Flush a file's or a folder's data and metadata to disk (a folder: the renames in it)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
