"""``/datasets``: the datasets in the data directory, by id."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Path

from rigd.api.deps import ServiceDep
from rigd.api.models import CameraOut, DatasetDetailOut, DatasetId, DatasetOut, ErrorOut, PairOut, TransformOut
from rigd.api.service import Service
from rigd.dataset import Dataset
from rigd.errors import DatasetError

router = APIRouter(prefix="/datasets", tags=["datasets"])


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
def get_dataset(service: ServiceDep, dataset_id: Annotated[DatasetId, Path()]) -> DatasetDetailOut:
    dataset = service.datasets.open(dataset_id)
    return DatasetDetailOut(
        **_summary(dataset_id, dataset, service.runner.capturing()),
        pairs=[PairOut(number=p.number, image=p.image, meta=p.meta) for p in service.datasets.pairs(dataset)],
        ground_truth=TransformOut.of(dataset.ground_truth) if dataset.ground_truth else None,
    )
