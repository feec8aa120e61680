"""The calibration (and check) worker: a child process of ``rigd serve`` (``python -m rigd.api.worker``).

Protocol: the parent writes one JSON line (the job; its ``kind`` is ``calibrate``, the default, or ``check``)
to stdin and keeps stdin open; the worker writes JSON lines to stdout: ``{"type": "progress", "stage",
"fraction"}``, ``{"type": "log", "line"}``, and finally ``{"type": "result", ...}`` or ``{"type": "error",
"message"}``. Its stderr goes to the job log.

A separate process keeps the service responsive (the GIL is not shared) and makes cancelling a running
calibration or check a plain SIGTERM to the worker's process group (it leads one: the parent starts it in a
session of its own, and the calibration's pool processes join it). When stdin reaches end of file the parent is
gone (killed, crashed): the worker ends its group at once instead of finishing a job nobody will record.

The protocol has the pipe to itself: file descriptor 1 is pointed at stderr (the job log) before anything
runs, so nothing the worker starts holds the pipe open after the worker is gone, and stray prints from
libraries go to the log instead of into the protocol.

A failure the worker did not foresee (a bug, numpy's LinAlgError) still ends with an ``error`` line naming
it, so the job says why it failed; its traceback goes to the job log.
"""

from __future__ import annotations

import json
import os
import sys
import threading
import traceback
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from calib.check import DriftOptions
from calib.errors import CalibError
from calib.geometry import Transform
from calib.pipeline import CalibParams
from drivers.errors import DriverError
from rigd.calibration import CalibrationRequest, run_calibration
from rigd.calibration.check import run_check
from rigd.dataset import open_dataset
from rigd.dataset.records import prior_from_yaml, tolerance_from_yaml
from rigd.errors import RigdError
from rigd.lifetime import leave
from rigd.store.datasets import content_hash
from rigd.store.jsonsafe import json_safe

EXIT_PARENT_GONE = 3


class Reporter:
    """Writes protocol lines to the parent; levels' iterations go to the log, throttled by the parent."""

    def __init__(self, out: TextIO) -> None:
        self.out = out
        self.levels = 1

    def send(self, message: dict[str, Any]) -> None:
        try:
            self.out.write(json.dumps(message) + "\n")
            self.out.flush()
        except BrokenPipeError:  # the parent is gone
            leave(EXIT_PARENT_GONE)

    def progress(self, stage: str, fraction: float) -> None:
        self.send({"type": "progress", "stage": stage, "fraction": fraction})
        self.send({"type": "log", "line": stage})

    def iteration(self, level: int, iteration: int, cost: float) -> None:
        # Optimisation is the 0.5 .. 0.95 part of the job; within a level, iterations count towards max 100.
        fraction = 0.5 + 0.45 * (level + min(iteration / 100.0, 1.0)) / self.levels
        self.send({"type": "progress", "stage": f"optimising level {level + 1}/{self.levels}", "fraction": fraction})
        self.send({"type": "log", "line": f"level {level + 1} iteration {iteration} cost {cost:.6f}"})


def _watch_parent(stdin: TextIO) -> None:
    """End the worker's process group when the parent closes our stdin (it died, or it cancels us)."""
    stdin.read()
    leave(EXIT_PARENT_GONE)


def run_job(job: dict[str, Any], reporter: Reporter) -> dict[str, Any]:
    dataset = open_dataset(Path(job["dataset"]))
    sigmas = job["sigmas_deg"]
    reporter.levels = len(sigmas if sigmas is not None else CalibParams().optim.sigmas_deg)
    reporter.progress("hashing the dataset", 0.0)
    digest = content_hash(dataset)
    # Without sigmas the request keeps run_calibration's own default schedule.
    schedule: dict[str, Any] = {"sigmas_deg": tuple(float(s) for s in sigmas)} if sigmas is not None else {}
    request = CalibrationRequest(
        dataset=dataset.root,
        out_dir=Path(job["out_dir"]),
        initial=Transform.from_matrix(np.asarray(job["initial_matrix"], dtype=np.float64))
        if job["initial_matrix"] is not None else None,
        search=job["initial_matrix"] is None,
        prior=prior_from_yaml(job["prior"], "request prior") if job.get("prior") else None,
        fix_translation=bool(job.get("fix_translation", False)),
        tolerance=tolerance_from_yaml(job["tolerance"], "request tolerance") if job.get("tolerance") else None,
        workers=int(job.get("workers", 2)),
        **schedule,
    )
    outcome = run_calibration(request, reporter.progress, reporter.iteration)
    return {
        "type": "result",
        "matrix": outcome.T_camera_lidar.matrix.tolist(),
        "report": json_safe(outcome.report),
        "dataset_hash": digest,
        "pair_numbers": [int(p.name) for p in dataset.pair_dirs],
    }


def run_check_job(job: dict[str, Any], reporter: Reporter) -> dict[str, Any]:
    """A ``"kind": "check"`` job: run_check of the job's extrinsics on the dataset; the result is its report."""
    threshold = job.get("threshold") or {}
    given: dict[str, Any] = {name: float(threshold[key]) for name, key in
                             (("threshold_rot_deg", "rotation_deg"), ("threshold_trans_cm", "translation_cm"))
                             if key in threshold}
    opts = DriftOptions(**given)
    checked = Transform.from_matrix(np.asarray(job["checked_matrix"], dtype=np.float64))
    outcome = run_check(Path(job["dataset"]), checked, opts, reporter.progress)
    return {"type": "result", "report": json_safe(outcome.report)}


JOBS = {"calibrate": run_job, "check": run_check_job}


def _protocol_out() -> TextIO:
    """The parent's pipe on a descriptor of its own (not inherited by child processes); fd 1 (sys.stdout)
    becomes the job log."""
    sys.stdout.flush()
    out = os.fdopen(os.dup(sys.stdout.fileno()), "w", encoding="utf-8")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    return out


def main() -> int:
    reporter = Reporter(_protocol_out())
    job = json.loads(sys.stdin.readline())
    threading.Thread(target=_watch_parent, args=(sys.stdin,), daemon=True).start()
    try:
        reporter.send(JOBS[job.get("kind", "calibrate")](job, reporter))
    except (RigdError, DriverError, CalibError) as exc:
        reporter.send({"type": "error", "message": str(exc)})
        return 2
    except Exception as exc:  # unforeseen: the job still says what killed it, the log has where
        traceback.print_exc()
        cause = traceback.format_exception_only(exc)[-1].strip()
        reporter.send({"type": "error", "message": f"the worker failed: {cause} (traceback in the job log)"})
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
