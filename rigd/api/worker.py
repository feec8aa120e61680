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
import math
import os
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from calib.drift import DriftOptions
from calib.errors import CalibError
from calib.geometry import Transform
from calib.pipeline import sigmas_for
from drivers.errors import DriverError
from rigd.calibration import CalibrationRequest, run_calibration
from rigd.calibration.check_job import run_check
from rigd.calibration.job import prepare
from rigd.calibration.progress import Stage
from rigd.errors import RigdError
from rigd.lifetime import leave
from rigd.store.datasets import content_hash
from rigd.store.jsonsafe import json_safe

EXIT_PARENT_GONE = 3


# The share of the job's bar each stage takes (a calibration with a global search, one without, a check). A stage
# reports how far it is (done of total); placed in its band, and never below what was shown, the bar only moves
# forward.
BANDS = {Stage.HASHING: (0.0, 0.02), Stage.EDGES: (0.02, 0.5), Stage.REFLECTIVITY: (0.5, 0.5),
         Stage.SEARCH: (0.5, 0.5), Stage.OPTIMISING: (0.5, 0.85), Stage.ASSESSING: (0.85, 0.95),
         Stage.OVERLAYS: (0.95, 1.0)}
BANDS_SEARCHING = {**BANDS, Stage.EDGES: (0.02, 0.25), Stage.REFLECTIVITY: (0.25, 0.3), Stage.SEARCH: (0.3, 0.5)}
CHECK_BANDS = {Stage.EDGES: (0.0, 0.6), Stage.AROUND: (0.6, 1.0)}


_SILENT = (Stage.OPTIMISING, Stage.ASSESSING)  # stages that may say nothing for long: the heartbeat moves them
HEARTBEAT_S = 1.0  # a stage that reports nothing for this long (a photometric solve, the assessment) still moves
CREEP_S = 60.0  # ... its bar towards its band's end: 63 % of the way after this long, never reaching it


class Reporter:
    """Writes protocol lines to the parent; levels' iterations go to the log, throttled by the parent.
    ``bands``: the job's stages' shares of its bar; ``search_why``: why the job searches for its start, said
    with the search's stage. Its heartbeat (:meth:`beat`, from a thread) keeps a silent stage's bar moving with
    its time said: a photometric method reports no iterations, and the assessment none either."""

    def __init__(self, out: TextIO, bands: dict[Stage, tuple[float, float]], search_why: str = "") -> None:
        self.out = out
        self.levels = 1
        self.bands = bands
        self.search_why = search_why
        self.shown = 0.0
        self.lock = threading.Lock()  # the heartbeat's thread writes too
        self.stage: Stage | None = None
        self.words = ""
        self.stage_since = self.sent_at = time.monotonic()

    def send(self, message: dict[str, Any]) -> None:
        with self.lock:
            try:
                self.out.write(json.dumps(message) + "\n")
                self.out.flush()
            except BrokenPipeError:  # the parent is gone
                leave(EXIT_PARENT_GONE)
            self.sent_at = time.monotonic()

    def _forward(self, stage: Stage, within: float) -> float:
        """The job's fraction for ``within`` (0..1) of ``stage``, never below the last one sent."""
        low, high = self.bands.get(stage, (self.shown, self.shown))
        self.shown = max(self.shown, low + (high - low) * min(max(within, 0.0), 1.0))
        return self.shown

    def _enter(self, stage: Stage, words: str) -> None:
        if stage is not self.stage:
            self.stage, self.stage_since = stage, time.monotonic()
        self.words = words

    def progress(self, stage: Stage, done: int, total: int) -> None:
        words = stage.words + (f" ({self.search_why})" if stage is Stage.SEARCH and self.search_why else "")
        if total > 1:
            words += f", {done}/{total}"
        self._enter(stage, words)
        self.send({"type": "progress", "stage": words, "fraction": self._forward(stage, done / max(total, 1))})
        self.send({"type": "log", "line": words})

    def iteration(self, level: int, iteration: int, cost: float) -> None:
        # Within a level, iterations count towards max 100.
        within = (level + min(iteration / 100.0, 1.0)) / self.levels
        self._enter(Stage.OPTIMISING, f"optimising level {level + 1}/{self.levels}")
        self.send({"type": "progress", "stage": self.words, "fraction": self._forward(Stage.OPTIMISING, within)})
        self.send({"type": "log", "line": f"level {level + 1} iteration {iteration} cost {cost:.6f}"})

    def beat(self) -> None:
        """When the optimisation has said nothing for HEARTBEAT_S: its words with the time it has run, and the bar
        a little further (1 - exp(-t / CREEP_S) of its band)."""
        now = time.monotonic()
        if self.stage not in _SILENT or now - self.sent_at < HEARTBEAT_S:
            return
        elapsed = now - self.stage_since
        fraction = self._forward(self.stage, 1.0 - math.exp(-elapsed / CREEP_S))
        self.send({"type": "progress", "stage": f"{self.words}, {elapsed:.0f} s", "fraction": fraction})

    def ended(self) -> None:
        """No more heartbeats: the job's result or error follows."""
        self.stage = None


