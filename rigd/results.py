"""What a finished job leaves as its ``result``, as typed records: a calibrate job's stored version, a check's
report (``rigd check --json``) and a capture's pairs.

TypedDicts, as the calibration report of rigd/report.py and for the same reasons: the records are the very
dicts that are stored and answered, and pydantic turns them into the schema of ``JobOut.result``
(rigd/api/models.py). Built in rigd/api/calibration_result.py (calibrate), rigd/calibration/check_job.py (check) and
rigd/api/routes/capture.py (capture).

Every record keeps keys it does not name when the API reads a stored job (``extra="allow"``), and a key an
earlier release did not store is ``NotRequired``. The fields are in the order the producers write them:
pydantic answers a TypedDict's keys in its fields' order.
"""

from __future__ import annotations

from typing import Literal, NotRequired

from pydantic import ConfigDict, with_config
from typing_extensions import TypedDict, TypeIs

from rigd.report import Sigmas, TransformYaml

_OPEN = ConfigDict(extra="allow")

# calib.drift.DriftStatus by value (tests/rigd/api/test_job_results.py checks the two agree).
CheckStatus = Literal["ok", "drifted", "unknown"]
# rigd.store.VersionStatus by value (the same test).
VersionStatusName = Literal["candidate", "active", "superseded"]


@with_config(_OPEN)
class VersionChange(TypedDict):
    """How a stored version differs from the version that was active when it was stored (rigd.store.Change)."""

    against: int
    rotation_deg: float
    translation_cm: float


@with_config(_OPEN)
class AutoActivation(TypedDict):
    """Whether the request asked to activate the result, and the activation bounds it failed (none: it was
    activated). Absent when the bounds were not consulted: the first trusted version is activated anyway."""

    requested: bool
    failed_checks: NotRequired[list[str]]


@with_config(_OPEN)
class CalibrateJobResult(TypedDict):
    """A calibrate job's result: the extrinsics version it stored (``result_link`` names it)."""

    version: int
    status: VersionStatusName  # the version's status when it was stored
    change: VersionChange | None  # None: no version was active
    auto_activate: AutoActivation


@with_config(_OPEN)
class ChangePerAxis(TypedDict):
    """A change per axis: roll, pitch, yaw (deg) and x, y, z (cm)."""

    rpy_deg: list[float]
    xyz_cm: list[float]


@with_config(_OPEN)
class GroupYaml(TypedDict):
    """One group's change as a length (deg for rotation, cm for translation): ``length`` measured, ``upper`` the
    largest the pairs allow at the ok confidence, ``t2`` Hotelling's T² of the change and ``t2_limit`` beyond
    which it is real."""

    length: float
    upper: float
    threshold: float
    t2: float
    t2_limit: float


@with_config(_OPEN)
class CheckThresholds(TypedDict):
    rotation_deg: float
    translation_cm: float


@with_config(_OPEN)
class CheckConfidence(TypedDict):
    ok: float
    drifted: float


@with_config(_OPEN)
class CheckReport(TypedDict):
    """``rigd check --json`` and a check job's result (docs/check.md, "Output")."""

    status: CheckStatus
    axes: list[str]  # the drifted axes, or those the pairs cannot tell
    reasons: list[str]
    change: ChangePerAxis
    sigma: Sigmas  # None where the uncertainty could not be measured
    # NotRequired: checks stored by earlier releases lack them
    groups: NotRequired[dict[str, GroupYaml]]  # "rotation", "translation"; empty when no group could be judged
    places: NotRequired[int]
    thresholds: CheckThresholds
    confidence: NotRequired[CheckConfidence]
    checked: TransformYaml
    found: TransformYaml
    dataset: str
    pairs: int
    wall_time_s: float


@with_config(_OPEN)
class CaptureJobResult(TypedDict):
    """A capture job's result, also of one cancelled or interrupted with pairs written (``result_link`` names
    the dataset)."""

    dataset: str
    pairs_written: int
    pairs_in_dataset: int
    seconds_per_pair: list[float]


# Their required keys tell the three apart: only a calibration's has ``version``, only a check's ``axes``, only
# a capture's ``pairs_written``.
JobResult = CalibrateJobResult | CheckReport | CaptureJobResult


def is_calibration(result: JobResult) -> TypeIs[CalibrateJobResult]:
    return "version" in result


def is_check(result: JobResult) -> TypeIs[CheckReport]:
    return "axes" in result


def is_capture(result: JobResult) -> TypeIs[CaptureJobResult]:
    return "pairs_written" in result
