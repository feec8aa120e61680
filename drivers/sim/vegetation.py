"""Street trees: a trunk and a porous crown of leaf clumps (boxes), for scenes with vegetation.

What vegetation does to the calibration is what a street scene's real data show (issue 10: most of a
64-ring LiDAR's edge points are on trees): a laser enters a crown through its gaps and returns from a clump
deeper in or from what is behind, so range jumps crowd every ring that crosses a crown; the camera sees
many small sunlit and shaded clumps, texture rather than a silhouette, with dappled shade beneath. A crown
here is a shell of clumps (the camera and the LiDAR see mostly its outer metre) with gaps between them.
"""

from __future__ import annotations

import numpy as np

from drivers.sim.scene import SceneBuilder

CLUMP_M = (0.25, 0.55)  # edge of a leaf clump
CROWN_RADIUS_M = (1.5, 3.0)
SHELL_COVER = 0.55  # share of the crown's outer surface that clumps cover (the rest are gaps)


def tree(b: SceneBuilder, rng: np.random.Generator, base_xyz: tuple[float, float, float]) -> None:
    """A tree standing at ``base_xyz`` (m): a trunk up into a crown of clumps on an ellipsoidal shell."""
    x, y, z = base_xyz
    radius = float(rng.uniform(*CROWN_RADIUS_M))
    trunk_h = float(rng.uniform(1.8, 3.0))
    half_w = float(rng.uniform(0.08, 0.2))
    bark = float(rng.uniform(0.15, 0.35))
    b.box((x - half_w, y - half_w, z), (x + half_w, y + half_w, z + trunk_h + radius), bark, texture=0.15)
    centre = np.array([x, y, z + trunk_h + radius * 0.8])
    squash = float(rng.uniform(0.7, 1.0))  # crowns are often wider than tall
    axes = np.array([radius, radius, radius * squash])
    area = 4.0 * np.pi * radius ** 2 * (1.0 + 2.0 * squash) / 3.0  # close enough for an ellipsoid's shell
    n = int(area * SHELL_COVER / np.mean(CLUMP_M) ** 2)
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    depth = rng.uniform(0.65, 1.0, size=(n, 1))  # a shell about a metre thick
    centres = centre + directions * axes * depth
    sizes = rng.uniform(*CLUMP_M, size=n)
    leaf = rng.uniform(0.08, 0.25, size=n)  # dark green foliage, from shade to sunlit
    for c, s, a in zip(centres, sizes, leaf, strict=True):
        b.box(c - s / 2, c + s / 2, float(a), texture=0.25)


def street_trees(b: SceneBuilder, rng: np.random.Generator, side: int, y_m: float, ground_z_m: float,
                 x_range_m: tuple[float, float] = (-60.0, 60.0)) -> None:
    """A row of trees along a street side (``side`` +-1) at ``y_m``, 8-20 m apart, some gaps in the row."""
    spacing = float(rng.uniform(8.0, 20.0))
    for x in np.arange(x_range_m[0] + rng.uniform(0, spacing), x_range_m[1], spacing):
        if rng.random() < 0.8:
            tree(b, rng, (float(x + rng.uniform(-1.0, 1.0)), side * y_m, ground_z_m))
