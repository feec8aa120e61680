"""The calibration report as typed records: one TypedDict per section of ``extrinsics.yaml``.

Built in one place (rigd/calibration/sections.py), read everywhere (the CLI's printers, the demo, the store,
the API's models and the operator page). TypedDicts, as rosbags types its YAML metadata, because the report
*is* its YAML and JSON: the records are the very dicts that are written, sent by the worker and stored, so the
file's and the API's shape cannot drift from the types, and pydantic turns the same records into the API's
OpenAPI schema (rigd/api/models.py). typing_extensions' TypedDict: pydantic needs it before Python 3.12.

Every record keeps keys it does not name when the API reads a stored version (``extra="allow"``): a version
stored by another release answers with all it holds. Floats that can be non-finite are ``float | None``: JSON
has no infinity (rigd.store.jsonsafe turns it into null).
"""

from __future__ import annotations

from typing import Literal, NotRequired

from pydantic import ConfigDict, with_config
from typing_extensions import TypedDict, TypeIs

_OPEN = ConfigDict(extra="allow")

# calib.assess.Status by value (the YAML holds the text; tests/rigd/test_report.py checks the two agree).
StatusName = Literal["trusted", "weak", "failed", "not_assessed"]


@with_config(_OPEN)
class TransformYaml(TypedDict):
    """T_camera_lidar in the project's YAML form (rigd.dataset.records.transform_to_yaml)."""

    matrix: list[list[float]]
    quaternion_xyzw: list[float]
    rpy_deg: list[float]
    xyz_m: list[float]


@with_config(_OPEN)
class Level(TypedDict):
    """One coarse-to-fine level of the solve."""

    sigma_in_deg: float
    iterations: int
    converged: bool
    final_cost: float | None


@with_config(_OPEN)
class PairQuality(TypedDict):
    """A pair's edges: image pixels (a head's summed over its sensors) and LiDAR points; for a photometric method,
    the LiDAR points it compares with the image instead."""

    edge_pixels: int
    edge_points: int
    edge_pixels_per_sensor: NotRequired[dict[str, int]]  # a multi-camera head only
    compared_points: NotRequired[int]  # a photometric method: the cloud's points with reflectivity


@with_config(_OPEN)
class Quality(TypedDict):
    """How the solve went (``quality``)."""

    final_cost: float | None
    converged: bool
    levels: list[Level]
    pairs: list[PairQuality]
    # NotRequired: versions stored by earlier releases lack them
    guess_prior_sigma_cm: NotRequired[float | None]  # the guess's lever arm as a weak prior of the solve
    wall_time_s: float
    image_size_px: NotRequired[list[int]]  # as solved on (rigd.dataset.working)
    source_image_size_px: NotRequired[list[int]]  # as on disk


@with_config(_OPEN)
class Change(TypedDict):
    """How far the result is from a pose: ``change_from_initial``."""

    rotation_deg: float
    translation_cm: float


@with_config(_OPEN)
class GroundTruthError(Change):
    """The result against a simulated dataset's ground truth (``error_vs_ground_truth``)."""

    rpy_deg: list[float]
    xyz_cm: list[float]
    local_deg_cm: list[float]  # in the uncertainty's axes (rotation about the LiDAR's x, y, z: docs/trust.md)


@with_config(_OPEN)
class ReferenceAgreement(Change):
    """The result against a real dataset's published calibration (``agreement_with_reference``)."""

    z_per_axis: dict[str, float | None]  # difference in the reference's sigmas; None: it has none
    within_2_5_sigma_0_6_deg_10_cm: bool


@with_config(_OPEN)
class Sigmas(TypedDict):
    """Sigma per axis: roll, pitch, yaw (deg) and x, y, z (cm); None where unknown."""

    rpy_deg: list[float | None]
    xyz_cm: list[float | None]


@with_config(_OPEN)
class Laplace(Sigmas):
    nll_scale: float


@with_config(_OPEN)
class Jackknife(Sigmas):
    groups: int
    # pairs the pose rests on: without any one, the others' edges do not hold it (calib.assess.Uncertainty)
    held_by_pairs: NotRequired[list[int]]


@with_config(_OPEN)
class Restart(TypedDict):
    offset_rpy_deg: list[float | None]
    offset_xyz_cm: list[float | None]
    delta_nll: float | None


