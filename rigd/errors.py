"""Errors raised by the application layer."""


class RigdError(Exception):
    """Base of every error raised by :mod:`rigd`; the CLI turns it into exit code 2."""


class DatasetError(RigdError):
    """A dataset, or a file in it, is missing or corrupt; the message names the file."""


class DatasetLockedError(DatasetError):
    """Another process is writing the dataset (a capture, an import); the message names it."""


class LockHeldError(RigdError):
    """Another process holds a lock file (:mod:`rigd.flock`); ``holder`` is what it wrote into it ("" if
    unreadable). The lock's owner turns it into its own error naming what is locked."""

    def __init__(self, holder: str) -> None:
        super().__init__(holder)
        self.holder = holder
