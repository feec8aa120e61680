"""``GET /status``: sensors, running jobs, the active extrinsics version, free space, software version."""

from __future__ import annotations

import shutil

from fastapi import APIRouter

from rigd.api.deps import ServiceDep
from rigd.api.models import ActiveBrief, DiskOut, JobBrief, SensorsOut, StatusOut
from rigd.report import verdict_of
from rigd.store import ExtrinsicsVersion, JobStatus

router = APIRouter(tags=["status"])


def _active_brief(active: ExtrinsicsVersion) -> ActiveBrief:
    verdict = verdict_of(active.quality)
    return ActiveBrief(version=active.number, created_at=active.created_at,
                       link=f"/extrinsics/versions/{active.number}", verdict=verdict["status"] if verdict else None,
                       weak_axes=list(verdict["weak_axes"]) if verdict else [])


@router.get("/status", response_model=StatusOut)
async def get_status(service: ServiceDep) -> StatusOut:
    # async: served on the event loop without a thread hop; everything here is a cached value or a
    # sub-millisecond SQLite read (WAL readers never wait for the job writing its progress).
    service.db.check()  # a deleted data directory is a 503 naming it, before disk_usage fails on it
    lidar, camera = service.sensors.snapshot()
    running = [j for j in service.jobs.unfinished() if j.status is JobStatus.RUNNING]
    active = service.versions.active()
    disk = shutil.disk_usage(service.data_dir)
    return StatusOut(
        software_version=service.software_version,
        started_at=service.started_at,
        sensors=SensorsOut(lidar=lidar, camera=camera),
        running_jobs=[JobBrief(id=j.id, kind=j.kind.value, stage=j.stage, fraction=j.fraction, link=f"/jobs/{j.id}")
                      for j in running],
        active_extrinsics=_active_brief(active) if active else None,
        data_dir=DiskOut(path=str(service.data_dir), free_bytes=disk.free, total_bytes=disk.total),
    )
