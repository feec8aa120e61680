"""Errors raised by the application layer."""


class RigdError(Exception):
    """Base of every error raised by :mod:`rigd`; the CLI turns it into exit code 2."""


class DatasetError(RigdError):
    """A dataset, or a file in it, is missing or corrupt; the message names the file."""


class DatasetLockedError(DatasetError):
    """Another process is writing the dataset (a capture, an import); the message names it."""
