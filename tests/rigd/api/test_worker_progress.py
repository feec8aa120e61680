"""The worker's progress (rigd/api/worker.py), as the job's bar and stage show it: forward only, across the
calibration's stages, and the search worded as the request chose it."""

from __future__ import annotations

import io
import json

from api_helpers import simulated_dataset

from rigd.api.worker import CHECK_BANDS, Reporter, job_bands, run_job


def reports(out: io.StringIO) -> list[tuple[str, float]]:
    lines = [json.loads(line) for line in out.getvalue().splitlines()]
    return [(m["stage"], m["fraction"]) for m in lines if m["type"] == "progress"]


def test_a_searched_calibration_moves_forward_and_says_the_search_was_chosen(tmp_path):
    """A real calibration from a chosen global search: its fractions never go back (they went from 70 % in the
    search to 50 % at the first level) and its stage says the search was chosen, not that there was no guess."""
    dataset = simulated_dataset(tmp_path, "ds", pairs=2)
    job = {"dataset": str(dataset), "out_dir": str(tmp_path / "out"), "initial_matrix": None, "sigmas_deg": None,
           "prior": None, "fix_translation": False, "tolerance": None, "workers": 1, "init": "search"}
    out = io.StringIO()
    run_job(job, Reporter(out, job_bands(job), job["init"]))
    shown = reports(out)
    fractions = [f for _, f in shown]
    assert fractions == sorted(fractions) and 0.0 <= fractions[0] and fractions[-1] <= 1.0, shown
    stages = [s for s, _ in shown]
    assert any(s.startswith("global search over the mounts, pair") for s in stages), stages
    assert not any("no initial guess" in s for s in stages), stages
    assert any(s.startswith("optimising level") for s in stages) and stages[-1] == "writing overlays", stages
    searched = [f for s, f in shown if "global search" in s]
    optimised = [f for s, f in shown if s.startswith("optimising")]
    assert max(searched) <= min(optimised), shown  # the search's band ends where the optimisation's begins


def test_a_check_and_the_rig_files_missing_guess():
    """A check's edges, then its search around the pose: forward only; a rig file without a guess is named."""
    out = io.StringIO()
    check = Reporter(out, CHECK_BANDS)
    for stage, fraction in (("edges of 1/8 pairs", 0.0), ("edges of 8/8 pairs", 0.875),
                            ("searching around the checked extrinsics", 0.6)):
        check.progress(stage, fraction)
    fractions = [f for _, f in reports(out)]
    assert fractions == [0.0, 0.525, 0.6]
    out = io.StringIO()
    rig = Reporter(out, job_bands({"initial_matrix": None}), "rig")
    rig.progress("no initial guess: global search over the mounts, pair 3/8", 0.575)
    assert reports(out) == [("no initial guess in the rig file: global search over the mounts, pair 3/8",
                             0.3 + 0.2 * 3 / 8)]
