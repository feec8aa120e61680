"""Request and response bodies (pydantic). Requests are bounded and reject unknown keys and NaN."""

from __future__ import annotations

from collections.abc import Callable
from enum import Enum
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, PrivateAttr, StrictInt, model_validator

from calib.errors import CalibError
from calib.geometry import Transform
from rigd.dataset.records import lever_arm_problem, transform_to_yaml
from rigd.report import NoQuality, StoredQuality, Uncertainty, Verdict
from rigd.results import CalibrateJobResult, CaptureJobResult, CheckReport
from rigd.store.datasets import DATASET_ID_PATTERN
from rigd.store.jsonsafe import unicode_safe

DatasetId = Annotated[str, Field(pattern=DATASET_ID_PATTERN, examples=["indoor-2025-01-31"])]
Coordinate = Annotated[float, Field(ge=-1e3, le=1e3)]
Angle = Annotated[float, Field(ge=-720.0, le=720.0)]
Vec3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]
Row4 = Annotated[list[Coordinate], Field(min_length=4, max_length=4)]


def _within(low: float, high: float, unit: str, why: str) -> Callable[[float], float]:
    """A check refusing values outside [low, high] with a message naming the range and why it is the range (the
    schema states it too, as minimum and maximum)."""
    def check(value: float) -> float:
        if not low <= value <= high:
            raise ValueError(f"must be within {low:g} .. {high:g} {unit}, got {value:g}: {why}")
        return value
    return check


def _range(low: float, high: float) -> Any:
    return Field(json_schema_extra={"minimum": low, "maximum": high})


# A tolerance or threshold per axis is the error that matters to the application. Below these lower bounds no
# sensor of the rig resolves a difference (a working pixel is 0.18 deg, a VLP-16 step 0.1-0.4 deg, its range
# accurate to 3 cm), and the verdict's arithmetic, which divides by them, breaks down (1e-300 killed the worker).
_TOLERANCE_WHY = "finer than the rig's sensors resolve, or so coarse that any result would pass"
ToleranceDeg = Annotated[float, _range(0.001, 10.0), AfterValidator(_within(0.001, 10.0, "deg", _TOLERANCE_WHY))]
ToleranceCm = Annotated[float, _range(0.01, 100.0), AfterValidator(_within(0.01, 100.0, "cm", _TOLERANCE_WHY))]
# A prior's sigma: how well the rig's drawing knows the lever arm or the mounting angles.
PriorSigmaCm = Annotated[float, _range(0.01, 1000.0), AfterValidator(_within(
    0.01, 1000.0, "cm", "no drawing knows a lever arm better than 0.1 mm, and 10 m is no prior at all"))]
PriorSigmaDeg = Annotated[float, _range(0.001, 180.0), AfterValidator(_within(
    0.001, 180.0, "deg", "no drawing knows a mounting angle better than 0.001 deg, and 180 deg is no prior at all"))]
# sigma_in of a coarse-to-fine level, deg at 1 m: narrower than half a working pixel (0.18 deg) it sees no edge.
SigmaIn = Annotated[float, _range(0.1, 30.0), AfterValidator(_within(
    0.1, 30.0, "deg", "a kernel narrower than half a working pixel (0.18 deg) sees no edge, wider than 30 deg no "
    "alignment"))]


MAX_NESTING = 16  # levels of objects and arrays in a request body; the deepest request needs 4


def body_problem(value: Any) -> str | None:
    """What makes a parsed JSON body unfit before validation, or None: nesting deeper than ``MAX_NESTING``, or
    a string or key holding a lone surrogate. Walked with a stack, not recursion: a 1 KB body can nest
    hundreds of levels deep."""
    stack: list[tuple[Any, str, int]] = [(value, "body", 0)]
    while stack:
        item, where, depth = stack.pop()
        if isinstance(item, str):
            if unicode_safe(item) != item:
                return (f"{where}: text must be Unicode, it holds a lone surrogate (a \\ud800-\\udfff escape "
                        "outside a pair)")
            continue
        if not isinstance(item, dict | list):
            continue
        if depth == MAX_NESTING:
            return (f"{where}: the body is nested more than {MAX_NESTING} levels deep (objects and arrays); "
                    "no request of this API needs that many")
        if isinstance(item, dict):  # a key is checked before its value
            children = [(part, f"{where}.{unicode_safe(str(k))}") for k, v in item.items() for part in (k, v)]
        else:
            children = [(v, f"{where}[{i}]") for i, v in enumerate(item)]
        stack.extend((child, at, depth + 1) for child, at in reversed(children))
    return None


