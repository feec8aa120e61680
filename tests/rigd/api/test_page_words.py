"""What the operator page says of jobs and reports, without a browser: a capture's outcome and where a job
stopped, what to do after a failed calibration (and the requests its buttons send), and the page's one vocabulary
(° and cm, reasons as "known to ±")."""

from __future__ import annotations

import json

from rigd.api.models import JobOut
from rigd.web.jobs_view import JobView, capture_words
from rigd.web.words import method_name, page_words


def job(kind: str, status: str, **fields) -> JobOut:
    return JobOut(**{"id": 7, "kind": kind, "status": status, "stage": status, "fraction": 0.0,
                     "created_at": "2026-01-01T00:00:00Z", "started_at": None, "finished_at": None, "params": {},
                     "result": None, "result_link": None, "error": None, "log_tail": [], **fields})


def capture_result(written: int, held: int) -> dict:
    return {"dataset": "yard", "pairs_written": written, "pairs_in_dataset": held, "seconds_per_pair": []}


def test_a_capture_says_how_it_ended_and_nothing_written_is_not_green():
    params = {"dataset": "yard", "n": 5}
    assert capture_words(capture_result(2, 2), params, "cancelled") == "cancelled after 2 pairs: 2 in the dataset"
    assert capture_words(capture_result(0, 12), {"n": 2}) == ("no pair written: the dataset already held 12 pairs, "
                                                               "and 2 in all were asked for")
    assert capture_words(capture_result(0, 0), params) == "no pair written: 0 in the dataset"  # no false cause
    nothing = JobView(job("capture", "succeeded", params={"n": 2}, result=capture_result(0, 12)))
    assert nothing.badge == ("nothing written", "weak") and nothing.tone == "warn"
    cancelled = JobView(job("capture", "cancelled", params=params, fraction=0.4, result=capture_result(2, 2)))
    assert cancelled.summary == "job 7 cancelled after 2 pairs: 2 in the dataset"
    assert cancelled.stopped == "stopped after 2 of 5 pairs"
    failed = JobView(job("capture", "failed", params={"n": 12}, fraction=11 / 12, error="the LiDAR went silent"))
    assert failed.stopped == "stopped after 11 of 12 pairs" and failed.tone == "bad"
    assert JobView(job("calibrate", "failed", fraction=0.5, error="x")).stopped == "stopped at 50 %"


def calibration_params(start: str, method: str) -> dict:
    initial = {"matrix": [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1.0]]}
    return {"dataset": "pin1", "auto_activate": False, "method": {"name": method, "why": "the default"},
            "request": {"start": start, "initial": initial, "start_version": 3,
                        "options": {"method": None, "prior": None, "fix_translation": False}}}


def test_a_failed_calibration_says_what_to_do_with_buttons_that_do_it():
    failed = JobView(job("calibrate", "failed", params=calibration_params("active", "nid-assessed"),
                         error="dataset pin1: the solution is not a minimum of the finest-level cost"))
    steps = failed.failure_steps
    search, gmm = (json.loads(button.body) for _, button in steps[:2])
    assert search["init"] == "search" and search["dataset"] == "pin1" and "method" not in search
    assert gmm["init"] == "active" and gmm["method"] == "gmm"
    assert steps[2][1] is None and "buildings, poles or doorways" in steps[2][0]  # words alone: no button
    assert failed.summary.startswith("job 7 failed: dataset pin1: the solution is not a minimum") \
        and "; what to do: start from a global search" in failed.summary
    searched = JobView(job("calibrate", "failed", params=calibration_params("search", "gmm"), error="x"))
    assert [b for _, b in searched.failure_steps] == [None]  # searched with the GMM already: only more pairs
    assert searched.method == "GMM edge alignment: the default"
    interrupted = JobView(job("calibrate", "failed", params=calibration_params("rig", "gmm"),
                              error="interrupted: the service stopped"))
    assert interrupted.failure_steps == []  # Run again instead


def test_a_failed_version_is_not_offered_as_if_it_could_be_accepted():
    stored = JobView(job("calibrate", "succeeded", result={
        "version": 5, "status": "candidate", "change": None, "auto_activate": {"requested": False}}),
        version=5, version_status="candidate", verdict="failed")
    assert stored.summary == ("job 7 done: version 5, verdict failed (do not use it: it was not activated, the "
                              "active version stays)")
    assert stored.tone == "bad" and stored.badge == ("verdict failed", "failed")


def test_the_page_speaks_in_degrees_and_centimetres():
    assert page_words("pitch: 2.5 sigma = 0.301 > tolerance 0.2") == "pitch known to ±0.30° (needs ±0.20°)"
    assert page_words("x: 2.5 sigma = 4.31 > tolerance 2") == "x known to ±4.31 cm (needs ±2.00 cm)"
    assert page_words("rotation moved 1.15 deg (yaw +1.1; threshold 0.3); real: T² 1.58e+04 > 18.6") == \
        "rotation moved 1.15° (yaw +1.1°; threshold 0.3)"
    assert page_words("solution 1 ended roll -1.14, pitch +1.12, y -6.46 away at a cost the data cannot tell "
                      "apart") == ("solution 1 ended roll -1.14°, pitch +1.12°, y -6.46 cm away at a cost the data "
                                   "cannot tell apart")
    assert page_words("x +3.2 cm, yaw -0.5°") == "x +3.2 cm, yaw -0.5°"  # units given stay as they are
    assert page_words("(LiDAR: 0.121 deg, 0.8 mm from the window's first sweep; still is within 0.050 deg, "
                      "2.6 mm)") == ("(LiDAR: 0.121°, 0.08 cm from the window's first sweep; still is within "
                                     "0.050°, 0.26 cm)")
    assert page_words("every axis within tolerance at 2.5 sigma; 4 restarts agree") == \
        "every axis within tolerance at 2.5 σ; 4 restarts agree"
    new = "pitch known to ±0.30° (needs ±0.20°)"
    assert page_words(new) == new  # the verdict's own words now: left as they are
    assert method_name("gmm") == "GMM edge alignment" and method_name("nid-assessed").startswith("NID")
    assert method_name("something-older") == "something-older"
