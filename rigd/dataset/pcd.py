"""PCL PCD v0.7 clouds (ascii, binary, binary_compressed/LZF) through pypcd4."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pypcd4.pypcd4 import Encoding, MetaData, PointCloud

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


MAX_RANGE_M = 10_000.0  # no LiDAR sees 10 km: a coordinate beyond is another unit, or garbage
MAX_RING = 1023  # the most lasers a LiDAR has is 128; a ring index beyond this is garbage (or a negative one wrapped)


def _first_line(exc: BaseException) -> str:
    """An exception's message without the rest of a pydantic report (20 lines for one bad header word)."""
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def _check_header(path: Path) -> None:
    """DatasetError when the header is unreadable or claims more data than the file holds (a 4e9-point header
    would have the reader allocate it)."""
    size = path.stat().st_size
    if size == 0:
        raise DatasetError(f"{path}: empty file, not a PCD cloud")
    with path.open("rb") as fh:
        lines: list[str] = []
        for raw in fh:  # as pypcd4 reads it: up to DATA, at most 10 lines that are not comments
            line = raw.decode("utf-8", "replace").strip()
            if line and not line.startswith("#"):
                lines.append(line)
                if line.startswith("DATA") or len(lines) >= 10:
                    break
        body = size - fh.tell()
        head = fh.read(8)
    try:
        meta = MetaData.parse_header(lines)
        need = meta.points * meta.build_dtype().itemsize
    except (ValueError, KeyError, IndexError, TypeError) as exc:
        raise DatasetError(f"{path}: not a readable PCD header ({_first_line(exc)})") from exc
    claims = f"the header says {meta.points} points ({need} bytes)"
    if meta.data is Encoding.BINARY and need > body:
        raise DatasetError(f"{path}: truncated PCD: {claims}, the file holds {body}")
    if meta.data is Encoding.BINARY_COMPRESSED and meta.points:
        packed, unpacked = struct.unpack("<II", head) if len(head) == 8 else (body, -1)
        if unpacked != need or packed > body - 8:
            raise DatasetError(f"{path}: corrupt PCD: {claims}, its compressed body {packed} bytes of {body} "
                               f"holds {unpacked}")
    if meta.data is Encoding.ASCII and meta.points * len(meta.fields) * 2 > body + 1:
        raise DatasetError(f"{path}: truncated PCD: {claims} as text, the file holds {body} bytes")


def read_pcd(path: Path) -> Cloud:
    """Read a PCD file; fields x y z are required, intensity and ring are kept when present. DatasetError naming
    the file for a corrupt one, and for a cloud without a finite point or with impossible values."""
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: point cloud file is missing")
    _check_header(path)
    try:
        cloud = PointCloud.from_path(path)
    # pypcd4 reports a short or corrupt body as struct.error (no size words) or RuntimeError (LZF size).
    except (ValueError, KeyError, IndexError, OSError, TypeError, struct.error, RuntimeError, MemoryError) as exc:
        raise DatasetError(f"{path}: not a readable PCD file ({_first_line(exc)})") from exc
    data = cloud.pc_data
    if len(data) != cloud.metadata.points:  # pypcd4 silently returns fewer points from a truncated body
        raise DatasetError(f"{path}: truncated PCD: {len(data)} of {cloud.metadata.points} points")
    names = data.dtype.names or ()
    if not {"x", "y", "z"} <= set(names):
        raise DatasetError(f"{path}: PCD has no x/y/z fields (fields: {', '.join(names)})")
    points = np.stack([data["x"], data["y"], data["z"]], axis=1).astype(np.float64)
    finite = np.all(np.isfinite(points), axis=1)
    if not finite.any():
        raise DatasetError(f"{path}: the cloud has no point" + (f" with finite x, y, z (all {len(points)} are "
                                                                  "NaN or infinite)" if len(points) else "s"))
    intensity = data["intensity"].astype(np.float32)[finite] if "intensity" in names else None
    ring = _rings(path, data["ring"][finite]) if "ring" in names else None
    _check_range(path, points[finite])
    return Cloud(points[finite], intensity, ring)


def _check_range(path: Path, points: NDArray[np.float64]) -> None:
    far = np.flatnonzero(np.abs(points).max(axis=1) > MAX_RANGE_M)
    if far.size:
        x, y, z = points[far[0]]
        raise DatasetError(f"{path}: {far.size} points lie beyond {MAX_RANGE_M:g} m, e.g. ({x:g}, {y:g}, {z:g}): no "
                           "LiDAR sees that far: are the coordinates in metres?")


def _rings(path: Path, ring: NDArray[np.generic]) -> NDArray[np.int16]:
    values = ring.astype(np.int64)
    bad = np.flatnonzero((values < 0) | (values > MAX_RING))
    if bad.size:
        raise DatasetError(f"{path}: {bad.size} points have a ring index outside 0..{MAX_RING}, e.g. {values[bad[0]]}")
    return values.astype(np.int16)


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
