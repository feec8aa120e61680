"""The worker processes of running calibrations and checks: each started in a session of its own, its output
followed into the job's progress and log, and its whole process group ended and reaped (docs/service.md)."""

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
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rigd.store import JobStore

PROGRESS_INTERVAL_S = 0.5  # progress is written at most this often (plus every change of stage)
WORKER_POLL_S = 0.1  # how often the runner looks for a cancel, a shutdown or a worker that exited
WORKER_STOP_GRACE_S = 2.0  # SIGTERM to SIGKILL of a worker's process group
WORKER_OUTPUT_GRACE_S = 1.0  # a worker that exited: how long its pipe may stay open before it is not read on
LOG = logging.getLogger(__name__)


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


def signal_group(pgid: int, signum: signal.Signals) -> None:
    with contextlib.suppress(ProcessLookupError):  # every member has exited already
        os.killpg(pgid, signum)


_LOG_STAMP = re.compile(r"^\d{4}-\d\d-\d\dT")  # the runner's own lines of a job log (JobStore.log)


def death(code: int, log_path: Path) -> str:
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


Outcome = tuple[dict[str, Any] | None, str | None]  # the worker's result message, or its error message


class WorkerProcesses:
    """The worker processes of running jobs by job id, under the runner's ``lock``: their ids name their process
    groups until they are reaped, so a cancel or a shutdown signals no stranger's."""

    def __init__(self, jobs: JobStore, lock: threading.RLock) -> None:
        self.jobs = jobs
        self._lock = lock
        self._procs: dict[int, subprocess.Popen[str]] = {}

    def run(self, job_id: int, payload: dict[str, Any], log_path: Path, ending: Callable[[], bool]) -> tuple[
            Outcome, int]:
        """Run the worker on ``payload`` until it ends or ``ending()`` (a cancel, a shutdown): its outcome and
        exit code; its stderr goes to the job log ``log_path``."""
        proc = self._start(job_id, log_path, ending)
        assert proc.stdin is not None and proc.stdout is not None
        try:
            self.jobs.log(job_id, f"worker process {proc.pid} started")
            with contextlib.suppress(BrokenPipeError):  # terminated before it read the job: its exit code tells
                proc.stdin.write(json.dumps(payload) + "\n")
                proc.stdin.flush()
            outcome = self._follow(job_id, proc, ending)
        except BaseException:  # e.g. StoreError: nothing it computes could be stored, it must not run on
            self._end(job_id, proc, stop=True)
            raise
        return outcome, self._end(job_id, proc, stop=ending())

    def signal(self, job_id: int) -> None:
        """SIGTERM to the group of job ``job_id``'s worker, if it runs (its runner then escalates to SIGKILL)."""
        with self._lock:
            if job_id in self._procs:
                signal_group(self._procs[job_id].pid, signal.SIGTERM)

    def signal_all(self) -> None:
        with self._lock:
            for proc in self._procs.values():
                signal_group(proc.pid, signal.SIGTERM)

    def _start(self, job_id: int, log_path: Path, ending: Callable[[], bool]) -> subprocess.Popen[str]:
        with log_path.open("a") as stderr, self._lock:
            # A session of its own: the worker leads a process group that its pool processes join, so a cancel
            # or a shutdown ends them all with one signal (rigd.lifetime).
            proc = subprocess.Popen([sys.executable, "-m", "rigd.api.worker"], stdin=subprocess.PIPE,
                                    stdout=subprocess.PIPE, stderr=stderr, text=True, start_new_session=True)
            self._procs[job_id] = proc
            if ending():
                signal_group(proc.pid, signal.SIGTERM)
        return proc

    def _follow(self, job_id: int, proc: subprocess.Popen[str], ending: Callable[[], bool]) -> Outcome:
        """The worker's result or error message, following its progress until it ends, is cancelled or the
        service stops. Its lines are read by a thread: the runner itself waits on the process, never on the
        pipe, which a child that escaped the worker's group could hold open."""
        assert proc.stdout is not None
        lines: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=_pump, args=(proc.stdout, lines), name=f"rigd-worker-out-{job_id}", daemon=True).start()
        throttle = _Throttle()
        result, error = None, None
        exited_at: float | None = None
        while not ending():
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

    def _end(self, job_id: int, proc: subprocess.Popen[str], stop: bool) -> int:
        """Wait for the worker's process group to end (``stop``: end it), reap the worker and return its exit
        code. SIGTERM first, so multiprocessing's resource tracker can remove the pool's semaphores, then
        SIGKILL for whatever is left after ``WORKER_STOP_GRACE_S``. The worker is reaped last, under the lock:
        until then its id names its group, so :meth:`signal` cannot signal a stranger's."""
        def ended() -> bool:
            return _exited(proc.pid) and not _group_alive(proc.pid)

        if not stop:  # it closed its output: give it the time to exit by itself
            _wait_until(ended, WORKER_OUTPUT_GRACE_S)
        if not ended():
            signal_group(proc.pid, signal.SIGTERM)
            if not _wait_until(ended, WORKER_STOP_GRACE_S):
                signal_group(proc.pid, signal.SIGKILL)
                LOG.warning("rigd: job %d: worker process group %d outlived SIGTERM, killed", job_id, proc.pid)
        os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOWAIT)  # not under the lock: cancels must not wait
        with self._lock:
            code = proc.wait()
            del self._procs[job_id]
        assert proc.stdin is not None
        with contextlib.suppress(BrokenPipeError):  # the worker is gone: closing flushes into nowhere
            proc.stdin.close()
        return code
