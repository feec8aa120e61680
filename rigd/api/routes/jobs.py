"""``/jobs``: captures, calibrations and checks, their progress, logs and results; DELETE cancels."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Query, Response, status

from rigd.api.deps import Authorized, ServiceDep
from rigd.api.models import ErrorOut, JobOut
from rigd.api.service import Service
from rigd.api.wording import public_text
from rigd.dataset import Dataset
from rigd.errors import RigdError
from rigd.results import is_calibration
from rigd.store import ConflictError, Job, JobKind, JobStatus

router = APIRouter(prefix="/jobs", tags=["jobs"])
JobId = Annotated[int, Path(ge=1, le=2**31 - 1)]
LOG_TAIL_LINES = 20


def job_link(job: Job) -> str:
    return f"/jobs/{job.id}"


def job_out(service: Service, job: Job, tail: int = LOG_TAIL_LINES) -> JobOut:
    link = None
    if job.result is not None and is_calibration(job.result):
        link = f"/extrinsics/versions/{job.result['version']}"
    elif job.kind is JobKind.CAPTURE and job.result:
        link = f"/datasets/{job.params['dataset']}"
    return JobOut(
        id=job.id, kind=job.kind.value, status=job.status.value, stage=job.stage, fraction=job.fraction,
        created_at=job.created_at, started_at=job.started_at, finished_at=job.finished_at, params=job.params,
        result=job.result, result_link=link,
        error=None if job.error is None else public_text(job.error, service.datasets.root),
        log_tail=service.jobs.log_tail(job.id, tail),
    )


@router.get("", response_model=list[JobOut], summary="jobs, newest first")
def list_jobs(service: ServiceDep, limit: Annotated[int, Query(ge=1, le=500)] = 50,
              kind: JobKind | None = None, status: JobStatus | None = None) -> list[JobOut]:
    return [job_out(service, job, tail=3) for job in service.jobs.list(limit, kind, status)]


@router.get("/{job_id}", response_model=JobOut, responses={404: {"model": ErrorOut}})
def get_job(service: ServiceDep, job_id: JobId) -> JobOut:
    return job_out(service, service.jobs.get(job_id))


@router.delete("/{job_id}", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED, dependencies=[Authorized],
               summary="cancel a queued or running job",
               responses={404: {"model": ErrorOut}, 409: {"model": ErrorOut, "description": "already finished"}})
def cancel_job(service: ServiceDep, job_id: JobId) -> JobOut:
    return job_out(service, service.runner.cancel(job_id))


def idle_dataset(service: Service, name: str, verb: str) -> Dataset:
    """Dataset ``name`` for a job to ``verb``: one with pairs that no capture is writing into."""
    if name in service.runner.capturing():
        raise ConflictError(f"dataset {name} is being captured; {verb} it when the capture ends")
    dataset = service.datasets.open(name)
    if len(dataset) == 0:
        raise RigdError(f"dataset {name} has no pairs yet")
    return dataset


def queued_out(service: Service, job: Job, new: bool, response: Response) -> JobOut:
    """A job queued by ``POST /calibrate`` or ``POST /check``: 202 if new, 200 for the identical queued or running
    job returned instead; ``Location`` names it either way."""
    if not new:
        response.status_code = status.HTTP_200_OK
    response.headers["Location"] = job_link(job)
    return job_out(service, job)
