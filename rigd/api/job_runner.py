"""Runs jobs: calibrations and checks one at a time in a worker process, captures in a thread; records everything.

The runner owns the decisions that must not race: starting a queued job, cancelling it, and refusing a
second capture while the sensors are in use. Errors are store errors (never HTTP ones).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calib.geometry import Transform
from drivers.errors import DriverError
from rigd.api.errors import QueueFullError
from rigd.calibration.request import CalibrationRequest
from rigd.dataset.records import transform_to_yaml
from rigd.errors import DatasetLockedError, RigdError
from rigd.locks import reading
from rigd.report import CalibrationReport, StoredQuality, stored_quality, verdict_of
from rigd.results import AutoActivation, CalibrateJobResult, CaptureJobResult, CheckReport
from rigd.space import os_reason, write_failure
from rigd.store import (
    Change,
    ConflictError,
    ExtrinsicsVersion,
    Job,
    JobKind,
    JobStatus,
    JobStore,
    NewVersion,
    StorageError,
    StoreError,
    VersionStore,
)
from rigd.store.datasets import DatasetCatalog

# What a refused client is told to wait: a small dataset calibrates in tens of seconds, a large one in minutes.
QUEUE_RETRY_AFTER_S = 30
PROGRESS_INTERVAL_S = 0.5  # progress is written at most this often (plus every change of stage)
WORKER_POLL_S = 0.1  # how often the runner looks for a cancel, a shutdown or a worker that exited
WORKER_STOP_GRACE_S = 2.0  # SIGTERM to SIGKILL of a worker's process group
WORKER_OUTPUT_GRACE_S = 1.0  # a worker that exited: how long its pipe may stay open before it is not read on
LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class ActivationBounds:
    """The quality a calibration needs to be activated by ``auto_activate``."""

    require_converged: bool = True
    min_pairs: int = 6
    max_rotation_deg: float = 5.0
    max_translation_cm: float = 10.0

    def failures(self, quality: StoredQuality, pairs: int, change: Change | None) -> list[str]:
        reasons = []
        verdict = verdict_of(quality)
        status = verdict["status"] if verdict else "missing"
        if status != "trusted":  # never activate what the calibration itself does not trust (docs/trust.md)
            reasons.append(f"the calibration's verdict is {status}, not trusted")
        if self.require_converged and not quality["converged"]:
            reasons.append("the optimisation did not converge")
        if pairs < self.min_pairs:
            reasons.append(f"{pairs} pairs, at least {self.min_pairs} needed")
        if change is not None and change.rotation_deg > self.max_rotation_deg:
            reasons.append(f"rotation moved {change.rotation_deg:.2f} deg from version {change.against}, "
                           f"more than {self.max_rotation_deg} deg")
        if change is not None and change.translation_cm > self.max_translation_cm:
            reasons.append(f"translation moved {change.translation_cm:.2f} cm from version {change.against}, "
                           f"more than {self.max_translation_cm} cm")
        return reasons


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


WORKER_KINDS = (JobKind.CALIBRATE, JobKind.CHECK)  # the jobs of the queue and the worker process


class _Throttle:
    def __init__(self) -> None:
        self.stage = ""
        self.last = 0.0

    def due(self, stage: str) -> bool:
        now = time.monotonic()
        if stage != self.stage or now - self.last >= PROGRESS_INTERVAL_S:
            self.stage, self.last = stage, now
            return True
        return False


def _pump(stdout: Any, lines: queue.Queue[str | None]) -> None:
    """Every line of the worker's ``stdout`` into ``lines``, then None at end of file."""
    try:
        for line in stdout:
            lines.put(line)
    finally:
        lines.put(None)
        stdout.close()


def _exited(pid: int) -> bool:
    """Whether child ``pid`` has exited, leaving it unreaped (a zombie) so its id stays its own."""
    try:
        return os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
    except ChildProcessError:  # reaped already
        return True


def _group_alive(pgid: int) -> bool:
    """Whether a process of group ``pgid`` other than a zombie is running (Linux: from /proc)."""
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()  # the name in parentheses may hold spaces
        except (FileNotFoundError, ProcessLookupError, IndexError):  # it exited meanwhile
            continue
        if fields[0] != "Z" and int(fields[2]) == pgid:
            return True
    return False


