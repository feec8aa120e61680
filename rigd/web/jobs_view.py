"""A job as the page shows it: what it produced in words (a calibration's verdict and what became of its version,
a check's status, a capture's pairs), where a job that ended early stopped, and what to do after a failure, with
the requests the page's buttons send for it."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from calib.drift import percent
from calib.methods import Method
from rigd.api.models import JobOut
from rigd.calibration.request import Start, TransformIn
from rigd.results import CaptureJobResult, is_calibration, is_capture, is_check
from rigd.web.words import method_name

# The colour of an outcome: a verdict, a check's status.
TONES = {"trusted": "ok", "ok": "ok", "weak": "warn", "unknown": "warn", "none": "warn", "failed": "bad",
         "drifted": "bad"}
NOTHING_WRITTEN = "nothing written"
PHOTOMETRIC = {Method.NID_ASSESSED.value}


@dataclass(frozen=True)
class Button:
    """A request one of the page's buttons sends (an endpoint and its JSON body), with its label."""

    label: str
    url: str
    body: str


def _body(request: dict[str, Any]) -> str:
    return json.dumps({k: v for k, v in request.items() if v is not None})


def pairs_word(n: int) -> str:
    return "1 pair" if n == 1 else f"{n} pairs"


def capture_words(result: CaptureJobResult, params: dict[str, Any], status: str = "succeeded") -> str:
    """A capture's outcome: how many pairs it wrote and the dataset holds; one that ended early says so, one
    that wrote nothing says why where it knows (the count is of pairs in all, not more pairs)."""
    written, held, asked = result["pairs_written"], result["pairs_in_dataset"], params.get("n")
    if status == "cancelled":
        return f"cancelled after {pairs_word(written)}: {held} in the dataset"
    if status == "failed":
        return f"stopped after {pairs_word(written)}: {held} in the dataset"
    if written == 0 and isinstance(asked, int) and held >= asked:
        return f"no pair written: the dataset already held {pairs_word(held)}, and {asked} in all were asked for"
    if written == 0:
        return f"no pair written: {held} in the dataset"
    return f"{pairs_word(written)} written, {held} in the dataset"


