"""``POST /check``: queue a check of extrinsics against a dataset's pairs (docs/check.md); 202 with the job."""

from __future__ import annotations

from fastapi import APIRouter, Response, status

from rigd.api.deps import Authorized, ServiceDep
from rigd.api.job_runner import CheckPlan
from rigd.api.models import CheckIn, ErrorOut, JobOut, ThresholdIn
from rigd.api.rigs import other_rig
from rigd.api.routes.jobs import idle_dataset, queued_out
from rigd.api.service import Service
from rigd.store import ConflictError

router = APIRouter(tags=["check"])


def plan(service: Service, body: CheckIn) -> CheckPlan:
    """Check the dataset and resolve the extrinsics now, so a bad request fails before it is queued."""
    dataset = idle_dataset(service, body.dataset, "check")
    if body.against == "active":
        active = service.versions.active()
        if active is None:
            raise ConflictError("there is no active extrinsics version yet; check a version number or a transform")
        checked, against, number = active.T_camera_lidar, "active", active.number
    elif isinstance(body.against, int):
        checked, against, number = service.versions.get(body.against).T_camera_lidar, "version", body.against
    else:
        checked, against, number = body.against.transform, "explicit", None
    version = service.versions.get(number) if number is not None else None
    if version is not None and (problem := other_rig(version, service.datasets, body.dataset, dataset)) is not None:
        raise ConflictError(f"{problem}: its extrinsics say nothing of this rig; calibrate dataset {body.dataset} "
                            "instead")
    threshold = (body.threshold or ThresholdIn()).model_dump()
    return CheckPlan(body.dataset, checked, against, number, threshold)


@router.post("/check", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED, dependencies=[Authorized],
             summary="check extrinsics against a dataset's pairs (ok, drifted or unknown) in the worker process",
             responses={200: {"model": JobOut, "description": "an identical check is queued or running: its job "
                              "(nothing new is queued)"},
                        404: {"model": ErrorOut, "description": "no such dataset or extrinsics version"},
                        409: {"model": ErrorOut, "description": "the dataset is being captured, against 'active' "
                              "without an active version, or a version of another rig (camera or LiDAR)"},
                        422: {"model": ErrorOut, "description": "bad request or unusable dataset"},
                        429: {"model": ErrorOut, "description": "the queue is full; ask again after Retry-After "
                              "seconds"}})
def check(service: ServiceDep, body: CheckIn, response: Response) -> JobOut:
    job, new = service.runner.submit_check(plan(service, body))
    return queued_out(service, job, new, response)
