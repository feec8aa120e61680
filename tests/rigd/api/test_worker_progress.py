"""The worker's progress (rigd/api/worker.py), as the job's bar and stage show it: forward only, across the
calibration's stages, and the search worded with why the job searches."""

from __future__ import annotations

import io
import json

from api_helpers import simulated_dataset

from rigd.api.worker import BANDS_SEARCHING, CHECK_BANDS, Reporter, run_job
from rigd.calibration import CalibrationRequest, Start
from rigd.calibration.progress import Stage


def reports(out: io.StringIO) -> list[tuple[str, float]]:
    lines = [json.loads(line) for line in out.getvalue().splitlines()]
    return [(m["stage"], m["fraction"]) for m in lines if m["type"] == "progress"]


def test_a_searched_calibration_moves_forward_and_says_the_search_was_chosen(tmp_path):
    """A real calibration from a chosen global search: its fractions never go back (they went from 70 % in the
    search to 50 % at the first level) and its stage says the search was asked for."""
    dataset = simulated_dataset(tmp_path, "ds", pairs=2)
    request = CalibrationRequest(dataset=dataset, start=Start.SEARCH, out_dir=tmp_path / "out", workers=1)
    out = io.StringIO()
    run_job({"kind": "calibrate", "request": request.model_dump(mode="json")}, out)
    shown = reports(out)
    fractions = [f for _, f in shown]
    assert fractions == sorted(fractions) and 0.0 <= fractions[0] and fractions[-1] <= 1.0, shown
    stages = [s for s, _ in shown]
    assert any(s.startswith("global search over the mounts (asked for (after a reassembly)), 1/") for s in stages)
    assert any(s.startswith("optimising level") for s in stages) and stages[-1] == "writing overlays", stages
    searched = [f for s, f in shown if "global search" in s]
    optimised = [f for s, f in shown if s.startswith("optimising")]
    assert max(searched) <= min(optimised), shown  # the search's band ends where the optimisation's begins
    # the assessment's restarts, counted after the solve (it once sat silent at the last level's iteration)
    assessed = [(s, f) for s, f in shown if s.startswith("assessing the result: restarts")]
    assert assessed[0][0] == "assessing the result: restarts, 0/4" and assessed[-1][0].endswith("4/4"), shown
    assert max(optimised) <= min(f for _, f in assessed), shown


def test_a_check_and_the_rig_files_missing_guess():
    """A check's edges, then its search around the pose: forward only; a rig file without a guess is named."""
    out = io.StringIO()
    check = Reporter(out, CHECK_BANDS)
    for stage, done, total in ((Stage.EDGES, 0, 8), (Stage.EDGES, 7, 8), (Stage.AROUND, 0, 1)):
        check.progress(stage, done, total)
    fractions = [f for _, f in reports(out)]
    assert fractions == [0.0, 0.525, 0.6]
    out = io.StringIO()
    rig = Reporter(out, BANDS_SEARCHING, "the rig file has no initial guess")
    rig.progress(Stage.SEARCH, 3, 8)
    assert reports(out) == [("global search over the mounts (the rig file has no initial guess), 3/8",
                             0.3 + 0.2 * 3 / 8)]
