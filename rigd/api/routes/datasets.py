"""``/datasets``: the datasets in the data directory, by id."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Path, Query, Response
from fastapi.responses import FileResponse

from rigd.api.deps import ServiceDep
from rigd.api.images import FormatQuery, image_response, pair_cloud_from_above
from rigd.api.models import CameraOut, DatasetDetailOut, DatasetId, DatasetOut, ErrorOut, PairOut, TransformOut
from rigd.api.service import Service
from rigd.dataset import Dataset
from rigd.dataset.records import SINGLE_VIEW
from rigd.errors import DatasetError
from rigd.store import NotFoundError

router = APIRouter(prefix="/datasets", tags=["datasets"])
DatasetPath = Annotated[DatasetId, Path()]
PairNumber = Annotated[int, Path(ge=0, le=99999, description="the pair's folder number (pairs/NNNN)")]
Width = Annotated[int | None, Query(ge=64, le=8192, description="at most this wide (px): a smaller copy for a "
                                    "screen; absent: full resolution")]
PNG = {200: {"content": {"image/png": {}}}, 404: {"model": ErrorOut}, 422: {"model": ErrorOut}}


def _summary(dataset_id: str, dataset: Dataset, capturing: set[str]) -> dict[str, Any]:
    rig = dataset.rig
    return {
        "id": dataset_id,
        "pair_count": len(dataset),
        "camera": CameraOut(model=rig.camera.kind.value, width=rig.camera.width, height=rig.camera.height),
        "lidar_model": rig.lidar_model,
        "initial_guess": TransformOut.of(rig.initial_guess) if rig.initial_guess else None,
        "has_ground_truth": dataset.ground_truth is not None,
        "capturing": dataset_id in capturing,
    }


def dataset_summary(service: Service, dataset_id: str, capturing: set[str]) -> DatasetOut:
    """The summary, or for a dataset that cannot be read one that says why (the list still shows it)."""
    try:
        return DatasetOut(**_summary(dataset_id, service.datasets.open(dataset_id), capturing))
    except DatasetError as exc:
        return DatasetOut(id=dataset_id, pair_count=0, camera=None, lidar_model=None, initial_guess=None,
                          has_ground_truth=False, capturing=dataset_id in capturing, error=str(exc))


@router.get("", response_model=list[DatasetOut])
def list_datasets(service: ServiceDep) -> list[DatasetOut]:
    capturing = service.runner.capturing()
    return [dataset_summary(service, i, capturing) for i in service.datasets.ids()]


@router.get("/{dataset_id}", response_model=DatasetDetailOut,
            responses={404: {"model": ErrorOut}, 422: {"model": ErrorOut, "description": "corrupt dataset"}})
def get_dataset(service: ServiceDep, dataset_id: DatasetPath) -> DatasetDetailOut:
    dataset = service.datasets.open(dataset_id)
    return DatasetDetailOut(
        **_summary(dataset_id, dataset, service.runner.capturing()),
        pairs=[PairOut(number=p.number, image=p.image, meta=p.meta) for p in service.datasets.pairs(dataset)],
        ground_truth=TransformOut.of(dataset.ground_truth) if dataset.ground_truth else None,
        sensors=[] if dataset.views == (SINGLE_VIEW,) else list(dataset.views),
    )


def pair_index(dataset: Dataset, dataset_id: str, number: int) -> int:
    """The index in ``dataset.pair_dirs`` of the pair folder ``number``; NotFoundError if there is none."""
    numbers = [int(folder.name) for folder in dataset.pair_dirs]
    if number not in numbers:
        raise NotFoundError(f"dataset {dataset_id} has no pair {number}")
    return numbers.index(number)


@router.get("/{dataset_id}/pairs/{number}/image", response_class=FileResponse, summary="a captured pair's image",
            responses={200: {"content": {"image/png": {}, "image/jpeg": {}}}, 404: {"model": ErrorOut},
                       422: {"model": ErrorOut}})
def get_pair_image(service: ServiceDep, dataset_id: DatasetPath, number: PairNumber, width: Width = None,
                   sensor: Annotated[str | None, Query(pattern="^[A-Za-z0-9_-]{1,32}$", description="a multi-camera "
                                                       "head's sensor (absent: its first)")] = None,
                   format: FormatQuery = None) -> Response:
    dataset = service.datasets.open(dataset_id)
    index = pair_index(dataset, dataset_id, number)
    view = sensor or dataset.views[0]
    if view not in dataset.views:
        raise NotFoundError(f"dataset {dataset_id} has no sensor {sensor}; its images: {', '.join(dataset.views)}")
    path = dataset.image_path(index, view)
    if not path.is_file():
        raise NotFoundError(f"dataset {dataset_id}: pair {number} has no image {path.name}")
    return image_response(path, width, format)  # as captured (PNG or JPEG), or narrowed


@router.get("/{dataset_id}/pairs/{number}/cloud.png", response_class=Response, responses=PNG,  # type: ignore[arg-type]
            summary="a captured pair's cloud from above, coloured from its images with the initial guess")
def get_pair_cloud(service: ServiceDep, dataset_id: DatasetPath, number: PairNumber, width: Width = None) -> Response:
    dataset = service.datasets.open(dataset_id)
    return Response(pair_cloud_from_above(dataset, pair_index(dataset, dataset_id, number), width),
                    media_type="image/png")
