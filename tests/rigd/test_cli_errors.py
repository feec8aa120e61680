"""How the ``rigd`` command ends on an error: each kind with its own code, none a verdict's (rigd check's 1 is
"drifted", 2 "unknown"), and a message naming the thing."""

from __future__ import annotations

import errno
import os

import pytest

import rigd
import rigd.cli.export
from rigd.cli import main
from rigd.cli.exit_codes import IO_ERROR, SOFTWARE, USAGE


def failing(exc: BaseException):
    def run(args):
        raise exc

    return run


def test_a_bug_exits_70_with_its_traceback(monkeypatch, capsys):
    monkeypatch.setattr(rigd.cli.export, "run", failing(IndexError("index 0 is out of bounds")))
    assert main(["export", "x.yaml", "--format", "urdf"]) == SOFTWARE
    err = capsys.readouterr().err
    assert "Traceback" in err and "rigd: internal error (a bug" in err and "IndexError" in err


def test_a_full_disk_no_layer_named_exits_74_with_the_path_and_free_space(monkeypatch, capsys, tmp_path):
    full = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "out" / "a.pcd"))
    monkeypatch.setattr(rigd.cli.export, "run", failing(full))
    assert main(["export", "x.yaml", "--format", "urdf"]) == IO_ERROR
    err = capsys.readouterr().err
    assert f"rigd: error: {tmp_path / 'out' / 'a.pcd'}: No space left on device; " in err and "MB free" in err


def test_a_wrong_command_line_exits_64(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["export", "x.yaml", "--format", "nope"])
    assert exit_info.value.code == USAGE and "invalid choice" in capsys.readouterr().err


def test_numba_caches_in_the_temporary_folder_when_it_can_write_nowhere_else(monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("HOME", "/nonexistent")
    monkeypatch.setattr(rigd, "_can_create", lambda folder: False)  # a system install, no writable HOME
    cache = rigd.numba_cache_dir()
    assert cache is not None and cache.name == f"rigd-numba-cache-{os.getuid()}"
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere")
    assert rigd.numba_cache_dir() is None  # the operator's choice stands


def test_the_demo_and_export_head_write_over_nothing_they_did_not_make(tmp_path, capsys):
    """A folder of someone else's files is not the demo's; a head file already there stays: exit 73 at once."""
    from rigd.cli.exit_codes import CANT_CREATE

    theirs = tmp_path / "theirs"
    theirs.mkdir()
    (theirs / "notes.txt").write_text("mine\n")
    assert main(["demo", "--out", str(theirs)]) == CANT_CREATE
    assert "holds files of something other than rigd demo" in capsys.readouterr().err
    head = tmp_path / "head.yaml"
    head.write_text("an earlier head\n")
    assert main(["camera", "export-head", "--out", str(head), "--layout", str(tmp_path / "absent.yaml")]) \
        == CANT_CREATE
    assert head.read_text() == "an earlier head\n" and "--overwrite" in capsys.readouterr().err
