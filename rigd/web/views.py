"""What the operator page shows, read from the service as the open ``GET`` endpoints read it: the status, the
latest jobs with the verdicts they produced, a page of the newest versions, the datasets."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from starlette.concurrency import run_in_threadpool

from calib.assess import TrustOptions
from calib.uncertainty import TO_DISPLAY, xi_of
from rigd.api.models import DatasetOut, JobOut, StatusOut, VersionOut
from rigd.api.routes.datasets import list_datasets
from rigd.api.routes.extrinsics import version_out
from rigd.api.routes.jobs import list_jobs
from rigd.api.routes.status import get_status
from rigd.api.service import Service
from rigd.calibration.advice import Action
from rigd.calibration.check_job import group_lines
from rigd.calibration.request import Start, TransformIn
from rigd.report import NextStep, VersionQuality, calibrated, verdict_of
from rigd.results import CaptureJobResult, is_calibration, is_capture, is_check
from rigd.store import ExtrinsicsVersion

JOBS_SHOWN = 15
VERSIONS_PAGE = 10  # versions on the page at first; "Show older" adds as many again

# The advice's actions (rigd.calibration.advice.Action) the page has a button for, with its label.
ADVICE_BUTTONS = {
    Action.LEVER_ARM.value: "Give the lever arm",
    Action.FIX_TRANSLATION.value: "Fix the translation",
    Action.SEARCH.value: "Use the global search",
    Action.CAPTURE.value: "Capture more pairs",
}


def _records(steps: list[NextStep | str]) -> list[NextStep]:
    """The steps as records; a report stored before steps were records holds words alone (no buttons)."""
    return [{"text": s, "actions": [], "axes": [], "pairs": None} if isinstance(s, str) else s for s in steps]


def capture_target(steps: list[NextStep | str]) -> int | None:
    """The one count the advice's capture button fills in: the largest its steps ask for (None: none asks)."""
    counts = [s["pairs"] for s in _records(steps) if s["pairs"] and Action.CAPTURE.value in s["actions"]]
    return max(counts) if counts else None


def advice_actions(step: NextStep) -> list[tuple[str, str]]:
    """(action, label) of the page's buttons for an advice step."""
    return [(a, ADVICE_BUTTONS[a]) for a in step["actions"] if a in ADVICE_BUTTONS]


def report_sensors(quality: VersionQuality) -> list[str]:
    """A head's sensors, in the dataset's order, as the version's report lists them per pair (the overlays were
    written per sensor under these names); empty for one camera or a version without pairs (manual)."""
    pairs = quality["pairs"] if calibrated(quality) else []
    return list(pairs[0].get("edge_pixels_per_sensor", {})) if pairs else []


SIGMA_FACTOR = TrustOptions().sigma_factor  # the verdict's: an axis is known to within 2.5 sigma


def stands_out(change: list[float], sigma: list[float | None] | None) -> list[bool]:
    """Which axes of a change against the active version stand out (shown bold): beyond the verdict's 2.5 sigma
    of this version, or, without a sigma (a manual version), any change the table shows (0.005 or more)."""
    limits = [SIGMA_FACTOR * s if s is not None else 0.005 for s in (sigma or [None] * len(change))]
    return [abs(d) >= 0.005 and abs(d) > limit for d, limit in zip(change, limits, strict=True)]


@dataclass(frozen=True)
class VersionView:
    """A version as the page shows it: its values, change against the active one and sigma per axis
    (roll, pitch, yaw deg; x, y, z cm; the change in the uncertainty's local axes, as ``rigd check``), its
    pairs with overlays and a multi-camera head's sensors (empty for one camera)."""

    record: VersionOut
    values: list[float]
    change: list[float] | None
    sigma: list[float | None] | None
    pairs: list[int]
    sensors: list[str]

    @property
    def verdict(self) -> str:
        """trusted, weak or failed; ``none`` for a version stored by hand."""
        return self.record.verdict["status"] if self.record.verdict else "none"

    @property
    def reasons(self) -> list[str]:
        """Why it is not trusted (what activating it asks the operator to accept); empty when trusted."""
        if self.record.verdict is None:
            note = self.record.parameters.get("note")
            return [f"stored by hand ({self.record.method}): it has no verdict, nothing measured its uncertainty"
                    + (f"; note: {note}" if note else "")]
        return [] if self.verdict == "trusted" else list(self.record.verdict["reasons"])

    @property
    def change_marks(self) -> list[bool]:
        """Per axis, whether the change against the active version stands out against sigma (bold)."""
        return stands_out(self.change, self.sigma) if self.change is not None else []

    @property
    def capture_target(self) -> int | None:
        """The pairs in all the advice asks for (its "Capture more pairs" button fills them in)."""
        return capture_target(self._next_steps())

    def _next_steps(self) -> list[NextStep | str]:
        return list(self.record.verdict.get("next_steps", [])) if self.record.verdict else []

    @property
    def steps(self) -> list[tuple[str, list[tuple[str, str]]]]:
        """The advice's steps, each with the page's buttons for it (a button only at its first step)."""
        seen: set[str] = set()
        steps = []
        for step in _records(self._next_steps()):
            actions = [(a, label) for a, label in advice_actions(step) if a not in seen]
            seen.update(a for a, _ in actions)
            steps.append((step["text"], actions))
        return steps


