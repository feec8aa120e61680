"""A calibration job's result kept: a new extrinsics version with its quality, activated when the request asked
and the quality is within the service's ActivationBounds, and the job's end, in one transaction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from calib.geometry import Transform
from rigd.report import CalibrationReport, StoredQuality, stored_quality, verdict_of
from rigd.results import AutoActivation, CalibrateJobResult
from rigd.store import Change, ExtrinsicsVersion, Job, JobStatus, JobStore, NewVersion, StorageError, VersionStore


@dataclass(frozen=True)
class ActivationBounds:
    """The quality a calibration needs to be activated by ``auto_activate``."""

    require_converged: bool = True
    min_pairs: int = 6
    max_rotation_deg: float = 5.0
    max_translation_cm: float = 10.0

    def failures(self, quality: StoredQuality, pairs: int, change: Change | None) -> list[str]:
        reasons = []
        verdict = verdict_of(quality)
        status = verdict["status"] if verdict else "missing"
        if status != "trusted":  # never activate what the calibration itself does not trust (docs/trust.md)
            reasons.append(f"the calibration's verdict is {status}, not trusted")
        if self.require_converged and not quality["converged"]:
            reasons.append("the optimisation did not converge")
        if pairs < self.min_pairs:
            reasons.append(f"{pairs} pairs, at least {self.min_pairs} needed")
        if change is not None and change.rotation_deg > self.max_rotation_deg:
            reasons.append(f"rotation moved {change.rotation_deg:.2f} deg from version {change.against}, "
                           f"more than {self.max_rotation_deg} deg")
        if change is not None and change.translation_cm > self.max_translation_cm:
            reasons.append(f"translation moved {change.translation_cm:.2f} cm from version {change.against}, "
                           f"more than {self.max_translation_cm} cm")
        return reasons


def _same_rig(params: dict[str, Any], active: ExtrinsicsVersion) -> bool:
    """A version of another rig is not compared with this one."""
    theirs, ours = active.parameters.get("rig"), params.get("rig")
    return theirs is None or ours is None or theirs == ours


def _job_result(version: ExtrinsicsVersion, decision: AutoActivation) -> CalibrateJobResult:
    change = version.change
    return {"version": version.number, "status": version.status.value,
            "change": {"against": change.against, "rotation_deg": change.rotation_deg,
                       "translation_cm": change.translation_cm} if change else None,
            "auto_activate": decision}


class CalibrationRecorder:
    """Stores calibration jobs' results as versions of ``versions`` made by ``code_version``."""

    def __init__(self, jobs: JobStore, versions: VersionStore, bounds: ActivationBounds, code_version: str) -> None:
        self.jobs = jobs
        self.versions = versions
        self.bounds = bounds
        self.code_version = code_version

    def store(self, job: Job, result: dict[str, Any]) -> None:
        """The worker's ``result`` message of ``job`` as a version and the job's end; a result that cannot be
        stored fails the job, naming where its files are."""
        params, pairs = job.params, result["pair_numbers"]
        report: CalibrationReport = result["report"]  # the worker's run_calibration report, through JSON
        quality = stored_quality(report, len(pairs))
        decision: AutoActivation = {"requested": params["auto_activate"]}

        def policy(change: Change | None) -> bool:
            decision["failed_checks"] = self.bounds.failures(quality, len(pairs), change)
            return bool(params["auto_activate"] and not decision["failed_checks"])

        new = NewVersion(
            T_camera_lidar=Transform.from_matrix(np.asarray(result["matrix"])),
            quality=quality,
            method=report["method"]["name"],
            parameters={**params, "pair_numbers": pairs, "change_from_initial": report["change_from_initial"]},
            code_version=self.code_version,
            dataset_id=params["dataset"],
            dataset_hash=result["dataset_hash"],
            job_id=job.id,
        )
        try:  # the version and the job's end in one transaction: a crash leaves both or neither
            version = self.versions.add(new, policy, job_result=lambda v: _job_result(v, decision),
                                        comparable=lambda active: _same_rig(params, active))
        except StorageError as exc:
            self.jobs.finish(job.id, JobStatus.FAILED, "failed", error=f"its result could not be stored: {exc} "
                             f"(its files are in {self.jobs.job_dir(job.id) / 'calibration'})")
            return
        self.jobs.log(job.id, f"stored extrinsics version {version.number} ({version.status.value})")
