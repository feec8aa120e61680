"""``POST /calibrate``: queue a calibration of a dataset; 202 with the job."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response, status

from calib.geometry import Transform
from rigd.api.deps import Authorized, ServiceDep
from rigd.api.job_runner import CalibrationPlan
from rigd.api.models import CalibrateIn, ErrorOut, InitMode, JobOut, RigOut
from rigd.api.rigs import fits_rig_file, other_rig, rig_record
from rigd.api.routes.jobs import idle_dataset, queued_out
from rigd.api.service import Service
from rigd.calibration.request import CalibrationRequest, Start, TransformIn, resolve
from rigd.dataset import Dataset
from rigd.store import ConflictError

router = APIRouter(tags=["calibrate"])


def _start(service: Service, body: CalibrateIn, dataset: Dataset) -> dict[str, Any]:
    """The request's start from the body's ``init``: the active version resolved now (its number kept; only for a
    dataset of its rig), the rig file's guess (the dataset's, else the service's; neither: the job searches and
    says so)."""
    if body.init is InitMode.ACTIVE:
        active = service.versions.active()
        if active is None:
            raise ConflictError("there is no active extrinsics version yet; start from init 'rig' or a transform")
        # Its extrinsics would put the LiDAR's points anywhere in another camera's image (or nowhere), and the job
        # would fail without saying why.
        if (problem := other_rig(active, service.datasets, body.dataset, dataset)) is not None:
            raise ConflictError(f"the active {problem}: start from the dataset's own guess (init 'rig') or a "
                                "global search (init 'search')")
        return {"start": Start.ACTIVE, "initial": TransformIn.of(active.T_camera_lidar),
                "start_version": active.number}
    if body.init is InitMode.RIG:  # the guess recorded with the job and its version
        guess = dataset.rig.initial_guess or rig_file_guess(service, dataset)
        return {"start": Start.RIG, "initial": None if guess is None else TransformIn.of(guess)}
    if body.init is InitMode.SEARCH:
        return {"start": Start.SEARCH}
    return {"start": Start.GIVEN, "initial": body.init}


def rig_file_guess(service: Service, dataset: Dataset) -> Transform | None:
    """The service's rig file's initial guess for ``dataset``: only when the dataset is of that rig."""
    fits = fits_rig_file(service.rig, RigOut.model_validate(rig_record(dataset)))
    return service.rig.initial_guess if fits else None


def plan(service: Service, body: CalibrateIn) -> CalibrationPlan:
    """The body as the calibration request the worker runs, read against the dataset now, so that a request it
    cannot honour fails before it is queued."""
    dataset = idle_dataset(service, body.dataset, "calibrate")
    request = CalibrationRequest(dataset=dataset.root, options=body.options(), **_start(service, body, dataset))
    resolved = resolve(request, dataset)
    method = {"name": resolved.method_why.choice, "why": resolved.method_why.why}
    return CalibrationPlan(body.dataset, request, body.auto_activate, rig=rig_record(dataset), method=method)


@router.post("/calibrate", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED, dependencies=[Authorized],
             summary="calibrate a dataset in a worker process",
             responses={200: {"model": JobOut, "description": "an identical calibration is queued or running: "
                              "its job (nothing new is queued)"},
                        404: {"model": ErrorOut, "description": "no such dataset"},
                        409: {"model": ErrorOut, "description": "the dataset is being captured, or init 'active' "
                              "without an active version or with one of another rig (camera or LiDAR)"},
                        422: {"model": ErrorOut, "description": "bad request or unusable dataset"},
                        429: {"model": ErrorOut, "description": "the queue is full; ask again after Retry-After "
                              "seconds"}})
def calibrate(service: ServiceDep, body: CalibrateIn, response: Response) -> JobOut:
    job, new = service.runner.submit_calibration(plan(service, body))
    return queued_out(service, job, new, response)