@with_config(_OPEN)
class Uncertainty(Sigmas):
    """Per-axis sigma, the 6x6 covariance in deg/cm and the weakest direction (docs/trust.md); a method without
    an assessment has unknown sigmas and none of the rest."""

    covariance: list[list[float | None]] | None
    weakest: str
    laplace: NotRequired[Laplace]
    jackknife: NotRequired[Jackknife | None]
    jackknife_rings: NotRequired[Jackknife | None]  # each ring of the LiDAR left out in turn (groups: rings)
    restart_spread: NotRequired[Sigmas | None]  # RMS of the restarts' offsets (nid-assessed; docs/trust.md)
    camera_model: NotRequired[Sigmas | None]  # the declared principal-point sigma as rotations (docs/trust.md)
    lidar_elevation: NotRequired[Sigmas | None]  # the fitted elevation offset's sigma, as the pose moves with it
    # nid-assessed: the GMM's edges refined from NID's answer, their move / sqrt(2) (docs/trust.md)
    cross_check: NotRequired[Sigmas | None]
    matched_share: NotRequired[float | None]
    restarts: NotRequired[list[Restart]]


@with_config(_OPEN)
class NextStep(TypedDict):
    """One thing to do next (rigd.calibration.advice.Step): its words, the actions it asks for
    (rigd.calibration.advice.Action's values), the axes it is about, and for a capture the pairs to have in all."""

    text: str
    actions: list[str]
    axes: list[str]
    pairs: int | None


@with_config(_OPEN)
class Verdict(TypedDict):
    """trusted | weak | failed (| not_assessed) with the weak axes, the reasons and what to do next."""

    status: StatusName
    weak_axes: list[str]
    reasons: list[str]
    fixed_axes: NotRequired[list[str]]  # held at the values given: reported as given, never vouched for
    next_steps: NotRequired[list[NextStep | str]]  # rigd.calibration.advice (words alone in older reports)
    moved_from_start_deg: NotRequired[float | None]


@with_config(_OPEN)
class SearchGrid(TypedDict):
    mounts: int
    scores: list[str]
    sigma_deg: float
    yaw_range_deg: float
    yaw_step_deg: float
    tilt_deg: float
    tilt_step_deg: float


@with_config(_OPEN)
class SearchStart(TypedDict):
    grid_rpy_deg: list[float]
    rpy_deg: list[float]
    xyz_m: list[float]


@with_config(_OPEN)
class SearchCandidate(TypedDict):
    grid_rpy_deg: list[float]
    rpy_deg: list[float]
    cost: float | None
    grid_rank: int
    score: str  # edges | mutual information: costs compare within one score only
    from_start_deg: float


@with_config(_OPEN)
class InitialSearch(TypedDict):
    """Which grid mount the global search started from and where the runners-up ended (``initial_search``)."""

    grid: SearchGrid
    start: SearchStart
    candidates: list[SearchCandidate]
    wall_time_s: float


@with_config(_OPEN)
class PhotometricSettings(TypedDict):
    cost: str
    blur_deg: list[float]
    bins: int


@with_config(_OPEN)
class MethodSettings(TypedDict):
    name: str  # calib.methods.Method's value
    why: NotRequired[str]  # why this method (asked for, or the dataset's default and its reason)
    sigmas_deg: NotRequired[list[float]]  # the GMM's schedule
    photometric: NotRequired[PhotometricSettings]


@with_config(_OPEN)
class Places(TypedDict):
    """Where the pairs were taken (rigd.dataset.places): how many places, and the place of each pair."""

    count: int
    of_pairs: list[int]


@with_config(_OPEN)
class StartYaml(TypedDict):
    """Where the solve started (rigd.calibration.request.Start's value) and why."""

    source: str
    choice: str
    why: str
    version: NotRequired[int]  # started from this active extrinsics version


@with_config(_OPEN)
class PriorYaml(TypedDict, total=False):
    """rig.yaml's ``prior`` form (rigd.dataset.records.prior_to_yaml)."""

    xyz_m: list[float]
    sigma_cm: list[float]
    rpy_deg: list[float]
    sigma_deg: list[float]
    fix_translation: bool


