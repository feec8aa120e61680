"""Records of the store: immutable extrinsics versions and jobs."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any

from calib.geometry import Transform
from rigd.report import VersionQuality
from rigd.results import JobResult


class VersionStatus(Enum):
    CANDIDATE = "candidate"  # computed, not in use
    ACTIVE = "active"  # the one in use (exactly one once any version exists)
    SUPERSEDED = "superseded"  # was active, replaced by another


@dataclass(frozen=True)
class Change:
    """How a version differs from ``against``, the version that was active when it was stored."""

    against: int
    rotation_deg: float
    translation_cm: float


@dataclass(frozen=True)
class NewVersion:
    """What a caller stores; the store adds number, times, supersedes, change and status."""

    T_camera_lidar: Transform
    quality: VersionQuality
    method: str
    parameters: dict[str, Any]
    code_version: str
    dataset_id: str | None = None
    dataset_hash: str | None = None
    job_id: int | None = None


@dataclass(frozen=True)
class ExtrinsicsVersion:
    number: int
    created_at: str
    T_camera_lidar: Transform
    quality: VersionQuality
    method: str
    parameters: dict[str, Any]
    code_version: str
    dataset_id: str | None
    dataset_hash: str | None
    job_id: int | None
    supersedes: int | None
    change: Change | None
    status: VersionStatus
    activated_at: str | None  # the last time it became active


class JobKind(Enum):
    CAPTURE = "capture"
    CALIBRATE = "calibrate"
    CHECK = "check"  # rigd check: is an extrinsics still right for a dataset? (docs/check.md)


class JobStatus(Enum):
    QUEUED = "queued"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"

    @property
    def finished(self) -> bool:
        return self in (JobStatus.SUCCEEDED, JobStatus.FAILED, JobStatus.CANCELLED)


@dataclass(frozen=True)
class Job:
    """A capture, calibration or check; ``fraction`` in [0, 1] of the work, ``stage`` says what it is doing."""

    id: int
    kind: JobKind
    status: JobStatus
    params: dict[str, Any]
    stage: str
    fraction: float
    created_at: str
    started_at: str | None
    finished_at: str | None
    result: JobResult | None  # by kind: rigd.results
    error: str | None
