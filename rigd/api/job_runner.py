"""Runs jobs: calibrations and checks one at a time in a worker process, captures in a thread; records everything.

The runner owns the decisions that must not race: starting a queued job, cancelling it, and refusing a
second capture while the sensors are in use. Errors are store errors (never HTTP ones). Its collaborators:
``worker_process`` (the worker processes), ``calibration_result`` (a result kept as a version),
``capture_jobs`` (the capture threads) and ``runner_state`` (cancels and shutdown, under one lock).
"""

from __future__ import annotations

import logging
import queue
import threading
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from calib.geometry import Transform
from rigd.api.calibration_result import ActivationBounds, CalibrationRecorder
from rigd.api.capture_jobs import CaptureJobs, CaptureWork
from rigd.api.errors import QueueFullError
from rigd.api.runner_state import WORKER_KINDS, RunnerState
from rigd.api.worker_process import WorkerProcesses, death
from rigd.calibration.request import CalibrationRequest
from rigd.dataset.records import transform_to_yaml
from rigd.errors import DatasetLockedError
from rigd.locks import reading
from rigd.results import CheckReport
from rigd.space import os_reason, write_failure
from rigd.store import (
    ConflictError,
    Job,
    JobKind,
    JobStatus,
    JobStore,
    StorageError,
    StoreError,
    VersionStore,
)
from rigd.store.datasets import DatasetCatalog

# What a refused client is told to wait: a small dataset calibrates in tens of seconds, a large one in minutes.
QUEUE_RETRY_AFTER_S = 30
LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class CalibrationPlan:
    """A validated calibration job: the dataset's id, the request as the worker runs it (its dataset the catalog's
    folder; the runner gives it the job's output folder and its workers) and whether to activate the result."""

    dataset_id: str
    request: CalibrationRequest
    auto_activate: bool
    rig: dict[str, Any] | None = None  # the dataset's camera and LiDAR (rigd.api.rigs), kept with its version
    method: dict[str, str] | None = None  # the method the request resolved to and why ({name, why})

    def params(self) -> dict[str, Any]:
        extra = {"rig": self.rig} if self.rig is not None else {}
        if self.method is not None:
            extra["method"] = self.method
        return {"dataset": self.dataset_id, "auto_activate": self.auto_activate,
                "request": self.request.model_dump(mode="json"), **extra}


@dataclass(frozen=True)
class CheckPlan:
    """A validated check request: the dataset, the resolved extrinsics to check and the thresholds."""

    dataset_id: str
    checked: Transform
    against: str  # active | version | explicit
    against_version: int | None
    threshold: dict[str, float]  # rotation_deg, translation_cm

    def params(self) -> dict[str, Any]:
        return {"dataset": self.dataset_id, "against": self.against, "against_version": self.against_version,
                "checked": transform_to_yaml(self.checked), "threshold": self.threshold}



