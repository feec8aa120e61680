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
import re
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


# The calibration's stages in order, by the words its progress reports begin with, and the share of the job's bar
# each takes (with a global search, and without). run_calibration reports each stage on its own scale (the
# edges 0..1 of the pairs, the search 0.5..0.7, the optimisation 0.5 at its start): placed in its band, and never
# below what was shown, the bar only moves forward (it went from 70 % in the search back to 50 % at "optimising
# level 1/4").
STAGES = (("hashing", "hashing"), ("edges of", "edges"), ("reflectivity", "reflectivity"),
          ("optimising", "optimising"), ("writing overlays", "overlays"), ("searching around", "around"))
BANDS = {"hashing": (0.0, 0.02), "edges": (0.02, 0.5), "reflectivity": (0.5, 0.5), "search": (0.5, 0.5),
         "optimising": (0.5, 0.95), "overlays": (0.95, 1.0)}
BANDS_SEARCHING = {**BANDS, "edges": (0.02, 0.25), "reflectivity": (0.25, 0.3), "search": (0.3, 0.5)}
CHECK_BANDS = {"edges": (0.0, 0.6), "around": (0.6, 1.0)}  # a check: the edges, then the search around the pose
PER_PAIR = ("hashing", "edges", "reflectivity")  # stages whose own fraction is 0..1 of the stage
PAIR_OF = re.compile(r"pair (\d+)/(\d+)")
# The search's reports say "no initial guess" (rigd calibrate without --init); a service job says why it searches.
NO_GUESS = "no initial guess: "
SEARCH_WORDS = {"search": "", "rig": "no initial guess in the rig file: "}


def stage_kind(stage: str) -> str | None:
    """Which of the calibration's stages a progress report belongs to; None: not one of them (a check's)."""
    if "global search" in stage:
        return "search"
    return next((kind for words, kind in STAGES if stage.startswith(words)), None)


class Reporter:
    """Writes protocol lines to the parent; levels' iterations go to the log, throttled by the parent.
    ``bands``: the job's stages' shares of its bar (BANDS, BANDS_SEARCHING when the calibration starts with the
    global search, CHECK_BANDS); ``init``: the request's start (active, rig, search, explicit), which words the
    search's stage."""

    def __init__(self, out: TextIO, bands: dict[str, tuple[float, float]] | None = None,
                 init: str | None = None) -> None:
        self.out = out
        self.levels = 1
        self.bands = BANDS if bands is None else bands
        self.init = init
        self.shown = 0.0

    def send(self, message: dict[str, Any]) -> None:
        try:
            self.out.write(json.dumps(message) + "\n")
            self.out.flush()
        except BrokenPipeError:  # the parent is gone
            leave(EXIT_PARENT_GONE)

    def _forward(self, kind: str | None, within: float, given: float) -> float:
        """The job's fraction for ``within`` (0..1) of stage ``kind`` (``given`` as it is for another job's
        stages), never below the last one sent."""
        if kind in self.bands:
            low, high = self.bands[kind]
            given = low + (high - low) * min(max(within, 0.0), 1.0)
        self.shown = max(self.shown, given)
        return self.shown

    def _words(self, stage: str) -> str:
        if stage.startswith(NO_GUESS) and self.init in SEARCH_WORDS:
            return SEARCH_WORDS[self.init] + stage.removeprefix(NO_GUESS)
        return stage

    def progress(self, stage: str, fraction: float) -> None:
        kind = stage_kind(stage)
        pair = PAIR_OF.search(stage)
        # The per-pair stages report how far they are; the others report their start on the caller's scale
        # (the search's "pair d/t" says how far it is).
        within = fraction if kind in PER_PAIR else int(pair[1]) / max(int(pair[2]), 1) if pair else 0.0
        stage = self._words(stage)
        self.send({"type": "progress", "stage": stage, "fraction": self._forward(kind, within, fraction)})
        self.send({"type": "log", "line": stage})

    def iteration(self, level: int, iteration: int, cost: float) -> None:
        # Within a level, iterations count towards max 100.
        within = (level + min(iteration / 100.0, 1.0)) / self.levels
        self.send({"type": "progress", "stage": f"optimising level {level + 1}/{self.levels}",
                   "fraction": self._forward("optimising", within, within)})
        self.send({"type": "log", "line": f"level {level + 1} iteration {iteration} cost {cost:.6f}"})


def job_bands(job: dict[str, Any]) -> dict[str, tuple[float, float]]:
    """The stages' shares of a job's bar: a check's, a calibration's with or without the global search."""
    if job.get("kind") == "check":
        return CHECK_BANDS
    return BANDS_SEARCHING if job["initial_matrix"] is None else BANDS


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
        fit_elevation=bool(job.get("fit_elevation_offset", False)),
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
    out = _protocol_out()
    job = json.loads(sys.stdin.readline())
    reporter = Reporter(out, job_bands(job), job.get("init"))
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
