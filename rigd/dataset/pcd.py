"""PCL PCD v0.7 clouds (ascii, binary, binary_compressed/LZF) through pypcd4."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pypcd4.pypcd4 import Encoding, PointCloud

from rigd.errors import DatasetError


@dataclass(frozen=True)
class Cloud:
    """One LiDAR cloud in the LiDAR frame.

    ``points_lidar`` (N,3) float64 m; ``intensity`` (N,) float32 or None; ``ring`` (N,) int16 laser index
    (0 = lowest) or None.
    """

    points_lidar: NDArray[np.float64]
    intensity: NDArray[np.float32] | None = None
    ring: NDArray[np.int16] | None = None

    def __len__(self) -> int:
        return len(self.points_lidar)


def read_pcd(path: Path) -> Cloud:
    """Read a PCD file; fields x y z are required, intensity and ring are kept when present."""
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: point cloud file is missing")
    try:
        cloud = PointCloud.from_path(path)
    # pypcd4 reports a short or corrupt body as struct.error (no size words) or RuntimeError (LZF size).
    except (ValueError, KeyError, IndexError, OSError, TypeError, struct.error, RuntimeError) as exc:
        raise DatasetError(f"{path}: not a readable PCD file ({exc})") from exc
    data = cloud.pc_data
    if len(data) != cloud.metadata.points:  # pypcd4 silently returns fewer points from a truncated body
        raise DatasetError(f"{path}: truncated PCD: {len(data)} of {cloud.metadata.points} points")
    names = data.dtype.names or ()
    if not {"x", "y", "z"} <= set(names):
        raise DatasetError(f"{path}: PCD has no x/y/z fields (fields: {', '.join(names)})")
    points = np.stack([data["x"], data["y"], data["z"]], axis=1).astype(np.float64)
    finite = np.all(np.isfinite(points), axis=1)
    intensity = data["intensity"].astype(np.float32)[finite] if "intensity" in names else None
    ring = data["ring"].astype(np.int16)[finite] if "ring" in names else None
    return Cloud(points[finite], intensity, ring)


def write_pcd(path: Path, cloud: Cloud, compressed: bool = True) -> None:
    """Write x y z [intensity] [ring] as PCD v0.7 (binary_compressed by default)."""
    columns = [cloud.points_lidar[:, i].astype(np.float32) for i in range(3)]
    fields = ["x", "y", "z"]
    types: list[type[np.generic]] = [np.float32, np.float32, np.float32]
    if cloud.intensity is not None:
        columns.append(cloud.intensity.astype(np.float32))
        fields.append("intensity")
        types.append(np.float32)
    if cloud.ring is not None:
        columns.append(cloud.ring.astype(np.uint16))
        fields.append("ring")
        types.append(np.uint16)
    pc = PointCloud.from_points(columns, tuple(fields), tuple(types))
    pc.save(Path(path), encoding=Encoding.BINARY_COMPRESSED if compressed else Encoding.BINARY)
