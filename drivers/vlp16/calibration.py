"""Per-laser geometry: elevation angles and vertical offsets, optionally from a ROS ``VLP16db.yaml`` file.

Without a file the geometry is the VLP-16 manual's (63-9243, "vertical correction"): nominal elevations, and
each laser's origin ``41.91 mm * tan(-elevation)`` above the sensor origin along z (+11.2 mm for the -15 deg
laser, -11.2 mm for +15 deg). velodyne_decoder and VeloView use the same default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from drivers.vlp16.errors import CalibrationFileError
from drivers.vlp16.layout import DISTANCE_UNIT_M, LASERS, NOMINAL_ELEVATION_DEG

#: The manual's vertical correction is this length times tan(-elevation), m.
MANUAL_OFFSET_LEVER_M = 0.04191


def manual_vertical_offset_m(elevation_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """(16,) float64 m: the VLP-16 manual's vertical offset of each laser's origin for elevations (16,) deg."""
    return MANUAL_OFFSET_LEVER_M * np.tan(np.radians(-np.asarray(elevation_deg, dtype=np.float64)))


# Fields of the ROS format this driver does not model; a file with a nonzero value is refused, not ignored.
_UNSUPPORTED_FIELDS = (
    "rot_correction",
    "horiz_offset_correction",
    "dist_correction",
    "dist_correction_x",
    "dist_correction_y",
    "focal_distance",
    "focal_slope",
)


@dataclass(frozen=True)
class LaserCalibration:
    """``elevation_deg`` (16,) float64 deg and ``vertical_offset_m`` (16,) float64 m of lasers 0..15.

    The vertical offset ``o`` of a laser's origin is added to z: ``x = r cos w cos a``,
    ``y = -r cos w sin a``, ``z = r sin w + o`` (the VLP-16 manual's "vertical correction", applied as
    velodyne_decoder does). The default is the manual's geometry; :meth:`nominal` has no offsets.
    """

    elevation_deg: NDArray[np.float64] = field(default_factory=lambda: NOMINAL_ELEVATION_DEG.copy())
    vertical_offset_m: NDArray[np.float64] = field(
        default_factory=lambda: manual_vertical_offset_m(NOMINAL_ELEVATION_DEG)
    )

    @classmethod
    def nominal(cls) -> LaserCalibration:
        """Nominal elevations with every laser at the sensor origin: rigd's earlier default, up to 11.2 mm off
        in z (CLI ``--nominal-geometry``)."""
        return cls(NOMINAL_ELEVATION_DEG.copy(), np.zeros(LASERS))

    def __post_init__(self) -> None:
        for name in ("elevation_deg", "vertical_offset_m"):
            value = np.asarray(getattr(self, name), dtype=np.float64)
            if value.shape != (LASERS,) or not np.all(np.isfinite(value)):
                raise CalibrationFileError(
                    f"laser calibration: {name} must be 16 finite numbers, got {value!r}"
                )
            object.__setattr__(self, name, value)

    @property
    def ring_of_laser(self) -> NDArray[np.uint8]:
        """(16,) uint8: rank of each laser by elevation, 0 = lowest (the ROS/VeloView ``ring``)."""
        ring = np.empty(LASERS, dtype=np.uint8)
        ring[np.argsort(self.elevation_deg, kind="stable")] = np.arange(LASERS, dtype=np.uint8)
        return ring


def _laser_id(path: Path, entry: dict[Any, Any]) -> int:
    """``entry``'s laser_id, an integer 0..15; CalibrationFileError naming the entry otherwise."""
    raw: Any = entry.get("laser_id")
    try:
        number = float(raw)
    except (TypeError, ValueError, OverflowError):
        number = math.nan
    if isinstance(raw, bool) or not (number.is_integer() and 0 <= number < LASERS):
        raise CalibrationFileError(f"{path}: bad laser entry {entry!r}: laser_id must be an integer 0..15")
    return int(number)


def _number(path: Path, entry: dict[Any, Any], laser: int, key: str, default: float | None) -> float:
    """``entry[key]`` as a finite float (``default`` when absent; None: required), else CalibrationFileError
    naming the laser and the field. Checked one by one, as a NaN would otherwise pass for a missing laser."""
    if key not in entry:
        if default is None:
            raise CalibrationFileError(f"{path}: laser {laser} has no {key}")
        return default
    raw = entry[key]
    try:
        number = float(raw)
    except (TypeError, ValueError, OverflowError):
        number = math.nan
    if isinstance(raw, bool) or not math.isfinite(number):
        raise CalibrationFileError(f"{path}: laser {laser}: {key} must be a finite number, got {raw!r}")
    return number


def load_calibration(path: Path) -> LaserCalibration:
    """Read ``lasers: [{laser_id, vert_correction (rad), vert_offset_correction (m)}, ...]`` from YAML."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise CalibrationFileError(f"{path}: cannot read calibration ({exc})") from exc
    lasers = data.get("lasers") if isinstance(data, dict) else None
    if not isinstance(lasers, list) or len(lasers) != LASERS:
        raise CalibrationFileError(f"{path}: needs a 'lasers' list of 16 entries")
    resolution = data.get("distance_resolution", DISTANCE_UNIT_M)
    # Written as "not <=" so that a NaN fails too.
    if not isinstance(resolution, (int, float)) or not abs(resolution - DISTANCE_UNIT_M) <= 1e-9:
        raise CalibrationFileError(f"{path}: distance_resolution {resolution} is not the VLP-16's 0.002 m")
    elevation = np.zeros(LASERS)
    offset = np.zeros(LASERS)
    seen: set[int] = set()
    for entry in lasers:
        if not isinstance(entry, dict):
            raise CalibrationFileError(f"{path}: bad laser entry {entry!r}: not a mapping")
        laser = _laser_id(path, entry)
        if laser in seen:
            raise CalibrationFileError(f"{path}: laser {laser} is listed twice (laser ids must be 0..15, each once)")
        seen.add(laser)
        elevation[laser] = np.degrees(_number(path, entry, laser, "vert_correction", None))
        offset[laser] = _number(path, entry, laser, "vert_offset_correction", 0.0)
        unsupported = [k for k in _UNSUPPORTED_FIELDS if _number(path, entry, laser, k, 0.0) != 0.0]
        if unsupported:
            raise CalibrationFileError(
                f"{path}: laser {laser} sets {', '.join(unsupported)}, which this "
                "driver does not apply (only vert_correction and vert_offset_correction)"
            )
    # 16 entries, each id in 0..15 and none twice: every laser is there.
    return LaserCalibration(elevation, offset)