def version_view(version: ExtrinsicsVersion, active: ExtrinsicsVersion | None) -> VersionView:
    v = version_out(version)
    values = [*v.T_camera_lidar.rpy_deg, *(np.asarray(v.T_camera_lidar.xyz_m) * 100.0)]
    change = None
    if active is not None and version.number != active.number:
        change = (xi_of(active.T_camera_lidar.tau, version.T_camera_lidar.tau) * TO_DISPLAY).tolist()
    sigma = [*v.uncertainty["rpy_deg"], *v.uncertainty["xyz_cm"]] if v.uncertainty else None
    pairs = [int(link.rsplit("/", 1)[1].removesuffix(".png")) for link in v.overlays]
    return VersionView(v, [float(x) for x in values], change, sigma, pairs, report_sensors(v.quality))


# The colour of an outcome: a verdict, a check's status.
TONES = {"trusted": "ok", "ok": "ok", "weak": "warn", "unknown": "warn", "none": "warn", "failed": "bad",
         "drifted": "bad"}


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
        """trusted | weak | failed for a calibration, ok | drifted | unknown for a check; None before the end."""
        result = self.record.result
        if self.record.status != "succeeded" or not result:
            return None
        if self.record.kind == "calibrate":
            return self.verdict
        return result["status"] if is_check(result) else None

    @property
    def tone(self) -> str:
        """ok, warn or bad: how the page colours the job's outcome; empty while it runs."""
        status = self.record.status
        if status in ("queued", "running"):
            return ""
        if status != "succeeded":
            return "bad" if status == "failed" else "warn"
        result = self.record.result
        if result is not None and is_capture(result) and result["pairs_written"] == 0:
            return "warn"  # asked for no more than the dataset held: nothing was captured
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
            return f"{head} failed: {j.error}"
        if j.status == "cancelled":
            return f"{head} cancelled"
        return f"{head} done: {self._result()}"

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
        return endpoint, json.dumps({k: v for k, v in body.items() if v is not None})

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
            lever = ", ".join(f"{x * 100.0:.1f}" for x in prior["xyz_m"])  # cm, as the page's forms and tables
            words.append(f"lever arm ({lever}) ± {prior['sigma_cm']:g} cm")
        if prior.get("sigma_deg") is not None:
            words.append(f"angles ± {prior['sigma_deg']:g}°")
        if p.get("fix_translation"):
            words.append("translation fixed")
        if tolerance := p.get("tolerance"):
            words.append(f"tolerance {tolerance['rotation_deg']:g}° / {tolerance['translation_cm']:g} cm")
        return words

    @property
    def check_lines(self) -> list[str]:
        """A finished check's rotation and translation change as lengths against their bounds (rigd check's
        words); none for another job, or a check stored before the report had its groups."""
        result = self.record.result
        if not result or not is_check(result) or "groups" not in result or "confidence" not in result:
            return []
        return group_lines(result)

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


def capture_words(result: CaptureJobResult, params: dict[str, Any]) -> str:
    """A capture's outcome; one that wrote nothing says why (the count is of pairs in all, not more pairs)."""
    if result["pairs_written"] == 0:
        return (f"no pair written: the dataset already held {result['pairs_in_dataset']} pairs, and "
                f"{params.get('n', '?')} in all were asked for")
    return f"{result['pairs_written']} pairs written, {result['pairs_in_dataset']} in the dataset"


def job_views(jobs: list[JobOut], stored: dict[int, ExtrinsicsVersion], active: int | None) -> list[JobView]:
    views = []
    for job in jobs:
        version = stored.get(n) if (n := stored_version(job)) is not None else None
        if version is None:
            views.append(JobView(job, n, active_now=active))
            continue
        verdict = verdict_of(version.quality)
        views.append(JobView(job, n, version.status.value, verdict["status"] if verdict else "none", active))
    return views


@dataclass(frozen=True)
class PageState:
    status: StatusOut
    jobs: list[JobView]
    versions: list[VersionView]  # newest first
    version_count: int
    default_view: VersionView | None  # the newest calibration: the viewer shows it until another is picked
    datasets: list[DatasetOut]

    @property
    def capture(self) -> JobOut | None:
        """The running (else the latest) capture job."""
        captures = [j.record for j in self.jobs if j.record.kind == "capture"]
        return next((j for j in captures if j.status == "running"), captures[0] if captures else None)

    @property
    def busy(self) -> bool:
        return any(j.record.status in ("queued", "running") for j in self.jobs)


def stored_version(job: JobOut) -> int | None:
    """The version a calibration job stored, if any."""
    return job.result["version"] if job.result is not None and is_calibration(job.result) else None


def _read(service: Service, shown: int) -> tuple[list[JobView], list[VersionView], int, VersionView | None,
                                                  list[DatasetOut]]:
    jobs = list_jobs(service, JOBS_SHOWN, None, None)
    stored = service.versions.numbered({n for j in jobs if (n := stored_version(j)) is not None})
    active = service.versions.active()
    versions = [version_view(v, active) for v in service.versions.newest(shown)]
    newest_calibration = service.versions.newest_calibration()
    default_view = version_view(newest_calibration, active) if newest_calibration else None
    views = job_views(jobs, stored, active.number if active else None)
    return views, versions, service.versions.count(), default_view, list_datasets(service)


async def page_state(service: Service, shown: int) -> PageState:
    """The page's state with the ``shown`` newest versions."""
    status = await get_status(service)
    return PageState(status, *await run_in_threadpool(_read, service, shown))
