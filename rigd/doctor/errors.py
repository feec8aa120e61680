"""Errors of ``rigd doctor``. The checks themselves never raise: what they find is a :class:`Check` line."""

from rigd.errors import RigdError


class DoctorError(RigdError):
    """Base of doctor errors: options the checks cannot run with."""