class Request(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _fit(cls, data: Any) -> Any:
        # JSON's "\ud800" parses to a string no UTF-8 can carry: it could be neither stored nor answered. And
        # a deep body would exhaust the recursion of whatever walks it next (validation, the error's echo).
        problem = body_problem(data)
        if problem is not None:
            raise ValueError(problem)
        return data


class TransformIn(Request):
    """T_camera_lidar (p_cam = R p_lidar + t): a 4x4 ``matrix``, or ``rpy_deg`` (deg) with ``xyz_m`` (m)."""

    matrix: Annotated[list[Row4], Field(min_length=4, max_length=4)] | None = None
    rpy_deg: Annotated[list[Angle], Field(min_length=3, max_length=3)] | None = None
    xyz_m: Vec3 | None = None
    _transform: Transform = PrivateAttr()

    @model_validator(mode="after")
    def _to_transform(self) -> TransformIn:
        try:
            if self.matrix is not None and self.rpy_deg is None and self.xyz_m is None:
                self._transform = Transform.from_matrix(self.matrix)  # type: ignore[arg-type]
            elif self.matrix is None and self.rpy_deg is not None and self.xyz_m is not None:
                self._transform = Transform.from_rpy_xyz(self.rpy_deg, self.xyz_m)  # type: ignore[arg-type]
            else:
                raise ValueError("give either matrix, or rpy_deg together with xyz_m")
        except CalibError as exc:
            raise ValueError(str(exc)) from exc
        return self

    @property
    def transform(self) -> Transform:
        return self._transform


class PriorIn(Request):
    """A Gaussian prior per axis from the rig's drawing (rig.yaml's ``prior`` form): the lever arm ``xyz_m``
    (t of T_camera_lidar, m) with ``sigma_cm``, and/or the rotation ``rpy_deg`` with ``sigma_deg``."""

    xyz_m: Vec3 | None = None
    sigma_cm: PriorSigmaCm | None = None
    rpy_deg: Annotated[list[Angle], Field(min_length=3, max_length=3)] | None = None
    sigma_deg: PriorSigmaDeg | None = None

    @model_validator(mode="after")
    def _pairs(self) -> PriorIn:
        if (self.xyz_m is None) != (self.sigma_cm is None):
            raise ValueError("a lever-arm prior needs both xyz_m and sigma_cm")
        if self.xyz_m is not None and (problem := lever_arm_problem(self.xyz_m)) is not None:
            raise ValueError(problem)
        if (self.rpy_deg is None) != (self.sigma_deg is None):
            raise ValueError("a rotation prior needs both rpy_deg and sigma_deg")
        return self


class ToleranceIn(Request):
    """The field tolerance per axis: an axis is known when 2.5 sigma is within it (docs/trust.md)."""

    rotation_deg: ToleranceDeg = Field(default=0.2, description="per rotation axis, deg (0.001 .. 10)")
    translation_cm: ToleranceCm = Field(default=2.0, description="per translation axis, cm (0.01 .. 100)")


class InitMode(Enum):
    """Where a calibration starts, short of an explicit transform (``CalibrateIn.init``)."""

    ACTIVE = "active"  # the active extrinsics version
    RIG = "rig"  # the rig file's initial guess
    SEARCH = "search"  # a global search over the mounts


class CalibrateIn(Request):
    dataset: DatasetId
    init: InitMode | TransformIn = Field(
        InitMode.ACTIVE, description="initial guess: the active extrinsics version, the rig file's (the dataset's "
        "rig.yaml, else the service's rig file; neither has one: the global search), 'search' (a global search, "
        "after a reassembly), or an explicit transform")
    sigmas_deg: Annotated[list[SigmaIn], Field(min_length=1, max_length=6)] | None = (
        Field(None, description="sigma_in per coarse-to-fine level, deg at 1 m; absent: the calibration's default "
              "schedule (the levels used are in the version's quality figures)"))
    auto_activate: bool = Field(False, description="activate the result if its verdict is trusted and its quality "
                                "passes the service's bounds")
    prior: PriorIn | None = Field(None, description="Gaussian prior per axis; absent: the dataset's rig.yaml prior")
    fix_translation: bool = Field(False, description="hold the translation at the prior's lever arm (or the start's)")
    tolerance: ToleranceIn | None = Field(None, description="field tolerance of the verdict; absent: the dataset's "
                                          "rig.yaml tolerance, else 0.2 deg / 2 cm")
    fit_elevation_offset: bool = Field(False, description="also fit the LiDAR's common elevation offset, for "
                                       "cameras that look all round (a panorama or a head); about 1.5 times the time")


class ThresholdIn(Request):
    """The length of a rotation / translation change that matters to a check: rigd check's defaults
    (calib.check.DriftOptions; a test holds them equal), docs/check.md."""

    rotation_deg: ToleranceDeg = Field(default=0.3, description="rotation change, deg (0.001 .. 10)")
    translation_cm: ToleranceCm = Field(default=2.0, description="translation change, cm (0.01 .. 100)")


class CheckIn(Request):
    dataset: DatasetId
    against: Literal["active"] | Annotated[StrictInt, Field(ge=1, le=2**31 - 1)] | TransformIn = Field(
        "active", description="the extrinsics to check: the active version, a version number, or an explicit "
        "transform")
    threshold: ThresholdIn | None = Field(None, description="the change that matters; absent: 0.3 deg / 2 cm")


class ManualVersionIn(Request):
    T_camera_lidar: TransformIn
    note: Annotated[str, Field(max_length=500)] = ""
    activate: bool = False


class TransformOut(BaseModel):
    matrix: list[list[float]]
    quaternion_xyzw: list[float]
    rpy_deg: list[float]
    xyz_m: list[float]

    @classmethod
    def of(cls, transform: Transform) -> TransformOut:
        return cls(**transform_to_yaml(transform))


class ChangeOut(BaseModel):
    against: int = Field(description="the version that was active when this one was made")
    rotation_deg: float
    translation_cm: float


class VersionOut(BaseModel):
    number: int
    status: Literal["candidate", "active", "superseded"]
    created_at: str
    activated_at: str | None
    T_camera_lidar: TransformOut
    verdict: Verdict | None = Field(description="trusted | weak | failed with the weak axes and the reasons "
                                    "(docs/trust.md); null for a manual version")
    uncertainty: Uncertainty | None = Field(description="per-axis sigma (rpy_deg, xyz_cm), 6x6 covariance in "
                                            "deg/cm and the weakest direction; null for a manual version")
    quality: StoredQuality | NoQuality = Field(description="the calibration's quality figures with its pairs used, "
                                               "error vs ground truth, uncertainty, verdict and initial search; "
                                               "{} for a manual version")
    method: str
    parameters: dict[str, Any]
    code_version: str
    dataset_id: str | None
    dataset_hash: str | None
    job_id: int | None
    supersedes: int | None
    change: ChangeOut | None
    overlays: list[str] = Field(description="links to the LiDAR-over-image overlays of each pair")


class JobOut(BaseModel):
    id: int
    kind: Literal["capture", "calibrate", "check"]
    status: Literal["queued", "running", "succeeded", "failed", "cancelled"]
    stage: str
    fraction: float
    created_at: str
    started_at: str | None
    finished_at: str | None
    params: dict[str, Any]
    result: CalibrateJobResult | CheckReport | CaptureJobResult | None = Field(
        description="a finished job's result: the calibration's stored version and its activation, the check's "
        "report (ok | drifted | unknown with the change and its sigma, docs/check.md) or the capture's pairs; "
        "null until the job ends, and for a calibration or check that failed or was cancelled")
    result_link: str | None
    error: str | None
    log_tail: list[str]


class CameraOut(BaseModel):
    model: str
    width: int
    height: int


class DatasetOut(BaseModel):
    id: str
    pair_count: int
    camera: CameraOut | None
    lidar_model: str | None
    initial_guess: TransformOut | None
    has_ground_truth: bool
    capturing: bool
    error: str | None = Field(None, description="why the dataset cannot be read (then camera is null)")


class PairOut(BaseModel):
    number: int
    image: str
    meta: dict[str, Any]


class DatasetDetailOut(DatasetOut):
    pairs: list[PairOut]
    sensors: list[str] = Field(description="a multi-camera head's sensors (a pair's images), empty for one camera")
    ground_truth: TransformOut | None


class LidarStatus(BaseModel):
    source: str
    state: str = Field(description="ok | silent | error | busy (a capture holds it) | simulated | replay | unknown")
    packet_rate_hz: float | None = None
    packets_lost: int | None = None
    pps: str | None = Field(None, description="absent | synchronising | locked | error")
    checked_at: str | None = None
    message: str = ""


class CameraStatus(BaseModel):
    source: str
    present: bool | None = None
    usb_speed: str | None = None
    serial: str | None = None
    warnings: list[str] = []
    checked_at: str | None = None
    message: str = ""


class SensorsOut(BaseModel):
    lidar: LidarStatus
    camera: CameraStatus


class JobBrief(BaseModel):
    id: int
    kind: str
    stage: str
    fraction: float
    link: str


class ActiveBrief(BaseModel):
    version: int
    created_at: str
    link: str


class DiskOut(BaseModel):
    path: str
    free_bytes: int
    total_bytes: int


class StatusOut(BaseModel):
    software_version: str
    started_at: str
    sensors: SensorsOut
    running_jobs: list[JobBrief]
    active_extrinsics: ActiveBrief | None
    data_dir: DiskOut


class ErrorOut(BaseModel):
    detail: str


class CaptureIn(Request):
    """A capture into ``DATA_DIR/datasets/<dataset>``; absent numbers come from the rig file's ``capture:``."""

    dataset: DatasetId | None = Field(None, description="new or existing dataset (continued at its next pair); "
                                      "absent: capture-<UTC time>")
    n: Annotated[int, Field(ge=1, le=200)] | None = Field(None, description="pairs the dataset should hold")
    still_seconds: Annotated[float, Field(gt=0.0, le=60.0)] | None = None
    sweeps: Annotated[int, Field(ge=1, le=50)] | None = None
    min_move: Annotated[float, Field(ge=0.0, le=100.0)] | None = Field(
        None, description="m the rig must move between pairs")
    source: Literal["rig", "sim"] = Field("rig", description="rig: the rig file's sensors; sim: the simulated rig")
