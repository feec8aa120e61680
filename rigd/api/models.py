"""Request and response bodies (pydantic). Requests are bounded and reject unknown keys and NaN."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, StrictInt, model_validator

from calib.errors import CalibError
from calib.geometry import Transform
from rigd.dataset.records import transform_to_yaml
from rigd.store.datasets import DATASET_ID_PATTERN
from rigd.store.jsonsafe import unicode_safe

DatasetId = Annotated[str, Field(pattern=DATASET_ID_PATTERN, examples=["indoor-2025-01-31"])]
Coordinate = Annotated[float, Field(ge=-1e3, le=1e3)]
Angle = Annotated[float, Field(ge=-720.0, le=720.0)]
Vec3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]
Row4 = Annotated[list[Coordinate], Field(min_length=4, max_length=4)]


def lone_surrogate(value: Any, where: str = "body") -> str | None:
    """Where in a parsed JSON value a string or key holds a lone surrogate, or None."""
    if isinstance(value, str):
        return where if unicode_safe(value) != value else None
    if isinstance(value, dict):
        named = [(f"{where}.{unicode_safe(str(k))}", (k, v)) for k, v in value.items()]
    elif isinstance(value, list):
        named = [(f"{where}[{i}]", (v,)) for i, v in enumerate(value)]
    else:
        return None
    found = (lone_surrogate(part, at) for at, parts in named for part in parts)
    return next((at for at in found if at is not None), None)


class Request(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _unicode_only(cls, data: Any) -> Any:
        # JSON's "\ud800" parses to a string no UTF-8 can carry: it could be neither stored nor answered.
        where = lone_surrogate(data)
        if where is not None:
            raise ValueError(f"{where}: text must be Unicode, it holds a lone surrogate (a \\ud800-\\udfff escape "
                             "outside a pair)")
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
    sigma_cm: Annotated[float, Field(gt=0.0, le=1000.0)] | None = None
    rpy_deg: Annotated[list[Angle], Field(min_length=3, max_length=3)] | None = None
    sigma_deg: Annotated[float, Field(gt=0.0, le=180.0)] | None = None

    @model_validator(mode="after")
    def _pairs(self) -> PriorIn:
        if (self.xyz_m is None) != (self.sigma_cm is None):
            raise ValueError("a lever-arm prior needs both xyz_m and sigma_cm")
        if (self.rpy_deg is None) != (self.sigma_deg is None):
            raise ValueError("a rotation prior needs both rpy_deg and sigma_deg")
        return self


class ToleranceIn(Request):
    rotation_deg: Annotated[float, Field(gt=0.0, le=90.0)] = 0.2
    translation_cm: Annotated[float, Field(gt=0.0, le=1000.0)] = 2.0


class CalibrateIn(Request):
    dataset: DatasetId
    init: Literal["active", "rig", "search"] | TransformIn = Field(
        "active", description="initial guess: the active extrinsics version, the rig file's (the dataset's "
        "rig.yaml, else the service's rig file; neither has one: the global search), 'search' (a global search, "
        "after a reassembly), or an explicit transform")
    sigmas_deg: Annotated[list[Annotated[float, Field(gt=0.0, le=30.0)]], Field(min_length=1, max_length=6)] | None = (
        Field(None, description="sigma_in per coarse-to-fine level, deg at 1 m; absent: the calibration's default "
              "schedule (the levels used are in the version's quality figures)"))
    auto_activate: bool = Field(False, description="activate the result if its verdict is trusted and its quality "
                                "passes the service's bounds")
    prior: PriorIn | None = Field(None, description="Gaussian prior per axis; absent: the dataset's rig.yaml prior")
    fix_translation: bool = Field(False, description="hold the translation at the prior's lever arm (or the start's)")
    tolerance: ToleranceIn | None = Field(None, description="field tolerance of the verdict; absent: the dataset's "
                                          "rig.yaml tolerance, else 0.2 deg / 2 cm")


class ThresholdIn(ToleranceIn):
    """The change per axis that matters to a check (default the field tolerance, 0.2 deg / 2 cm)."""


class CheckIn(Request):
    dataset: DatasetId
    against: Literal["active"] | Annotated[StrictInt, Field(ge=1, le=2**31 - 1)] | TransformIn = Field(
        "active", description="the extrinsics to check: the active version, a version number, or an explicit "
        "transform")
    threshold: ThresholdIn | None = Field(None, description="change per axis that matters; absent: 0.2 deg / 2 cm")


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
    verdict: dict[str, Any] | None = Field(description="trusted | weak | failed with the weak axes and the reasons "
                                           "(docs/trust.md); null for a manual version")
    uncertainty: dict[str, Any] | None = Field(description="per-axis sigma (rpy_deg, xyz_cm), 6x6 covariance in "
                                               "deg/cm and the weakest direction; null for a manual version")
    quality: dict[str, Any]
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
    result: dict[str, Any] | None
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
