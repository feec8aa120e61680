"""Request and response bodies (pydantic). Requests are bounded and reject unknown keys and NaN."""

from __future__ import annotations

from enum import Enum
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field, StrictInt, model_validator

from calib.geometry import Transform
from calib.methods import FIELD_METHODS
from rigd.calibration.request import Options, Request, ToleranceCm, ToleranceDeg, TransformIn
from rigd.dataset.records import transform_to_yaml
from rigd.report import NoQuality, StatusName, StoredQuality, Uncertainty, Verdict
from rigd.results import CalibrateJobResult, CaptureJobResult, CheckReport
from rigd.store.datasets import DATASET_ID_PATTERN

DatasetId = Annotated[str, Field(pattern=DATASET_ID_PATTERN, examples=["indoor-2025-01-31"])]


class InitMode(Enum):
    """Where a calibration starts, short of an explicit transform (``CalibrateIn.init``)."""

    ACTIVE = "active"  # the active extrinsics version
    RIG = "rig"  # the rig file's initial guess
    SEARCH = "search"  # a global search over the mounts


class CalibrateIn(Options):
    """A calibration of a dataset: where it starts, whether to activate it, and the options rigd calibrate takes."""

    dataset: DatasetId
    init: InitMode | TransformIn = Field(
        InitMode.ACTIVE, description="initial guess: the active extrinsics version, the rig file's (the dataset's "
        "rig.yaml, else the service's rig file; neither has one: the global search, said in the report), 'search' "
        "(a global search, after a reassembly), or an explicit transform")
    auto_activate: bool = Field(False, description="activate the result if its verdict is trusted and its quality "
                                "passes the service's bounds")

    @model_validator(mode="after")
    def _field_method(self) -> CalibrateIn:
        if self.method is not None and self.method not in FIELD_METHODS:
            raise ValueError(f"method {self.method.value} is a research method (rigd evaluate); the service runs "
                             f"{', '.join(m.value for m in FIELD_METHODS)}")
        return self

    def options(self) -> Options:
        """The body's :class:`Options`, as the calibration request carries them."""
        return Options(**{name: getattr(self, name) for name in Options.model_fields})


class ThresholdIn(Request):
    """The length of a rotation / translation change that matters to a check: rigd check's defaults
    (calib.drift.DriftOptions; a test holds them equal), docs/check.md."""

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


class CameraOut(BaseModel):
    model: str
    width: int
    height: int


class RigOut(BaseModel):
    """The rig a calibration's dataset came from: its camera (model and size as on disk) and LiDAR model. Versions
    compare (their change per axis, a start from the active one) only within one rig."""

    camera: CameraOut
    lidar_model: str | None


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
    rig: RigOut | None = Field(None, description="the camera and LiDAR of the dataset it was calibrated on, as "
                               "recorded with the job (null: a manual version, or one stored before rigs were "
                               "recorded)")


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
    verdict: StatusName | None = Field(None, description="its calibration's verdict; null: stored by hand")
    weak_axes: list[str] = Field([], description="the axes its verdict does not know to the tolerance")


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