def _heartbeat(reporter: Reporter) -> None:
    while True:
        time.sleep(HEARTBEAT_S / 2)
        reporter.beat()


def _watch_parent(stdin: TextIO) -> None:
    """End the worker's process group when the parent closes our stdin (it died, or it cancels us)."""
    stdin.read()
    leave(EXIT_PARENT_GONE)


def run_job(job: dict[str, Any], out: TextIO) -> dict[str, Any]:
    """A ``"kind": "calibrate"`` job: its request, run as `rigd calibrate` runs it; the result is its report with the
    dataset's content hash and pair numbers (the version records them)."""
    request = CalibrationRequest.model_validate(job["request"])
    dataset, resolved = prepare(request)
    searching = resolved.solve.initial is None
    reporter = Reporter(out, BANDS_SEARCHING if searching else BANDS, resolved.start_why.why if searching else "")
    threading.Thread(target=_heartbeat, args=(reporter,), name="rigd-worker-heartbeat", daemon=True).start()
    gmm = resolved.solve.gmm
    photo = resolved.solve.photo
    reporter.levels = (len(sigmas_for(gmm, list(dataset.rig.camera.models()))) if gmm is not None else 0) + \
        (len(photo.blur_deg) if photo is not None else 0)
    reporter.progress(Stage.HASHING, 0, 1)
    digest = content_hash(dataset)
    try:
        outcome = run_calibration(request, reporter.progress, reporter.iteration, (dataset, resolved))
    finally:
        reporter.ended()
    return {
        "type": "result",
        "matrix": outcome.T_camera_lidar.matrix.tolist(),
        "report": json_safe(outcome.report),
        "dataset_hash": digest,
        "pair_numbers": [int(p.name) for p in dataset.pair_dirs],
    }


def run_check_job(job: dict[str, Any], out: TextIO) -> dict[str, Any]:
    """A ``"kind": "check"`` job: run_check of the job's extrinsics on the dataset; the result is its report."""
    threshold = job.get("threshold") or {}
    given: dict[str, Any] = {name: float(threshold[key]) for name, key in
                             (("threshold_rot_deg", "rotation_deg"), ("threshold_trans_cm", "translation_cm"))
                             if key in threshold}
    opts = DriftOptions(**given)
    checked = Transform.from_matrix(np.asarray(job["checked_matrix"], dtype=np.float64))
    outcome = run_check(Path(job["dataset"]), checked, opts, Reporter(out, CHECK_BANDS).progress)
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
    out = _protocol_out()
    job = json.loads(sys.stdin.readline())
    reporter = Reporter(out, {})
    threading.Thread(target=_watch_parent, args=(sys.stdin,), daemon=True).start()
    try:
        reporter.send(JOBS[job["kind"]](job, out))
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
