"""Surface texture: smooth value noise fixed to each surface, so the albedo is not perfectly flat.

Real walls, floors and asphalt are never uniform; a flat-shaded world would give the calibration an image
whose only gradients are the geometric edges. The texture is a property of the surface (it moves with it,
the camera and the LiDAR reflectivity both see it), two octaves of value noise (0.4 m and 0.1 m cells).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

_OCTAVES = ((0.4, 0.65), (0.1, 0.35))  # (cell size m, weight)


def _hash_unit(ix: I64, iy: I64, key: I64) -> F64:
    """A deterministic pseudo-random value in [-1, 1) per integer lattice point and surface key."""
    with np.errstate(over="ignore"):
        h = ix.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)
        h ^= iy.astype(np.uint64) * np.uint64(0xC2B2AE3D27D4EB4F)
        h ^= key.astype(np.uint64) * np.uint64(0x165667B19E3779F9)
        h ^= h >> np.uint64(31)
        h *= np.uint64(0xBF58476D1CE4E5B9)
        h ^= h >> np.uint64(29)
    return (h >> np.uint64(11)).astype(np.float64) * (2.0 / 2.0**53) - 1.0


def value_noise(coords_m: F64, key: I64) -> F64:
    """Noise in about [-1, 1] at in-plane surface coordinates ``coords_m`` (N,2) m; ``key`` (N,) int64."""
    total = np.zeros(len(coords_m))
    for cell_m, weight in _OCTAVES:
        g = coords_m / cell_m
        i0 = np.floor(g)
        f = g - i0
        f = f * f * (3.0 - 2.0 * f)  # smoothstep: continuous gradient across cells
        ix, iy = i0[:, 0].astype(np.int64), i0[:, 1].astype(np.int64)
        k = key * 2 + (cell_m < 0.2)
        v00, v10 = _hash_unit(ix, iy, k), _hash_unit(ix + 1, iy, k)
        v01, v11 = _hash_unit(ix, iy + 1, k), _hash_unit(ix + 1, iy + 1, k)
        fx, fy = f[:, 0], f[:, 1]
        total += weight * ((v00 * (1 - fx) + v10 * fx) * (1 - fy) + (v01 * (1 - fx) + v11 * fx) * fy)
    return total
