"""``POST /calibrate``: queue a calibration of a dataset; 202 with the job."""

from __future__ import annotations

from fastapi import APIRouter, Response, status

from calib.geometry import Transform
from rigd.api.deps import Authorized, ServiceDep
from rigd.api.models import CalibrateIn, ErrorOut, InitMode, JobOut
from rigd.api.routes.jobs import queued_out
from rigd.api.runner import CalibrationPlan, Start
from rigd.api.service import Service
from rigd.errors import RigdError
from rigd.store import ConflictError

router = APIRouter(tags=["calibrate"])


def plan(service: Service, body: CalibrateIn) -> CalibrationPlan:
    """Check the dataset and resolve the initial guess now, so a bad request fails before it is queued."""
    if body.dataset in service.runner.capturing():
        raise ConflictError(f"dataset {body.dataset} is being captured; calibrate it when the capture ends")
    dataset = service.datasets.open(body.dataset)
    if len(dataset) == 0:
        raise RigdError(f"dataset {body.dataset} has no pairs yet")
    initial: Transform | None
    init_version = None
    if body.init is InitMode.ACTIVE:
        active = service.versions.active()
        if active is None:
            raise ConflictError("there is no active extrinsics version yet; start from init 'rig' or a transform")
        initial, init_version, start = active.T_camera_lidar, active.number, Start.ACTIVE
    elif body.init is InitMode.RIG:
        guess = dataset.rig.initial_guess or service.rig.initial_guess
        # no guess in either rig file: the global search finds the start
        initial, start = guess, Start.RIG if guess is not None else Start.SEARCH
    elif body.init is InitMode.SEARCH:
        initial, start = None, Start.SEARCH
    else:
        initial, start = body.init.transform, Start.EXPLICIT
    sigmas = tuple(body.sigmas_deg) if body.sigmas_deg is not None else None
    prior = body.prior.model_dump(exclude_none=True) if body.prior is not None else None
    tolerance = body.tolerance.model_dump() if body.tolerance is not None else None
    return CalibrationPlan(body.dataset, initial, start, init_version, sigmas, body.auto_activate, prior,
                           body.fix_translation, tolerance, body.fit_elevation_offset)


@router.post("/calibrate", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED, dependencies=[Authorized],
             summary="calibrate a dataset in a worker process",
             responses={200: {"model": JobOut, "description": "an identical calibration is queued or running: "
                              "its job (nothing new is queued)"},
                        404: {"model": ErrorOut, "description": "no such dataset"},
                        409: {"model": ErrorOut, "description": "the dataset is being captured, or init 'active' "
                              "without an active version"},
                        422: {"model": ErrorOut, "description": "bad request or unusable dataset"},
                        429: {"model": ErrorOut, "description": "the queue is full; ask again after Retry-After "
                              "seconds"}})
def calibrate(service: ServiceDep, body: CalibrateIn, response: Response) -> JobOut:
    job, new = service.runner.submit_calibration(plan(service, body))
    return queued_out(service, job, new, response)