@dataclass(frozen=True)
class JobView:
    """A job with what it produced: the verdict of the version a calibration stored (and that version's status
    now), or a check's status and what it checked; ``active_now``: the version active now."""

    record: JobOut
    version: int | None = None
    version_status: str | None = None
    verdict: str | None = None
    active_now: int | None = None

    @property
    def outcome(self) -> str | None:
        """trusted | weak | failed for a calibration, ok | drifted | unknown for a check, "nothing written" for
        a capture that wrote no pair; None before the end."""
        result = self.record.result
        if self.record.status != "succeeded" or not result:
            return None
        if self.record.kind == "calibrate":
            return self.verdict
        if is_capture(result):
            return NOTHING_WRITTEN if result["pairs_written"] == 0 else None
        return result["status"] if is_check(result) else None

    @property
    def badge(self) -> tuple[str, str]:
        """The row's badge: its words and its class (its colour)."""
        outcome = self.outcome
        if outcome == NOTHING_WRITTEN:
            return outcome, "weak"
        if outcome is not None:
            return ("verdict " if self.record.kind == "calibrate" else "") + outcome, outcome
        return self.record.status, self.record.status

    @property
    def tone(self) -> str:
        """ok, warn or bad: how the page colours the job's outcome; empty while it runs."""
        status = self.record.status
        if status in ("queued", "running"):
            return ""
        if status != "succeeded":
            return "bad" if status == "failed" else "warn"
        if self.outcome == NOTHING_WRITTEN:
            return "warn"
        return TONES.get(self.outcome or "", "ok")

    @property
    def summary(self) -> str:
        """One line on where the job stands, for the message at the top of the page."""
        j = self.record
        head = f"job {j.id}"
        if j.status == "queued":
            return f"{head} queued" + (f": {j.stage}" if j.stage else "")
        if j.status == "running":
            return f"{head} running: {j.stage} ({j.fraction * 100:.0f} %)"
        if self.interrupted:
            return f"{head} was interrupted: the service stopped while it ran; run it again"
        if j.status == "failed":
            steps = self.failure_steps
            return f"{head} failed: {j.error}" + (f"; what to do: {steps[0][0]}" if steps else "")
        if j.status == "cancelled":
            result = j.result
            return f"{head} " + (capture_words(result, j.params, "cancelled") if result and is_capture(result)
                                 else "cancelled")
        return f"{head} done: {self._result()}"

    @property
    def stopped(self) -> str | None:
        """Where a job that ended early stopped, for its bar (None: it finished, or runs)."""
        j = self.record
        if j.status not in ("failed", "cancelled"):
            return None
        if j.kind == "capture" and isinstance(n := j.params.get("n"), int):
            done = j.result["pairs_written"] if j.result and is_capture(j.result) else round(j.fraction * n)
            return f"stopped after {done} of {n} pairs"
        return f"stopped at {j.fraction * 100:.0f} %"

    @property
    def checked(self) -> str | None:
        """What a check checked, as the row and the message name it ("version 1 on s2"); None for another job."""
        p = self.record.params
        if self.record.kind != "check":
            return None
        number = p.get("against_version")
        return f"{'a given transform' if number is None else f'version {number}'} on {p.get('dataset', '?')}"

    @property
    def checked_since(self) -> str | None:
        """For a check of a version no longer active, which one is active now (the row would read as current)."""
        number = self.record.params.get("against_version")
        if self.record.kind != "check" or number is None or self.active_now in (None, number):
            return None
        return f"version {self.active_now} is active now"

    @property
    def first_activated(self) -> bool:
        """The calibration's version was activated as the first one (nothing was active; its verdict trusted),
        not by "activate if trusted" (the store does so: docs/service.md)."""
        result = self.record.result
        return (result is not None and is_calibration(result) and result["status"] == "active"
                and result["change"] is None and not result["auto_activate"]["requested"])

    @property
    def interrupted(self) -> bool:
        """Failed because the service stopped while it was queued or running (not for a reason of its own)."""
        return self.record.status == "failed" and (self.record.error or "").startswith("interrupted")

    @property
    def rerun(self) -> tuple[str, str] | None:
        """An interrupted job's request again (the endpoint and its JSON body), for its "Run again" button."""
        if not self.interrupted:
            return None
        endpoint, body = RERUNS[self.record.kind](self.record.params)
        return endpoint, _body(body)

    @property
    def method(self) -> str | None:
        """The method a calibration runs (resolved when it was queued) and why, in words; None if not recorded."""
        method = self.record.params.get("method") if self.record.kind == "calibrate" else None
        return f"{method_name(method['name'])}: {method['why']}" if method else None

    @property
    def options(self) -> list[str]:
        """A calibration's start and the options it was given, in words."""
        if self.record.kind != "calibrate":
            return []
        request = self.record.params.get("request") or {}
        start = {Start.ACTIVE.value: f"from version {request.get('start_version')}",
                 Start.RIG.value: "from the rig file's guess", Start.SEARCH.value: "from a global search",
                 Start.GIVEN.value: "from a given transform"}
        words = [start.get(str(request.get("start")), str(request.get("start")))]
        p = request.get("options") or {}
        prior = p.get("prior") or {}
        if prior.get("sigma_cm") is not None:
            # cm, as the page's forms and tables, with the digits given (0.0934 cm typed for metres shows so)
            lever = ", ".join(f"{x * 100.0:.4g}" for x in prior["xyz_m"])
            words.append(f"lever arm ({lever}) ± {prior['sigma_cm']:g} cm")
        if prior.get("sigma_deg") is not None:
            words.append(f"angles ± {prior['sigma_deg']:g}°")
        if p.get("fix_translation"):
            words.append("translation fixed")
        if tolerance := p.get("tolerance"):
            words.append(f"tolerance {tolerance['rotation_deg']:g}° / {tolerance['translation_cm']:g} cm")
        return words

    @property
    def failure_steps(self) -> list[tuple[str, Button | None]]:
        """What to do after a calibration failed (not interrupted), each with the request its button sends: a
        start that needs no guess, the GMM after a photometric method, more pairs with structure after both."""
        j = self.record
        if j.kind != "calibrate" or j.status != "failed" or self.interrupted:
            return []
        endpoint, again = _calibrate_again(j.params)
        dataset = j.params.get("dataset")
        method = (j.params.get("method") or {}).get("name") or (again.get("method"))
        steps: list[tuple[str, Button | None]] = []
        if again["init"] != Start.SEARCH.value:
            steps.append(("start from a global search: it needs no guess, and a start made for another rig or "
                          "far off puts the LiDAR's points outside the image",
                          Button(f"Calibrate {dataset} from a global search", endpoint,
                                 _body({**again, "init": Start.SEARCH.value}))))
        if method in PHOTOMETRIC:
            why = f": {method_name(method)} found no minimum" if "not a minimum" in (j.error or "") else ""
            steps.append((f"or calibrate with {method_name(Method.GMM.value)} instead{why}",
                          Button(f"Calibrate {dataset} with edges (GMM)", endpoint,
                                 _body({**again, "method": Method.GMM.value}))))
        steps.append(("capture more pairs at places with buildings, poles or doorways 2-10 m from the rig", None))
        return steps

    @property
    def check_lines(self) -> list[str]:
        """A finished check's rotation and translation change, each as how far it moved against its threshold;
        none for another job, or a check stored before the report had its groups."""
        result = self.record.result
        if not result or not is_check(result) or "groups" not in result or "confidence" not in result:
            return []
        confidence = percent(result["confidence"]["ok"])
        lines = []
        for name, u in (("rotation", "°"), ("translation", " cm")):
            if (g := result["groups"].get(name)) is not None:
                lines.append(f"{name} moved by {g['length']:.2f}{u} (threshold {g['threshold']:g}{u}); the pairs "
                             f"allow up to {g['upper']:.2f}{u} at {confidence} confidence")
        return lines

    def _result(self) -> str:
        result = self.record.result
        if result is not None and is_check(result):
            reasons = result["reasons"]
            return f"{self.checked}: {result['status']}" + (f" ({reasons[0]})" if reasons else "")
        if result is not None and is_capture(result):
            return capture_words(result, self.record.params)
        if self.version is None:
            return "no version stored"
        return f"version {self.version}, verdict {self.verdict} ({self._version_state()})"

    def _version_state(self) -> str:
        if self.verdict == "failed" and self.version_status != "active":
            return "do not use it: it was not activated, the active version stays"
        now = {"active": "active", "superseded": "no longer active"}.get(
            self.version_status or "", "not active: activate it below if you accept it")
        if self.first_activated:  # not asked for: the page says why it is active
            return "activated: the first version, as nothing was active" + ("" if now == "active" else f"; {now}")
        return now