def _wait_until(done: Callable[[], bool], timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not (finished := done()) and time.monotonic() < deadline:
        time.sleep(0.02)
    return finished


def _signal_group(pgid: int, signum: signal.Signals) -> None:
    with contextlib.suppress(ProcessLookupError):  # every member has exited already
        os.killpg(pgid, signum)


_LOG_STAMP = re.compile(r"^\d{4}-\d\d-\d\dT")  # the runner's own lines of a job log (JobStore.log)


def _death(code: int, log_path: Path) -> str:
    """How a worker that reported no error ended, for the job's error: the signal that killed it, or its exit
    code with the last line it wrote to the job log (a traceback's last line names the exception)."""
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:  # a real-time signal has no name
            name = f"signal {-code}"
        hint = " (the out-of-memory killer?)" if code == -signal.SIGKILL else ""
        return f"was killed by {name}{hint}"
    try:
        with log_path.open("rb") as fh:
            fh.seek(max(0, log_path.stat().st_size - 16384))
            tail = fh.read().decode("utf-8", "replace").splitlines()
    except OSError:
        tail = []
    last = next((line.strip() for line in reversed(tail) if line.strip() and not _LOG_STAMP.match(line)), None)
    return f"exited with code {code}" + (f": {last}" if last else " (see the job log)")


class JobRunner:
    def __init__(self, jobs: JobStore, versions: VersionStore, datasets: DatasetCatalog, bounds: ActivationBounds,
                 code_version: str, max_queued: int = 4, workers: int = 2) -> None:
        self.jobs = jobs
        self.workers = workers
        self.max_queued = max_queued
        self.versions = versions
        self.datasets = datasets
        self.bounds = bounds
        self.code_version = code_version
        self._lock = threading.RLock()
        self._queue: queue.Queue[int | None] = queue.Queue()
        self._procs: dict[int, subprocess.Popen[str]] = {}
        self._cancelled: set[int] = set()
        self._captures: dict[int, tuple[str, threading.Event, threading.Thread]] = {}
        self._stopping = False
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
        with self._lock:  # two identical requests at once must not both find no job and both queue one
            if dataset_id in self.capturing():  # a capture may have started since the request was checked
                raise ConflictError(f"dataset {dataset_id} is being captured; {kind.value} it when the capture ends")
            same = [j for j in self.jobs.unfinished_with(kind, params) if j.id not in self._cancelled]
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
        with self._lock:
            job = self.jobs.get(job_id)
            if job.status is not JobStatus.QUEUED or self._stopping:
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
        with log_path.open("a") as stderr, self._lock:
            # A session of its own: the worker leads a process group that its pool processes join, so a cancel
            # or a shutdown ends them all with one signal (rigd.lifetime).
            proc = subprocess.Popen([sys.executable, "-m", "rigd.api.worker"], stdin=subprocess.PIPE,
                                    stdout=subprocess.PIPE, stderr=stderr, text=True, start_new_session=True)
            self._procs[job.id] = proc
            if job.id in self._cancelled or self._stopping:
                _signal_group(proc.pid, signal.SIGTERM)
        assert proc.stdin is not None and proc.stdout is not None
        try:
            self.jobs.log(job.id, f"worker process {proc.pid} started")
            with contextlib.suppress(BrokenPipeError):  # terminated before it read the job: its exit code tells
                proc.stdin.write(json.dumps(payload) + "\n")
                proc.stdin.flush()
            result, error = self._follow_worker(job.id, proc)
        except BaseException:  # e.g. StoreError: nothing it computes could be stored, it must not run on
            self._end_worker(job.id, proc, stop=True)
            raise
        code = self._end_worker(job.id, proc, stop=self._ending(job.id))
        with self._lock:
            cancelled = job.id in self._cancelled
            self._cancelled.discard(job.id)
        if cancelled:
            self.jobs.finish(job.id, JobStatus.CANCELLED, "cancelled")
        elif self._stopping:
            self.jobs.finish(job.id, JobStatus.FAILED, "interrupted", error="interrupted: the service stopped")
        elif result is not None and job.kind is JobKind.CHECK:
            report: CheckReport = result["report"]  # the worker's run_check report, through JSON
            self.jobs.log(job.id, f"check: {report['status']}")
            self.jobs.finish(job.id, JobStatus.SUCCEEDED, "done", result=report)
        elif result is not None:
            self._store_result(job, result)
        else:
            self.jobs.finish(job.id, JobStatus.FAILED, "failed",
                             error=error or f"the {job.kind.value} worker {_death(code, log_path)}")

    def _ending(self, job_id: int) -> bool:
        with self._lock:
            return job_id in self._cancelled or self._stopping

    def _follow_worker(self, job_id: int, proc: subprocess.Popen[str]) -> tuple[dict[str, Any] | None, str | None]:
        """The worker's result or error message, following its progress until it ends, is cancelled or the
        service stops. Its lines are read by a thread: the runner itself waits on the process, never on the
        pipe, which a child that escaped the worker's group could hold open."""
        assert proc.stdout is not None
        lines: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=_pump, args=(proc.stdout, lines), name=f"rigd-worker-out-{job_id}", daemon=True).start()
        throttle = _Throttle()
        result, error = None, None
        exited_at: float | None = None
        while not self._ending(job_id):
            try:
                line = lines.get(timeout=WORKER_POLL_S)
            except queue.Empty:
                if exited_at is None and _exited(proc.pid):
                    exited_at = time.monotonic()
                if exited_at is not None and time.monotonic() - exited_at > WORKER_OUTPUT_GRACE_S:
                    break  # it exited, yet its pipe stays open: the rest of its output is not coming
                continue
            if line is None:  # end of file: the worker (the only writer) has gone
                break
            try:
                message = json.loads(line)
            except json.JSONDecodeError:
                self.jobs.log(job_id, f"worker: {line}")
                continue
            kind = message.get("type")
            if kind == "progress" and throttle.due(message["stage"]):
                self.jobs.progress(job_id, message["stage"], float(message["fraction"]))
            elif kind == "log":
                self.jobs.log(job_id, message["line"])
            elif kind == "result":
                result = message
            elif kind == "error":
                error = message["message"]
                self.jobs.log(job_id, f"error: {error}")
        return result, error

    def _end_worker(self, job_id: int, proc: subprocess.Popen[str], stop: bool) -> int:
        """Wait for the worker's process group to end (``stop``: end it), reap the worker and return its exit
        code. SIGTERM first, so multiprocessing's resource tracker can remove the pool's semaphores, then
        SIGKILL for whatever is left after ``WORKER_STOP_GRACE_S``. The worker is reaped last, under the lock:
        until then its id names its group, so :meth:`cancel` cannot signal a stranger's."""
        def ended() -> bool:
            return _exited(proc.pid) and not _group_alive(proc.pid)

        if not stop:  # it closed its output: give it the time to exit by itself
            _wait_until(ended, WORKER_OUTPUT_GRACE_S)
        if not ended():
            _signal_group(proc.pid, signal.SIGTERM)
            if not _wait_until(ended, WORKER_STOP_GRACE_S):
                _signal_group(proc.pid, signal.SIGKILL)
                LOG.warning("rigd: job %d: worker process group %d outlived SIGTERM, killed", job_id, proc.pid)
        os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOWAIT)  # not under the lock: cancels must not wait
        with self._lock:
            code = proc.wait()
            del self._procs[job_id]
        assert proc.stdin is not None
        with contextlib.suppress(BrokenPipeError):  # the worker is gone: closing flushes into nowhere
            proc.stdin.close()
        return code

    def _store_result(self, job: Job, result: dict[str, Any]) -> None:
        params, pairs = job.params, result["pair_numbers"]
        report: CalibrationReport = result["report"]  # the worker's run_calibration report, through JSON
        quality = stored_quality(report, len(pairs))
        decision: AutoActivation = {"requested": params["auto_activate"]}

        def policy(change: Change | None) -> bool:
            decision["failed_checks"] = self.bounds.failures(quality, len(pairs), change)
            return bool(params["auto_activate"] and not decision["failed_checks"])

        new = NewVersion(
            T_camera_lidar=Transform.from_matrix(np.asarray(result["matrix"])),
            quality=quality,
            method=report["method"]["name"],
            parameters={**params, "pair_numbers": pairs, "change_from_initial": report["change_from_initial"]},
            code_version=self.code_version,
            dataset_id=params["dataset"],
            dataset_hash=result["dataset_hash"],
            job_id=job.id,
        )

        def same_rig(active: ExtrinsicsVersion) -> bool:  # a version of another rig is not compared with this one
            theirs, ours = active.parameters.get("rig"), params.get("rig")
            return theirs is None or ours is None or theirs == ours

        def result_of(version: ExtrinsicsVersion) -> CalibrateJobResult:
            change = version.change
            return {"version": version.number, "status": version.status.value,
                    "change": {"against": change.against, "rotation_deg": change.rotation_deg,
                               "translation_cm": change.translation_cm} if change else None,
                    "auto_activate": decision}

        try:  # the version and the job's end in one transaction: a crash leaves both or neither
            version = self.versions.add(new, policy, job_result=result_of, comparable=same_rig)
        except StorageError as exc:
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=f"its result could not be stored: {exc} "
                             f"(its files are in {self.jobs.job_dir(job.id) / 'calibration'})")
            return
        self.jobs.log(job.id, f"stored extrinsics version {version.number} ({version.status.value})")

    # -- captures -----------------------------------------------------------------------------------------------
    def capturing(self) -> set[str]:
        """Ids of the datasets being captured now."""
        with self._lock:
            return {dataset for dataset, _, _ in self._captures.values()}

    def submit_capture(self, dataset_id: str, params: dict[str, Any],
                       work: Callable[[Job, threading.Event], CaptureJobResult]) -> Job:
        """Start ``work(job, stop)`` in a thread; ConflictError while another capture holds the sensors."""
        with self._lock:
            if self._stopping:
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
            thread = threading.Thread(target=self._run_capture, args=(job, stop, work), name=f"rigd-capture-{job.id}",
                                      daemon=True)
            self._captures[job.id] = (dataset_id, stop, thread)
        thread.start()
        return job

    def _run_capture(self, job: Job, stop: threading.Event, work: Callable[[Job, threading.Event], CaptureJobResult]
                     ) -> None:
        try:
            result = work(job, stop)
            with self._lock:
                cancelled = job.id in self._cancelled
                self._cancelled.discard(job.id)
            if cancelled:
                self.jobs.finish(job.id, JobStatus.CANCELLED, "cancelled", result=result)
            elif self._stopping:
                self.jobs.finish(job.id, JobStatus.FAILED, "interrupted", result=result,
                                 error="interrupted: the service stopped")
            else:
                self.jobs.finish(job.id, JobStatus.SUCCEEDED, "done", result=result)
        except (RigdError, DriverError) as exc:  # sensors, rig file, disk: the job fails with the reason
            self.jobs.log(job.id, f"failed: {exc}")
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=str(exc))
        except OSError as exc:  # a write no layer named: the path and the OS's reason, as for the dataset's
            error = write_failure(Path(exc.filename or self.datasets.root), os_reason(exc))
            self.jobs.log(job.id, f"failed: {error}")
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=error)
        except Exception as exc:  # a bug: fail the job with its traceback in the log, keep the service up
            self.jobs.log(job.id, traceback.format_exc())
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=f"internal error: {exc!r}")
        finally:
            with self._lock:
                del self._captures[job.id]

    # -- cancel, stop -------------------------------------------------------------------------------------------
    def cancel(self, job_id: int) -> Job:
        with self._lock:
            job = self.jobs.get(job_id)
            if job.status.finished:
                raise ConflictError(f"job {job_id} has already {job.status.value}")
            if job.status is JobStatus.QUEUED:
                self.jobs.log(job_id, "cancelled while queued")
                return self.jobs.finish(job_id, JobStatus.CANCELLED, "cancelled")
            self._cancelled.add(job_id)
            self.jobs.progress(job_id, "cancelling", job.fraction)
            self.jobs.log(job_id, "cancel requested")
            if job_id in self._procs:  # the runner's thread then waits for the group, escalating to SIGKILL
                _signal_group(self._procs[job_id].pid, signal.SIGTERM)
            if job_id in self._captures:
                self._captures[job_id][1].set()
            return self.jobs.get(job_id)

    def shutdown(self, timeout_s: float = 20.0) -> None:
        """Stop the worker and captures; what was running is recorded as failed (interrupted)."""
        with self._lock:
            self._stopping = True
            for proc in self._procs.values():
                _signal_group(proc.pid, signal.SIGTERM)
            for _, stop, _ in self._captures.values():
                stop.set()
            threads = [t for _, _, t in self._captures.values()]
        self._queue.put(None)
        for thread in (self._thread, *threads):
            if thread.is_alive():
                thread.join(timeout_s)
        try:
            self.jobs.fail_unfinished("interrupted: the service stopped")
        except StoreError as exc:  # the data directory was deleted: nothing can be recorded, the service still stops
            LOG.error("rigd: the unfinished jobs cannot be marked interrupted: %s", exc)
