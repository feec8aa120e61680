"""Capture jobs: one at a time (it holds the sensors), each in a thread of its own, never into a dataset a
calibration or a check reads; its end recorded with what it wrote, also when it fails or is cancelled."""

from __future__ import annotations

import threading
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from drivers.errors import DriverError
from rigd.api.runner_state import WORKER_KINDS, RunnerState
from rigd.errors import RigdError
from rigd.results import CaptureJobResult
from rigd.space import os_reason, write_failure
from rigd.store import ConflictError, Job, JobKind, JobStatus, JobStore

CaptureWork = Callable[[Job, threading.Event], CaptureJobResult]


class CaptureJobs:
    """The captures the runner runs; ``datasets_root``: where a write no layer named is reported."""

    def __init__(self, jobs: JobStore, datasets_root: Path, state: RunnerState) -> None:
        self.jobs = jobs
        self.datasets_root = datasets_root
        self.state = state
        self._captures: dict[int, tuple[str, threading.Event, threading.Thread]] = {}

    def capturing(self) -> set[str]:
        """Ids of the datasets being captured now."""
        with self.state.lock:
            return {dataset for dataset, _, _ in self._captures.values()}

    def submit(self, dataset_id: str, params: dict[str, Any], work: CaptureWork) -> Job:
        """Start ``work(job, stop)`` in a thread; ConflictError while another capture holds the sensors."""
        with self.state.lock:
            if self.state.stopping:
                raise ConflictError("the service is stopping")
            if self._captures:  # the runner's own, not the database's: a job it never ran holds no sensor
                raise ConflictError(f"the sensors are in use by capture job {min(self._captures)}")
            readers = [j for j in self.jobs.unfinished()
                       if j.kind in WORKER_KINDS and j.params.get("dataset") == dataset_id]
            if readers:
                raise ConflictError(f"dataset {dataset_id} has a {readers[0].kind.value} job ({readers[0].id}, "
                                    f"{readers[0].status.value}): capture into it when that has finished, or cancel it")
            job = self.jobs.create(JobKind.CAPTURE, {"dataset": dataset_id, **params}, "opening the sensors",
                                   running=True)
            stop = threading.Event()
            thread = threading.Thread(target=self._run, args=(job, stop, work), name=f"rigd-capture-{job.id}",
                                      daemon=True)
            self._captures[job.id] = (dataset_id, stop, thread)
        thread.start()
        return job

    def stop(self, job_id: int) -> None:
        """Ask capture ``job_id`` to stop between pairs, if it runs."""
        with self.state.lock:
            if job_id in self._captures:
                self._captures[job_id][1].set()

    def stop_all(self) -> list[threading.Thread]:
        """Ask every capture to stop; their threads, to wait for."""
        with self.state.lock:
            for _, stop, _ in self._captures.values():
                stop.set()
            return [t for _, _, t in self._captures.values()]

    def _run(self, job: Job, stop: threading.Event, work: CaptureWork) -> None:
        try:
            result = work(job, stop)
            if self.state.take_cancel(job.id):
                self.jobs.finish(job.id, JobStatus.CANCELLED, "cancelled", result=result)
            elif self.state.stopping:
                self.jobs.finish(job.id, JobStatus.FAILED, "interrupted", result=result,
                                 error="interrupted: the service stopped")
            else:
                self.jobs.finish(job.id, JobStatus.SUCCEEDED, "done", result=result)
        except (RigdError, DriverError) as exc:  # sensors, rig file, disk: the job fails with the reason
            self.jobs.log(job.id, f"failed: {exc}")
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=str(exc))
        except OSError as exc:  # a write no layer named: the path and the OS's reason, as for the dataset's
            error = write_failure(Path(exc.filename or self.datasets_root), os_reason(exc))
            self.jobs.log(job.id, f"failed: {error}")
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=error)
        except Exception as exc:  # a bug: fail the job with its traceback in the log, keep the service up
            self.jobs.log(job.id, traceback.format_exc())
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=f"internal error: {exc!r}")
        finally:
            with self.state.lock:
                del self._captures[job.id]