class JobRunner:
    def __init__(self, jobs: JobStore, versions: VersionStore, datasets: DatasetCatalog, bounds: ActivationBounds,
                 code_version: str, max_queued: int = 4, workers: int = 2) -> None:
        self.jobs = jobs
        self.workers = workers
        self.max_queued = max_queued
        self.versions = versions
        self.datasets = datasets
        self.state = RunnerState()
        self.recorder = CalibrationRecorder(jobs, versions, bounds, code_version)
        self.procs = WorkerProcesses(jobs, self.state.lock)
        self.captures = CaptureJobs(jobs, datasets.root, self.state)
        self._queue: queue.Queue[int | None] = queue.Queue()
        self._thread = threading.Thread(target=self._worker_loop, name="rigd-worker-jobs", daemon=True)

    def start(self) -> None:
        self._thread.start()

    # -- calibrations and checks: one at a time in the worker process -------------------------------------------
    def submit_calibration(self, plan: CalibrationPlan) -> tuple[Job, bool]:
        """The job calibrating ``plan`` and whether it is new: the job of an identical calibration that is queued
        or running is returned rather than queuing it twice. QueueFullError when ``max_queued`` jobs wait."""
        start = plan.request.start
        return self._submit(JobKind.CALIBRATE, plan.dataset_id, plan.params(),
                            f"queued: calibrate dataset {plan.dataset_id} from {start.value} start")

    def submit_check(self, plan: CheckPlan) -> tuple[Job, bool]:
        """Like :meth:`submit_calibration`, for a check (same queue, bound and de-duplication)."""
        what = f"version {plan.against_version}" if plan.against_version is not None else plan.against
        return self._submit(JobKind.CHECK, plan.dataset_id, plan.params(),
                            f"queued: check dataset {plan.dataset_id} against the {what} extrinsics")

    def _submit(self, kind: JobKind, dataset_id: str, params: dict[str, Any], message: str) -> tuple[Job, bool]:
        with self.state.lock:  # two identical requests at once must not both find no job and both queue one
            if dataset_id in self.capturing():  # a capture may have started since the request was checked
                raise ConflictError(f"dataset {dataset_id} is being captured; {kind.value} it when the capture ends")
            same = [j for j in self.jobs.unfinished_with(kind, params) if j.id not in self.state.cancelled]
            if same:
                return same[0], False
            waiting = [j for j in self.jobs.unfinished() if j.kind in WORKER_KINDS and j.status is JobStatus.QUEUED]
            if len(waiting) >= self.max_queued:
                kinds = {j.kind for j in waiting}
                noun = ("calibrations" if kinds == {JobKind.CALIBRATE} else "checks" if kinds == {JobKind.CHECK}
                        else "calibrations and checks")
                raise QueueFullError(f"{len(waiting)} {noun} are queued already (jobs {[j.id for j in waiting]}; at "
                                     f"most {self.max_queued}, RIGD_MAX_QUEUED_JOBS): retry when one has finished",
                                     QUEUE_RETRY_AFTER_S)
            job = self.jobs.create(kind, params)
        self.jobs.log(job.id, message)
        self._queue.put(job.id)
        return job, True

    def _worker_loop(self) -> None:
        while (job_id := self._queue.get()) is not None:
            try:
                self._run_job(job_id)
            except StoreError as exc:  # e.g. the data directory was deleted: the job cannot even be recorded
                LOG.error("rigd: job %d stopped, its record cannot be written: %s", job_id, exc)

    def _run_job(self, job_id: int) -> None:
        with self.state.lock:
            job = self.jobs.get(job_id)
            if job.status is not JobStatus.QUEUED or self.state.stopping:
                return
            try:
                job = self._start(job_id)
            except StorageError as exc:  # the disk filled while it waited: it cannot run, nor stay queued
                self.jobs.finish(job_id, JobStatus.FAILED, "failed", error=f"not started: {exc}")
                return
        try:
            with reading(self.datasets.path(job.params["dataset"])):  # no capture into it meanwhile
                self._run_in_worker(job)
        except StorageError as exc:  # its end is kept until the database takes it (rigd.store.jobs)
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=str(exc))
        except StoreError:
            raise
        except DatasetLockedError as exc:  # a capture from a shell writes the dataset
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=f"not started: {exc}")
        except OSError as exc:  # its log or output folder: the file system is full or read-only
            self.jobs.finish(job.id, JobStatus.FAILED, "failed",
                             error=write_failure(Path(exc.filename or self.jobs.job_dir(job.id)), os_reason(exc)))
        except Exception as exc:  # a bug must fail its job, not stop every later calibration or check
            self.jobs.log(job.id, traceback.format_exc())
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=f"internal error: {exc!r}")

    def _start(self, job_id: int) -> Job:
        """queued -> running, unless the data directory is short of space (StorageError)."""
        problem = self.jobs.space_problem()
        if problem is not None:
            raise StorageError(problem)
        return self.jobs.start(job_id, "starting the worker")

    def _payload(self, job: Job) -> dict[str, Any]:
        """The worker's job line: ``kind`` selects what it runs (absent: calibrate)."""
        params = job.params
        dataset = str(self.datasets.path(params["dataset"]))
        if job.kind is JobKind.CHECK:
            return {"kind": "check", "dataset": dataset, "checked_matrix": params["checked"]["matrix"],
                    "threshold": params["threshold"]}
        # the request as stored (the worker validates it), with the job's folder and the service's workers
        out_dir = str(self.jobs.job_dir(job.id) / "calibration")
        return {"kind": "calibrate", "request": {**params["request"], "out_dir": out_dir, "workers": self.workers}}

    def _run_in_worker(self, job: Job) -> None:
        payload = self._payload(job)
        log_path = self.jobs.job_dir(job.id) / "job.log"
        (result, error), code = self.procs.run(job.id, payload, log_path, lambda: self.state.ending(job.id))
        if self.state.take_cancel(job.id):
            self.jobs.finish(job.id, JobStatus.CANCELLED, "cancelled")
        elif self.state.stopping:
            self.jobs.finish(job.id, JobStatus.FAILED, "interrupted", error="interrupted: the service stopped")
        elif result is not None and job.kind is JobKind.CHECK:
            report: CheckReport = result["report"]  # the worker's run_check report, through JSON
            self.jobs.log(job.id, f"check: {report['status']}")
            self.jobs.finish(job.id, JobStatus.SUCCEEDED, "done", result=report)
        elif result is not None:
            self.recorder.store(job, result)
        else:
            self.jobs.finish(job.id, JobStatus.FAILED, "failed",
                             error=error or f"the {job.kind.value} worker {death(code, log_path)}")

    # -- captures -----------------------------------------------------------------------------------------------
    def capturing(self) -> set[str]:
        """Ids of the datasets being captured now."""
        return self.captures.capturing()

    def submit_capture(self, dataset_id: str, params: dict[str, Any], work: CaptureWork) -> Job:
        """Start ``work(job, stop)`` in a thread; ConflictError while another capture holds the sensors."""
        return self.captures.submit(dataset_id, params, work)

    # -- cancel, stop -------------------------------------------------------------------------------------------
    def cancel(self, job_id: int) -> Job:
        with self.state.lock:
            job = self.jobs.get(job_id)
            if job.status.finished:
                raise ConflictError(f"job {job_id} has already {job.status.value}")
            if job.status is JobStatus.QUEUED:
                self.jobs.log(job_id, "cancelled while queued")
                return self.jobs.finish(job_id, JobStatus.CANCELLED, "cancelled")
            self.state.cancelled.add(job_id)
            self.jobs.progress(job_id, "cancelling", job.fraction)
            self.jobs.log(job_id, "cancel requested")
            self.procs.signal(job_id)  # the runner's thread then waits for the group, escalating to SIGKILL
            self.captures.stop(job_id)
            return self.jobs.get(job_id)

    def shutdown(self, timeout_s: float = 20.0) -> None:
        """Stop the worker and captures; what was running is recorded as failed (interrupted)."""
        with self.state.lock:
            self.state.stopping = True
            self.procs.signal_all()
            threads = self.captures.stop_all()
        self._queue.put(None)
        for thread in (self._thread, *threads):
            if thread.is_alive():
                thread.join(timeout_s)
        try:
            self.jobs.fail_unfinished("interrupted: the service stopped")
        except StoreError as exc:  # the data directory was deleted: nothing can be recorded, the service still stops
            LOG.error("rigd: the unfinished jobs cannot be marked interrupted: %s", exc)
