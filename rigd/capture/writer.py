"""A capture's writes into its dataset: the writer lock, rig.yaml (and the simulator's ground truth) with the first
pair, the free space a pair needs, and the pair itself; a full disk is a DiskFullError that says what was kept."""

from __future__ import annotations

import errno
import shutil
from pathlib import Path
from typing import Any

from calib.geometry import Transform
from drivers.sim.motion import MotionRigSpec
from rigd.capture.config import RigSettings
from rigd.capture.errors import DiskFullError
from rigd.capture.pair_files import camera_difference, pair_bytes, pair_images, rig_camera
from rigd.capture.sources import CameraFrame
from rigd.dataset import Cloud, RigConfig, write_ground_truth, write_pair, write_rig
from rigd.dataset.store import next_pair_index, read_yaml
from rigd.errors import DatasetError
from rigd.locks import DatasetLock


def lock(out: Path) -> DatasetLock:
    """The dataset's writer lock, for the whole capture; DatasetLockedError at once if another process has it."""
    try:
        return DatasetLock.acquire(out)
    except DatasetError as exc:
        if _disk_full(exc):
            raise DiskFullError(f"{exc}: free some space and rerun") from exc
        raise


def _disk_full(exc: DatasetError) -> bool:
    cause = exc.__cause__
    return isinstance(cause, OSError) and cause.errno in (errno.ENOSPC, errno.EDQUOT)


class PairWriter:
    """Writes pairs into the dataset ``out`` of a rig with ``settings`` (``sim_spec``: the simulated rig, whose
    ground truth goes with the first pair; None for a real one)."""

    def __init__(self, out: Path, settings: RigSettings, sim_spec: MotionRigSpec | None) -> None:
        self.out = out
        self.settings = settings
        self.sim_spec = sim_spec

    def write(self, frame: CameraFrame, cloud: Cloud, meta: dict[str, Any], done: int) -> Path:
        """The pair at the dataset's next index, after the ``done`` pairs of this capture; checks the space first,
        before anything is written, rig.yaml included."""
        index = next_pair_index(self.out)
        self._check_space(pair_bytes(frame), cloud, done)
        self._ensure_rig(frame)
        image, extras = pair_images(frame)
        try:
            return write_pair(self.out, index, image, cloud, meta, extras=extras)
        except DatasetError as exc:
            if _disk_full(exc):
                raise DiskFullError(f"{self.out}: disk full while writing pair {index:04d}; it was not written, the "
                                    f"{done} pairs before it are complete: free some space and rerun") from exc
            raise

    def _check_space(self, image_bytes: int, cloud: Cloud, done: int) -> None:
        needed = image_bytes + 20 * len(cloud) + (1 << 20)  # uncompressed images and cloud, and metadata
        try:
            free = shutil.disk_usage(self.out).free
        except OSError as exc:
            raise DatasetError(f"{self.out}: cannot read the free space ({exc.strerror})") from exc
        if free < 2 * needed:  # twice: the pair's temporary folder, and room left for what comes after it
            raise DiskFullError(f"{self.out}: {free / 1e6:.1f} MB free, a capture needs {2 * needed / 1e6:.1f} MB "
                                f"(twice a pair's {needed / 1e6:.1f} MB); free some space and rerun (the "
                                f"{done} pairs written are complete)")

    def _ensure_rig(self, frame: CameraFrame) -> None:
        """Write rig.yaml (and the simulator's ground truth) with the first pair; check it on a resumed one. Its
        camera is the panorama, or the head the frame's sensor images go with (rigd.capture.pair_files)."""
        camera = rig_camera(frame)
        rig_path = self.out / "rig.yaml"
        if rig_path.is_file():
            rig = RigConfig.from_yaml(read_yaml(rig_path), str(rig_path))
            difference = camera_difference(rig.camera, camera)
            if difference is not None:
                raise DatasetError(f"{rig_path}: {difference}: capture into a new dataset")
            return
        spec, settings = self.sim_spec, self.settings
        sigma = settings.lidar_elevation_sigma_deg
        if sigma is None and spec is not None:
            sigma = 0.0  # the simulated beams are where the table says
        try:
            write_rig(self.out, RigConfig(camera, settings.lidar_model, settings.initial_guess, settings.prior,
                                          settings.tolerance, settings.search, settings.lidar_elevation_offset_deg,
                                          sigma))
            if spec is not None and not (self.out / "ground_truth.yaml").is_file():
                write_ground_truth(self.out, Transform.from_matrix(spec.T_camera_lidar.matrix))
        except DatasetError as exc:
            if _disk_full(exc):
                raise DiskFullError(f"{exc}: disk full before the first pair; free some space and rerun") from exc
            raise
