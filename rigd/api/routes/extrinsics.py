"""``/extrinsics``: the active version, all versions, activation, exports and overlay images."""

from __future__ import annotations

import pathlib
from dataclasses import asdict
from typing import Annotated, Any

from fastapi import APIRouter, Path, Query, Response, status
from fastapi.responses import FileResponse

from rigd.api.deps import Authorized, ServiceDep
from rigd.api.exports import ExportFormat, download_name, render
from rigd.api.images import FormatQuery, image_response
from rigd.api.models import ChangeOut, ErrorOut, ManualVersionIn, TransformOut, VersionOut
from rigd.api.rigs import recorded_rig
from rigd.api.service import Service
from rigd.exports import MAX_NAME_LENGTH, ROS_NAME_PATTERN
from rigd.report import uncertainty_of, verdict_of
from rigd.store import ExtrinsicsVersion, NewVersion, NotFoundError

router = APIRouter(prefix="/extrinsics", tags=["extrinsics"])

VersionNumber = Annotated[int, Path(ge=1, le=2**31 - 1)]
Format = Annotated[ExportFormat | None, Query(description="export format; absent: the version record (JSON)")]
FrameName = Annotated[str, Query(pattern=ROS_NAME_PATTERN, max_length=MAX_NAME_LENGTH,
                                  description="a frame id: a ROS name (rigd.exports.frame_problem)")]
EXPORTS: dict[int | str, dict[str, Any]] = {
    200: {"content": {"application/yaml": {"schema": {"type": "string"}}},
          "description": "the version record, or its export in the requested format"},
    404: {"model": ErrorOut}}


def version_out(version: ExtrinsicsVersion) -> VersionOut:
    pairs = version.parameters.get("pair_numbers", []) if version.job_id is not None else []
    return VersionOut(
        number=version.number, status=version.status.value, created_at=version.created_at,
        activated_at=version.activated_at, T_camera_lidar=TransformOut.of(version.T_camera_lidar),
        verdict=verdict_of(version.quality), uncertainty=uncertainty_of(version.quality),
        quality=version.quality, method=version.method, parameters=version.parameters,
        code_version=version.code_version, dataset_id=version.dataset_id, dataset_hash=version.dataset_hash,
        job_id=version.job_id, supersedes=version.supersedes,
        change=ChangeOut(**asdict(version.change)) if version.change else None,
        overlays=[f"/extrinsics/versions/{version.number}/overlays/{p}.png" for p in pairs],
        rig=recorded_rig(version),
    )


def _respond(version: ExtrinsicsVersion, fmt: ExportFormat | None, camera_frame: str,
             lidar_frame: str) -> VersionOut | Response:
    if fmt is None:
        return version_out(version)
    body, media_type = render(version, fmt, camera_frame, lidar_frame)
    return Response(body, media_type=media_type, headers={
        "Content-Disposition": f'inline; filename="{download_name(version.number, fmt)}"'})


@router.get("", response_model=VersionOut, responses=EXPORTS, summary="the active version")
def get_active(service: ServiceDep, format: Format = None, camera_frame: FrameName = "camera",
               lidar_frame: FrameName = "velodyne") -> VersionOut | Response:
    active = service.versions.active()
    if active is None:
        raise NotFoundError("there is no extrinsics version yet: calibrate a dataset or POST /extrinsics/versions")
    return _respond(active, format, camera_frame, lidar_frame)


@router.get("/versions", response_model=list[VersionOut], summary="every version, oldest first")
def list_versions(service: ServiceDep) -> list[VersionOut]:
    return [version_out(v) for v in service.versions.list()]


@router.post("/versions", response_model=VersionOut, status_code=status.HTTP_201_CREATED, dependencies=[Authorized],
             summary="store a transform measured or computed elsewhere as a new version")
def add_version(service: ServiceDep, body: ManualVersionIn, response: Response) -> VersionOut:
    new = NewVersion(T_camera_lidar=body.T_camera_lidar.transform, quality={}, method="manual",
                     parameters={"note": body.note}, code_version=service.software_version)
    version = service.versions.add(new, lambda change: body.activate)
    response.headers["Location"] = f"/extrinsics/versions/{version.number}"
    return version_out(version)


@router.get("/versions/{number}", response_model=VersionOut, responses=EXPORTS)
def get_version(service: ServiceDep, number: VersionNumber, format: Format = None,
                camera_frame: FrameName = "camera", lidar_frame: FrameName = "velodyne") -> VersionOut | Response:
    return _respond(service.versions.get(number), format, camera_frame, lidar_frame)


@router.post("/versions/{number}/activate", response_model=VersionOut, dependencies=[Authorized],
             responses={404: {"model": ErrorOut}}, summary="make this version the active one")
def activate(service: ServiceDep, number: VersionNumber) -> VersionOut:
    return version_out(service.versions.activate(number))


def overlay_path(service: Service, version: ExtrinsicsVersion, pair: int, stage: str,
                 sensor: str | None = None) -> pathlib.Path:
    """The overlay file of ``pair`` at ``stage``; a multi-camera head has one per sensor (``sensor``, else the
    first sensor's), its cloud one per pair."""
    pairs = version.parameters.get("pair_numbers", [])
    if version.job_id is None or pair not in pairs:
        raise NotFoundError(f"extrinsics version {version.number} has no overlay of pair {pair}")
    folder = service.jobs.job_dir(version.job_id) / "calibration" / "overlays"
    stem = f"{pairs.index(pair):04d}"
    path = folder / (f"{stem}_{sensor}_{stage}.png" if sensor and stage != "cloud" else f"{stem}_{stage}.png")
    if not path.is_file() and sensor is None and stage != "cloud":
        path = next(iter(sorted(folder.glob(f"{stem}_*_{stage}.png"))), path)
    if not path.is_file():
        raise NotFoundError(f"the overlay of pair {pair} of version {version.number} is missing ({path.name})")
    return path


@router.get("/versions/{number}/overlays/{pair}.png", response_class=FileResponse,
            responses={200: {"content": {"image/png": {}, "image/jpeg": {}},
                             "description": "the LiDAR edge points over the image, coloured by range"},
                       404: {"model": ErrorOut}})
def get_overlay(service: ServiceDep, number: VersionNumber, pair: Annotated[int, Path(ge=0, le=99999)],
                stage: Annotated[str, Query(pattern="^(after|before|closeup|cloud)$",
                                            description="after: with this version; before: with its initial guess; "
                                            "closeup: before | after where the points moved most, enlarged; "
                                            "cloud: the whole cloud from above, coloured from the image with "
                                            "this version")
                                 ] = "after",
                width: Annotated[int | None, Query(ge=64, le=8192, description="at most this wide (px): a smaller "
                                                   "copy for a screen; absent: full resolution")] = None,
                sensor: Annotated[str | None, Query(pattern="^[A-Za-z0-9_-]{1,32}$", description="a multi-camera "
                                                    "head's sensor (absent: its first)")] = None,
                format: FormatQuery = None) -> Response:
    path = overlay_path(service, service.versions.get(number), pair, stage, sensor)
    return image_response(path, width, format, immutable=True)

