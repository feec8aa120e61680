"""An extrinsics version as the page shows it: its values per axis, its change against the active version when
both are of one rig, its verdict in the page's words, the advice with the page's buttons, and what activating it
would move."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from calib.assess import TrustOptions
from calib.uncertainty import AXES, TO_DISPLAY, xi_of
from rigd.api.models import RigOut, VersionOut
from rigd.api.rigs import rig_words, same_rig
from rigd.api.routes.extrinsics import version_out
from rigd.calibration.advice import Action
from rigd.report import NextStep, VersionQuality, calibrated
from rigd.store import ExtrinsicsVersion
from rigd.store.versions import change_between
from rigd.web.words import method_name, page_words, unit

# The advice's actions (rigd.calibration.advice.Action) the page has a button for, with its label.
ADVICE_BUTTONS = {
    Action.LEVER_ARM.value: "Give the lever arm",
    Action.FIX_TRANSLATION.value: "Fix the translation",
    Action.SEARCH.value: "Use the global search",
    Action.CAPTURE.value: "Capture more pairs",
}
CHECK_LEVER_ARM = "Check the lever arm given"  # the lever-arm button where one was given: it shows it again


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


def given_lever_arm_cm(parameters: dict[str, Any]) -> list[float] | None:
    """The lever arm a calibration was given on the page or in its request (cm, as the page's fields), if any."""
    prior = (((parameters.get("request") or {}).get("options") or {}).get("prior")) or {}
    xyz = prior.get("xyz_m")
    return [float(x) * 100.0 for x in xyz] if xyz else None


@dataclass(frozen=True)
class Against:
    """The active version as a version is compared with: its number, its rig, its transform's change to this one
    (per axis in the uncertainty's local axes, deg and cm) and the lengths of that change; ``change`` None when
    the two are of different rigs (``other_rig`` names the active one's)."""

    number: int
    change: list[float] | None
    lengths: tuple[float, float] | None  # rotation deg, translation cm
    other_rig: str | None = None


@dataclass(frozen=True)
class VersionView:
    """A version as the page shows it: its values, change against the active one and sigma per axis
    (roll, pitch, yaw deg; x, y, z cm; the change in the uncertainty's local axes, as ``rigd check``), its
    pairs with overlays, a multi-camera head's sensors (empty for one camera) and its rig."""

    record: VersionOut
    values: list[float]
    against: Against | None
    sigma: list[float | None] | None
    pairs: list[int]
    sensors: list[str]
    rig: RigOut | None = None

    @property
    def change(self) -> list[float] | None:
        return self.against.change if self.against else None

    @property
    def verdict(self) -> str:
        """trusted, weak or failed; ``none`` for a version stored by hand."""
        return self.record.verdict["status"] if self.record.verdict else "none"

    @property
    def activatable(self) -> bool:
        """Whether the page offers to activate it: not a failed result (its own advice says not to use it)."""
        return self.record.status != "active" and self.verdict != "failed"

    @property
    def reasons(self) -> list[str]:
        """Why it is not trusted (what activating it asks the operator to accept), in the page's words."""
        if self.record.verdict is None:
            note = self.record.parameters.get("note")
            return [f"stored by hand ({self.record.method}): it has no verdict, nothing measured its uncertainty"
                    + (f"; note: {note}" if note else "")]
        return [] if self.verdict == "trusted" else [page_words(r) for r in self.record.verdict["reasons"]]

    @property
    def unknown_axes(self) -> list[str]:
        """The axes not known to the tolerance (all six for a manual version: nothing measured them)."""
        return list(self.record.verdict["weak_axes"]) if self.record.verdict else list(AXES)

    @property
    def change_marks(self) -> list[bool]:
        """Per axis, whether the change against the active version stands out against sigma (bold)."""
        return stands_out(self.change, self.sigma) if self.change is not None else []

    @property
    def unmeasured(self) -> bool:
        """Some axis has no sigma (shown as –)."""
        return self.sigma is not None and any(s is None for s in self.sigma)

    @property
    def move_words(self) -> str:
        """How far activating it moves the rig's extrinsics, per axis and in all, for the confirm dialog."""
        if self.against is None or self.against.change is None or self.against.lengths is None:
            return ""
        per_axis = ", ".join(f"{a} {d:+.2f}{unit(a)}" for a, d in zip(AXES, self.against.change, strict=True))
        rotation, translation = self.against.lengths
        return f"{per_axis} (in all {rotation:.2f}° and {translation:.1f} cm) from version {self.against.number}"

    @property
    def method_words(self) -> str:
        """The method by its name, and why it ran (the report's)."""
        method = self.record.quality.get("method") if calibrated(self.record.quality) else None
        name = method_name(self.record.method)
        return f"{name} ({method['why']})" if method and method.get("why") else name

    @property
    def capture_target(self) -> int | None:
        """The pairs in all the advice asks for (its "Capture more pairs" button fills them in)."""
        return capture_target(self._next_steps())

    @property
    def lever_arm_cm(self) -> str:
        """The lever arm this calibration was given, cm, comma separated ("" if none): its button fills it in."""
        given = given_lever_arm_cm(self.record.parameters)
        return ",".join(f"{x:.4g}" for x in given) if given else ""

    def _next_steps(self) -> list[NextStep | str]:
        return list(self.record.verdict.get("next_steps", [])) if self.record.verdict else []

    @property
    def steps(self) -> list[tuple[str, list[tuple[str, str]]]]:
        """The advice's steps in the page's words, each with the page's buttons for it (a button only at its first
        step; the lever arm's says it shows the one given, where one was)."""
        seen: set[str] = set()
        steps = []
        for step in _records(self._next_steps()):
            actions = [(a, CHECK_LEVER_ARM if a == Action.LEVER_ARM.value and self.lever_arm_cm else label)
                       for a, label in advice_actions(step) if a not in seen]
            seen.update(a for a, _ in actions)
            steps.append((page_words(step["text"]), actions))
        return steps


def _against(version: ExtrinsicsVersion, active: ExtrinsicsVersion, rig: RigOut | None,
             active_rig: RigOut | None) -> Against:
    if not same_rig(rig, active_rig):
        assert active_rig is not None
        return Against(active.number, None, None, rig_words(active_rig))
    change = (xi_of(active.T_camera_lidar.tau, version.T_camera_lidar.tau) * TO_DISPLAY).tolist()
    total = change_between(active, version.T_camera_lidar)
    return Against(active.number, change, (total.rotation_deg, total.translation_cm))


def version_view(version: ExtrinsicsVersion, active: ExtrinsicsVersion | None, rig: RigOut | None = None,
                 active_rig: RigOut | None = None) -> VersionView:
    """``version`` beside ``active`` (compared per axis only when both are of one rig: ``rig`` and
    ``active_rig``, None where unknown)."""
    v = version_out(version)
    values = [*v.T_camera_lidar.rpy_deg, *(np.asarray(v.T_camera_lidar.xyz_m) * 100.0)]
    against = None
    if active is not None and version.number != active.number:
        against = _against(version, active, rig, active_rig)
    sigma = [*v.uncertainty["rpy_deg"], *v.uncertainty["xyz_cm"]] if v.uncertainty else None
    pairs = [int(link.rsplit("/", 1)[1].removesuffix(".png")) for link in v.overlays]
    return VersionView(v, [float(x) for x in values], against, sigma, pairs, report_sensors(v.quality), rig)
