"""Errors of the service layer itself (neither store nor dataset errors); ``rigd.api.main`` maps them to
status codes, the routers and the runner never raise HTTP errors."""

from rigd.errors import RigdError


class ServiceError(RigdError):
    """Base of the service layer's errors."""


class QueueFullError(ServiceError):
    """Too many calibrations wait already; ``retry_after_s`` is when asking again is worth it."""

    def __init__(self, message: str, retry_after_s: int) -> None:
        super().__init__(message)
        self.retry_after_s = retry_after_s
