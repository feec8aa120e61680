"""Which rig a dataset or a version is of: its camera (model, size on disk) and its LiDAR model.

A version's extrinsics mean something only for the rig it was calibrated on: a panorama's T_camera_lidar as the
start of a pinhole's calibration puts no LiDAR point into the image, and two rigs' versions differ by whatever
their mounts differ by. So a start from the active version, and a change against it, are offered only within
one rig. A calibration records its dataset's rig with its job (and so with its version); a version stored
before that is read from its dataset, when that is still there.
"""

from __future__ import annotations

from typing import Any

from rigd.api.models import CameraOut, RigOut
from rigd.capture.config import RigSettings
from rigd.dataset import Dataset
from rigd.dataset.records import CameraKind
from rigd.errors import DatasetError
from rigd.store import ExtrinsicsVersion, NotFoundError
from rigd.store.datasets import DatasetCatalog


def rig_record(dataset: Dataset) -> dict[str, Any]:
    """``dataset``'s rig as the job's params record it (:class:`RigOut`'s form)."""
    rig = dataset.rig
    return {"camera": {"model": rig.camera.kind.value, "width": rig.camera.width, "height": rig.camera.height},
            "lidar_model": rig.lidar_model}


def recorded_rig(version: ExtrinsicsVersion) -> RigOut | None:
    """The rig recorded with a calibration's version; None for a manual one or one stored before rigs were."""
    rig = version.parameters.get("rig")
    return RigOut.model_validate(rig) if isinstance(rig, dict) else None


def version_rig(version: ExtrinsicsVersion, datasets: DatasetCatalog) -> RigOut | None:
    """The version's rig: recorded, else its dataset's as it is now (None: manual, or its dataset is gone)."""
    if (recorded := recorded_rig(version)) is not None or version.dataset_id is None:
        return recorded
    try:
        return RigOut.model_validate(rig_record(datasets.open(version.dataset_id)))
    except (DatasetError, NotFoundError):  # removed or unreadable since: nothing to compare with
        return None


def rig_words(rig: RigOut) -> str:
    """``equirectangular 1024×512, VLP-16``."""
    camera = rig.camera
    return f"{camera.model} {camera.width}×{camera.height}" + (f", {rig.lidar_model}" if rig.lidar_model else "")


def fits_rig_file(settings: RigSettings, rig: RigOut) -> bool:
    """Whether a dataset of ``rig`` is of the rig the service's rig file describes (its camera's model, the
    panorama's size, its LiDAR), so that the rig file's initial guess may start it: an imported pinhole dataset
    is not, and the panorama's guess would put its LiDAR's points outside its image."""
    if settings.head:
        return rig.camera.model == CameraKind.HEAD.value and rig.lidar_model == settings.lidar_model
    ours = RigOut(camera=CameraOut(model=CameraKind.EQUIRECTANGULAR.value, width=settings.width,
                                   height=settings.height), lidar_model=settings.lidar_model)
    return rig == ours


def same_rig(a: RigOut | None, b: RigOut | None) -> bool:
    """Whether two rigs are one (an unknown one is taken as the same: nothing says otherwise)."""
    return a is None or b is None or a == b


def other_rig(version: ExtrinsicsVersion, datasets: DatasetCatalog, dataset_id: str, dataset: Dataset) -> str | None:
    """How ``version`` and dataset ``dataset_id`` are of different rigs, in words (None: one rig, or unknown)."""
    theirs = version_rig(version, datasets)
    ours = RigOut.model_validate(rig_record(dataset))
    if same_rig(theirs, ours):
        return None
    assert theirs is not None
    return (f"version {version.number} was calibrated on another rig ({rig_words(theirs)}, dataset "
            f"{version.dataset_id}) than dataset {dataset_id} ({rig_words(ours)})")
