"""The dataset format: the contract between capture and calibrate (docs/dataset.md)."""

from rigd.dataset.pcd import Cloud, read_pcd, write_pcd
from rigd.dataset.records import CameraConfig, CameraKind, RigConfig
from rigd.dataset.store import Dataset, Pair, open_dataset, write_ground_truth, write_pair, write_rig

__all__ = [
    "CameraConfig",
    "CameraKind",
    "Cloud",
    "Dataset",
    "Pair",
    "RigConfig",
    "open_dataset",
    "read_pcd",
    "write_ground_truth",
    "write_pair",
    "write_pcd",
    "write_rig",
]
