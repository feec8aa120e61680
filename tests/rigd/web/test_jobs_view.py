"""The jobs list as the page renders it (rigd/web/templates/_jobs.html), without a browser."""

import re
from html import unescape

from rigd.api.models import JobOut
from rigd.web.routes import TEMPLATES
from rigd.web.views import JobView

GROUPS = {"rotation": {"length": 0.4123, "upper": 0.5871, "threshold": 0.3, "t2": 41.2, "t2_limit": 9.3},
          "translation": {"length": 0.87, "upper": 1.65, "threshold": 2.0, "t2": 3.1, "t2_limit": 9.3}}
IDENTITY = {"matrix": [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
            "quaternion_xyzw": [0.0, 0.0, 0.0, 1.0], "rpy_deg": [0.0, 0.0, 0.0], "xyz_m": [0.0, 0.0, 0.0]}
# What every check report holds (JobOut types it: rigd.results.CheckReport); the tests add the rest.
REPORT = {"axes": [], "change": {"rpy_deg": [0.0] * 3, "xyz_cm": [0.0] * 3},
          "sigma": {"rpy_deg": [0.1] * 3, "xyz_cm": [1.0] * 3},
          "thresholds": {"rotation_deg": 0.3, "translation_cm": 2.0}, "checked": IDENTITY, "found": IDENTITY,
          "dataset": "/data/datasets/field", "pairs": 8, "wall_time_s": 2.5}


def _check_job(result: dict) -> JobOut:
    return JobOut(id=7, kind="check", status="succeeded", stage="done", fraction=1.0, created_at="t",
                  started_at="t", finished_at="t", params={"dataset": "field"}, result={**REPORT, **result},
                  result_link=None, error=None, log_tail=[])


def _items(html: str, css_class: str) -> list[str]:
    block = re.search(rf'<ul class="{css_class} small">(.*?)</ul>', html, re.S)
    return [] if block is None else [unescape(x) for x in re.findall(r"<li>(.*?)</li>", block.group(1))]


def _render(job: JobOut) -> str:
    class State:
        jobs = [JobView(job)]

    return TEMPLATES.get_template("_jobs.html").render({"state": State()})


def test_a_check_shows_each_groups_length_against_its_bound_and_threshold():
    result = {"status": "drifted", "reasons": ["rotation changed by 0.41 deg"], "groups": GROUPS,
              "confidence": {"ok": 0.95, "drifted": 0.95}}
    html = _render(_check_job(result))
    lengths = _items(html, "lengths")
    assert len(lengths) == 2
    for line, (name, unit) in zip(lengths, (("rotation", "deg"), ("translation", "cm")), strict=True):
        g = GROUPS[name]
        assert line.startswith(f"{name}: {g['length']:.3g} {unit}, at most {g['upper']:.3g} at 95")
        assert line.endswith(f"(threshold {g['threshold']:g})")
    assert _items(html, "reasons") == result["reasons"]


def test_a_check_that_judged_no_group_or_predates_them_shows_no_lengths():
    for result in ({"status": "unknown", "reasons": ["3 places"], "groups": {},
                    "confidence": {"ok": 0.95, "drifted": 0.95}},
                   {"status": "ok", "reasons": ["old report"]}):
        html = _render(_check_job(result))
        assert _items(html, "lengths") == [] and _items(html, "reasons") == result["reasons"]
