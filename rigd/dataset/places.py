"""Which pairs were taken at one place: the rig did not move between them, so their static background coincides.

Pairs at one place see the same scene from the same pose: the calibration's evidence from them is not
independent (the same edges, the same rings crossing them), and the uncertainty's jackknife and the verdict's
counts go by places, not pairs (docs/trust.md). Two clouds are of one place when, over the directions both see,
most ranges agree: people or a target that moved between them change a few directions, a move of the rig by a
step or a turn by a few degrees changes most (docs/dataset.md).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rigd.dataset.pcd import Cloud, read_pcd
from rigd.dataset.store import Dataset

# Beams below this see the ground, at the same ranges wherever a level rig stands: only those above it compare
MIN_ELEVATION_DEG = -3.0
AZIMUTH_BIN_DEG = 1.0  # a VLP-16 fires every 0.2-0.4 deg: a bin holds a few points of each ring
ELEVATION_BIN_DEG = 1.0  # without rings: rows of this height
AGREE_M = 0.05  # two ranges agree within this, or within AGREE_SHARE of the range
AGREE_SHARE = 0.02
SAME_PLACE_SHARE = 0.7  # of the directions both clouds see, at least this share agrees: one place (measured: 0.86-0.93
# between frames of one place with people moving; at most 0.51 between places a street apart, 0.18 in simulated drives)
MIN_SHARED_CELLS = 100  # fewer directions in common say nothing: not one place


def range_image(cloud: Cloud) -> NDArray[np.float32]:
    """(rows, 360) float32 m: the median range of the cloud's points above :data:`MIN_ELEVATION_DEG` per ring (or
    1 deg row of elevation) and 1 deg of azimuth, NaN where no point falls."""
    elevation = np.degrees(np.arctan2(cloud.points_lidar[:, 2], np.hypot(*cloud.points_lidar[:, :2].T)))
    above = elevation >= MIN_ELEVATION_DEG
    p, elevation = cloud.points_lidar[above], elevation[above]
    ring = None if cloud.ring is None else cloud.ring[above]
    rng = np.linalg.norm(p, axis=1)
    azimuth = np.degrees(np.arctan2(p[:, 1], p[:, 0])) % 360.0
    col = np.minimum((azimuth / AZIMUTH_BIN_DEG).astype(np.int64), int(360 / AZIMUTH_BIN_DEG) - 1)
    if ring is not None:
        row = ring.astype(np.int64)
    else:
        row = ((elevation + 90.0) / ELEVATION_BIN_DEG).astype(np.int64)
    rows, cols = int(row.max(initial=0)) + 1, int(360 / AZIMUTH_BIN_DEG)
    key = row * cols + col
    order = np.lexsort((rng, key))
    key, rng = key[order], rng[order]
    starts = np.flatnonzero(np.r_[True, np.diff(key) > 0])
    counts = np.diff(np.r_[starts, len(key)])
    image = np.full(rows * cols, np.nan, np.float32)
    image[key[starts]] = rng[starts + counts // 2]  # each cell's median (sorted by range within the cell)
    return image.reshape(rows, cols)


def agreement(a: NDArray[np.float32], b: NDArray[np.float32]) -> float | None:
    """The share of cells both range images hold whose ranges agree; None when they share too few cells."""
    rows = min(a.shape[0], b.shape[0])
    a, b = a[:rows], b[:rows]
    both = np.isfinite(a) & np.isfinite(b)
    if int(both.sum()) < MIN_SHARED_CELLS:
        return None
    diff = np.abs(a[both] - b[both])
    return float(np.mean(diff <= np.maximum(AGREE_M, AGREE_SHARE * np.minimum(a[both], b[both]))))


def find_places(images: list[NDArray[np.float32]]) -> tuple[int, ...]:
    """The place of each pair (from its cloud's :func:`range_image`), numbered 0.. in order of first appearance:
    a pair whose cloud agrees with an earlier pair's (:data:`SAME_PLACE_SHARE`) joins that pair's place."""
    place: list[int] = []
    for i, image in enumerate(images):
        same = next((place[j] for j in range(i) if (agreement(image, images[j]) or 0.0) >= SAME_PLACE_SHARE), None)
        place.append(same if same is not None else (max(place) + 1 if place else 0))
    return tuple(place)


def dataset_places(dataset: Dataset) -> tuple[int, ...]:
    """The place of each pair of ``dataset`` (:func:`find_places` of its clouds, read without the images)."""
    return find_places([range_image(read_pcd(folder / "cloud.pcd")) for folder in dataset.pair_dirs])
