"""What the job runner's threads share under one lock: the running jobs a cancel was asked for and whether the
service stops; every job looks at it before it starts and when it ends."""

from __future__ import annotations

import threading

from rigd.store import JobKind

WORKER_KINDS = (JobKind.CALIBRATE, JobKind.CHECK)  # the jobs of the queue and the worker process


class RunnerState:
    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.cancelled: set[int] = set()  # running jobs asked to stop
        self.stopping = False  # the service stops: nothing new starts, what runs is interrupted

    def ending(self, job_id: int) -> bool:
        """Whether job ``job_id`` is to stop now: it was cancelled or the service stops."""
        with self.lock:
            return job_id in self.cancelled or self.stopping

    def take_cancel(self, job_id: int) -> bool:
        """Whether job ``job_id``, which has ended, was cancelled (and forget the cancel)."""
        with self.lock:
            cancelled = job_id in self.cancelled
            self.cancelled.discard(job_id)
            return cancelled
