"""The jobs list as the page renders it (rigd/web/templates/_jobs.html), without a browser."""

import re
from html import unescape

from rigd.api.models import JobOut
from rigd.web.jobs_view import JobView
from rigd.web.routes import TEMPLATES

GROUPS = {"rotation": {"length": 0.4123, "upper": 0.5871, "threshold": 0.3, "t2": 41.2, "t2_limit": 9.3},
          "translation": {"length": 0.87, "upper": 1.65, "threshold": 2.0, "t2": 3.1, "t2_limit": 9.3}}
IDENTITY = {"matrix": [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
            "quaternion_xyzw": [0.0, 0.0, 0.0, 1.0], "rpy_deg": [0.0, 0.0, 0.0], "xyz_m": [0.0, 0.0, 0.0]}
# What every check report holds (JobOut types it: rigd.results.CheckReport); the tests add the rest.
REPORT = {"axes": [], "change": {"rpy_deg": [0.0] * 3, "xyz_cm": [0.0] * 3},
          "sigma": {"rpy_deg": [0.1] * 3, "xyz_cm": [1.0] * 3},
          "thresholds": {"rotation_deg": 0.3, "translation_cm": 2.0}, "checked": IDENTITY, "found": IDENTITY,
          "dataset": "/data/datasets/field", "pairs": 8, "wall_time_s": 2.5}


def _check_job(result: dict, version: int | None = None) -> JobOut:
    return JobOut(id=7, kind="check", status="succeeded", stage="done", fraction=1.0, created_at="t",
                  started_at="t", finished_at="t", params={"dataset": "field", "against_version": version},
                  result={**REPORT, **result}, result_link=None, error=None, log_tail=[])


def _items(html: str, css_class: str) -> list[str]:
    block = re.search(rf'<ul class="{css_class} small">(.*?)</ul>', html, re.S)
    return [] if block is None else [unescape(x) for x in re.findall(r"<li>(.*?)</li>", block.group(1))]


def _render(job: JobOut, active_now: int | None = None) -> str:
    class State:
        jobs = [JobView(job, active_now=active_now)]
        capture = None

    return TEMPLATES.get_template("_jobs.html").render({"state": State()})


def test_a_check_shows_each_groups_length_against_its_bound_and_threshold():
    result = {"status": "drifted", "reasons": ["rotation changed by 0.41 deg"], "groups": GROUPS,
              "confidence": {"ok": 0.95, "drifted": 0.95}}
    html = _render(_check_job(result))
    lengths = _items(html, "lengths")
    assert len(lengths) == 2
    for line, (name, unit) in zip(lengths, (("rotation", "°"), ("translation", " cm")), strict=True):
        g = GROUPS[name]  # the page's words: "moved by ... (threshold ...)", in ° and cm
        assert line.startswith(f"{name} moved by {g['length']:.2f}{unit} (threshold {g['threshold']:g}{unit})")
        assert f"up to {g['upper']:.2f}{unit} at 95 % confidence" in line
    assert _items(html, "reasons") == ["rotation changed by 0.41°"]  # rigd check's words with the page's units


def test_a_check_that_judged_no_group_or_predates_them_shows_no_lengths():
    for result in ({"status": "unknown", "reasons": ["3 places"], "groups": {},
                    "confidence": {"ok": 0.95, "drifted": 0.95}},
                   {"status": "ok", "reasons": ["old report"]}):
        html = _render(_check_job(result))
        assert _items(html, "lengths") == [] and _items(html, "reasons") == result["reasons"]


def _text(html: str) -> str:
    return " ".join(unescape(re.sub(r"<[^>]+>", " ", html)).split())


def test_a_check_says_which_version_it_checked_and_when_another_is_active_now():
    """ "#9 check s2 ok" read as current after version 4 was activated: it names version 1, and that 4 is now."""
    result = {"status": "ok", "reasons": ["every change below its threshold"]}
    job = _check_job(result, version=1)
    assert JobView(job, active_now=1).summary == "job 7 done: version 1 on field: ok (every change below its threshold)"
    assert "#7 check version 1 on field" in _text(_render(job, active_now=1))
    assert "active now" not in _text(_render(job, active_now=1))
    assert "(version 4 is active now)" in _text(_render(job, active_now=4))
    given = _check_job(result)  # against a transform given in the request
    assert JobView(given).summary.startswith("job 7 done: a given transform on field: ok")


def _calibration_job(status: str, change: dict | None, requested: bool) -> JobOut:
    result = {"version": 1, "status": status, "change": change,
              "auto_activate": {"requested": requested, "failed_checks": []}}
    return JobOut(id=3, kind="calibrate", status="succeeded", stage="done", fraction=1.0, created_at="t",
                  started_at="t", finished_at="t", params={"dataset": "field", "init": "rig"}, result=result,
                  result_link="/extrinsics/versions/1", error=None, log_tail=[])


def test_a_first_version_activated_without_the_box_says_so():
    """Nothing was active and "activate if trusted" was unticked: the trusted first version is active, and the
    job says why; activated because the box asked, or a later version, it does not."""
    first = JobView(_calibration_job("active", None, requested=False), 1, "active", "trusted", active_now=1)
    assert first.first_activated
    assert first.summary == ("job 3 done: version 1, verdict trusted (activated: the first version, as nothing was "
                             "active)")
    assert "activated: the first version" in _text(_render(first.record, active_now=1))
    asked = JobView(_calibration_job("active", None, requested=True), 1, "active", "trusted")
    change = {"against": 1, "rotation_deg": 0.1, "translation_cm": 0.5}
    later = JobView(_calibration_job("candidate", change, requested=False), 1, "candidate", "weak")
    assert not asked.first_activated and not later.first_activated
    assert asked.summary.endswith("(active)")
    superseded = JobView(_calibration_job("active", None, requested=False), 1, "superseded", "trusted")
    assert superseded.summary.endswith("(activated: the first version, as nothing was active; no longer active)")