@with_config(_OPEN)
class Tolerance(TypedDict):
    """The verdict's field tolerance: per rotation and translation axis, and each axis's (roll, pitch, yaw deg;
    x, y, z cm) as the verdict judged it."""

    rotation_deg: float
    translation_cm: float
    per_axis: NotRequired[list[float]]


class ElevationOffset(TypedDict):
    """The LiDAR's common elevation offset fitted with the pose (calib.elevation): the profile of the finest
    level's cost over the grid, its vertex and jackknife sigma."""

    offset_deg: float  # as rig.yaml's lidar.elevation_offset_deg would declare it
    declared_deg: float  # rig.yaml's, which the clouds were loaded with (the grid lies around it)
    sigma_deg: float  # the larger of the two jackknives'
    sigma_places_deg: float
    sigma_rings_deg: float
    at_bound: bool
    grid_deg: list[float]
    cost: list[float]


class CalibrationReport(TypedDict):
    """``extrinsics.yaml``, ``rigd calibrate --json`` and the worker's result, section by section."""

    T_camera_lidar: TransformYaml
    quality: Quality
    change_from_initial: Change
    dataset: str
    places: NotRequired[Places]
    error_vs_ground_truth: NotRequired[GroundTruthError]  # simulated datasets
    agreement_with_reference: NotRequired[ReferenceAgreement]  # imported datasets with a reference.yaml
    uncertainty: Uncertainty
    verdict: Verdict
    initial_search: NotRequired[InitialSearch]  # started by the global search
    lidar_elevation_offset: NotRequired[ElevationOffset]  # fitted with the pose (--fit-elevation-offset)
    method: MethodSettings
    start: NotRequired[StartYaml]
    prior: NotRequired[PriorYaml]
    tolerance: Tolerance


class Assessed(TypedDict):
    """The ``uncertainty`` and ``verdict`` sections together."""

    uncertainty: Uncertainty
    verdict: Verdict


@with_config(_OPEN)
class StoredQuality(Quality):
    """An extrinsics version's ``quality`` from a calibration: the report's, the pairs used and the report's
    sections the service shows with it (rigd/api/calibration_result.py)."""

    pairs_used: int
    error_vs_ground_truth: NotRequired[GroundTruthError]
    uncertainty: NotRequired[Uncertainty]
    verdict: NotRequired[Verdict]
    initial_search: NotRequired[InitialSearch]
    method: NotRequired[MethodSettings]
    start: NotRequired[StartYaml]


@with_config(ConfigDict(extra="forbid"))
class NoQuality(TypedDict):
    """A version stored by hand: nothing was measured (``{}``)."""


class _Shown(TypedDict, total=False):
    """The report's sections a version's ``quality`` shows, in its order."""

    error_vs_ground_truth: GroundTruthError
    uncertainty: Uncertainty
    verdict: Verdict
    initial_search: InitialSearch
    method: MethodSettings
    start: StartYaml


def stored_quality(report: CalibrationReport, pairs_used: int) -> StoredQuality:
    """The ``quality`` a calibration's version stores: the report's, the pairs used, then what the service
    shows with it."""
    shown: _Shown = {"uncertainty": report["uncertainty"], "verdict": report["verdict"]}
    if "error_vs_ground_truth" in report:
        shown = {"error_vs_ground_truth": report["error_vs_ground_truth"], **shown}
    if "initial_search" in report:
        shown["initial_search"] = report["initial_search"]
    shown["method"] = report["method"]
    if "start" in report:
        shown["start"] = report["start"]
    return {**report["quality"], "pairs_used": pairs_used, **shown}


VersionQuality = StoredQuality | NoQuality


def calibrated(quality: VersionQuality) -> TypeIs[StoredQuality]:
    """Whether a version's ``quality`` is a calibration's (one stored by hand has none: ``{}``)."""
    return bool(quality)


def verdict_of(quality: VersionQuality) -> Verdict | None:
    """A version's verdict; None for a version stored by hand."""
    return quality.get("verdict") if calibrated(quality) else None


def uncertainty_of(quality: VersionQuality) -> Uncertainty | None:
    """A version's per-axis uncertainty; None for a version stored by hand."""
    return quality.get("uncertainty") if calibrated(quality) else None
