"""Errors raised by the application layer."""


class RigdError(Exception):
    """Base of every error raised by :mod:`rigd`; the CLI prints it and exits 65 (rigd.cli.exit_codes)."""


class DiskError(RigdError):
    """A write found its file system full, over quota or read-only; the message names the path and the free
    space (the CLI exits 74, the service answers 507)."""


class OutputError(RigdError):
    """An output is refused before anything is written: it is one of the command's inputs, or it holds what
    another run wrote and ``--overwrite`` was not given (the CLI exits 73)."""


class DatasetError(RigdError):
    """A dataset, or a file in it, is missing or corrupt; the message names the file."""


class DatasetLockedError(DatasetError):
    """Another process is writing the dataset (a capture, an import); the message names it."""


class LockHeldError(RigdError):
    """Another process holds a lock file (:mod:`rigd.locks`); ``holder`` is what it wrote into it ("" if
    unreadable). The lock's owner turns it into its own error naming what is locked."""

    def __init__(self, holder: str) -> None:
        super().__init__(holder)
        self.holder = holder


class DataDirLockedError(RigdError):
    """Another process (another ``rigd serve``) holds the data directory; the message names its pid."""


class WorkerLostError(RigdError):
    """A worker process of a calibration ended abruptly (killed, or by the kernel for want of memory) and took its
    task with it; nothing of the calibration was written (the CLI exits 71)."""