def _calibrate_again(p: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """The start as the operator chose it (the active version or the rig file's guess as they are now), a given
    transform as it was given, with the same options."""
    request = p.get("request") or {}
    start = request.get("start")
    init = {"matrix": TransformIn.model_validate(request["initial"]).transform.matrix.tolist()} \
        if start == Start.GIVEN.value else start
    return "/calibrate", {"dataset": p.get("dataset"), "init": init, "auto_activate": p.get("auto_activate"),
                          **(request.get("options") or {})}


def _check_again(p: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """The same extrinsics again: the version it checked (not whichever is active now), or the transform."""
    number = p.get("against_version")
    against = number if number is not None else {"matrix": p["checked"]["matrix"]}
    return "/check", {"dataset": p.get("dataset"), "against": against, "threshold": p.get("threshold")}


def _capture_again(p: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """Into the same dataset (continued at its next pair) up to the same count."""
    return "/capture", {"dataset": p.get("dataset"), "n": p.get("n"), "still_seconds": p.get("still_seconds"),
                        "sweeps": p.get("sweeps"), "min_move": p.get("min_move"), "source": p.get("source")}


RERUNS: dict[str, Callable[[dict[str, Any]], tuple[str, dict[str, Any]]]] = {
    "calibrate": _calibrate_again, "check": _check_again, "capture": _capture_again}
