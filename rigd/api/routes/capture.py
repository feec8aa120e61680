"""``POST /capture``: capture pairs into a dataset in a thread of the service; 202 with the job, 409 while
another capture holds the sensors."""

from __future__ import annotations

import threading
from collections.abc import Callable
from datetime import UTC, datetime

from fastapi import APIRouter, Response, status

from rigd.api.deps import Authorized, ServiceDep
from rigd.api.models import CameraStatus, CaptureIn, ErrorOut, JobOut, LidarStatus
from rigd.api.routes.jobs import job_link, job_out
from rigd.api.service import Service
from rigd.capture import CaptureRequest, CaptureStatus, run_capture
from rigd.capture.engine import existing_pairs
from rigd.results import CaptureJobResult
from rigd.store import Job
from rigd.store.db import utc_now

router = APIRouter(tags=["capture"])


def capture_request(service: Service, body: CaptureIn, dataset_id: str) -> CaptureRequest:
    rig = service.rig
    defaults = rig.capture
    sim = body.source == "sim"
    return CaptureRequest(
        out=service.datasets.path(dataset_id),
        n=body.n or defaults.n,
        lidar="sim" if sim else rig.lidar_source,
        camera="sim" if sim else rig.camera_source,
        still_seconds=body.still_seconds or defaults.still_seconds,
        sweeps=body.sweeps or defaults.sweeps,
        min_move=body.min_move if body.min_move is not None else defaults.min_move,
        silence_timeout_s=defaults.silence_timeout_s,
        config=service.settings.config,
    )


def capture_sensors(request: CaptureRequest, job: Job, s: CaptureStatus) -> tuple[LidarStatus, CameraStatus]:
    """The sensors as a running capture sees them: its LiDAR figures, and its camera delivering frames (a
    simulated one has no USB device the probe could find: it would read "absent")."""
    now = utc_now()
    lidar = LidarStatus(source=request.lidar, state="busy", packet_rate_hz=s.packet_rate_hz,
                        packets_lost=s.packets_lost, checked_at=now,
                        message=f"in use by capture job {job.id}; still for {s.still_for_s:.1f} s")
    simulated = request.camera.startswith("sim")
    camera = CameraStatus(source=request.camera, present=None if simulated else True, checked_at=now,
                          message=f"in use by capture job {job.id}: {s.pairs_done} of {s.pairs_wanted} pairs taken"
                          + (" from the simulated rig" if simulated else ""))
    return lidar, camera


def capture_work(service: Service, request: CaptureRequest) -> Callable[[Job, threading.Event], CaptureJobResult]:
    """The job body run by the runner's capture thread: progress into the job and into GET /status."""

    def work(job: Job, stop: threading.Event) -> CaptureJobResult:
        last_state = ""

        def progress(s: CaptureStatus) -> None:
            nonlocal last_state
            # the stage in rigd capture's words ("hold still 1.2 s"); the state's name goes to the log
            words = s.message or s.state.replace("_", " ")
            service.jobs.progress(job.id, f"{s.pairs_done}/{s.pairs_wanted} pairs: {words}",
                                  s.pairs_done / max(s.pairs_wanted, 1))
            if s.state != last_state:
                service.jobs.log(job.id, f"{s.state}: {s.message}" if s.message else s.state)
                last_state = s.state
            service.capture_figures.set(capture_sensors(request, job, s))

        with service.sensors.lidar_lock:  # waits for a running sensor probe to release the LiDAR port
            try:
                summary = run_capture(request, progress, stop)
            finally:
                service.capture_figures.set(None)
        return {"dataset": request.out.name, "pairs_written": len(summary.pairs),
                "pairs_in_dataset": len(existing_pairs(request.out)),
                "seconds_per_pair": list(summary.seconds_per_pair)}

    return work


@router.post("/capture", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED, dependencies=[Authorized],
             summary="capture still camera/LiDAR pairs into a dataset",
             responses={409: {"model": ErrorOut, "description": "the sensors are in use by another capture"},
                        422: {"model": ErrorOut, "description": "bad request or rig file"}})
def capture(service: ServiceDep, body: CaptureIn, response: Response) -> JobOut:
    dataset_id = body.dataset or datetime.now(UTC).strftime("capture-%Y%m%d-%H%M%S")
    request = capture_request(service, body, dataset_id)
    params = {"n": request.n, "still_seconds": request.still_seconds, "sweeps": request.sweeps,
              "min_move": request.min_move, "lidar": request.lidar, "camera": request.camera, "source": body.source}
    job = service.runner.submit_capture(dataset_id, params, capture_work(service, request))
    response.headers["Location"] = job_link(job)
    return job_out(service, job)
