"""Street trees: porous crowns that a laser enters through gaps, added without moving the rest of a scene."""

import numpy as np
import pytest

from drivers.sim import Lighting, SimError, cast, make_scene
from drivers.sim.scene import SceneBuilder, SceneKind
from drivers.sim.vegetation import tree


def test_trees_are_added_after_the_scene_which_stays_the_same():
    plain, wooded = make_scene("outdoor", 7, 0), make_scene("outdoor", 7, 0, trees=True)
    n = plain.n_boxes
    assert wooded.n_boxes > n + 100
    np.testing.assert_array_equal(wooded.box_min[:n], plain.box_min)
    np.testing.assert_array_equal(wooded.face_albedo[:n], plain.face_albedo)
    np.testing.assert_array_equal(wooded.paint_rect, plain.paint_rect)


def test_indoor_scenes_have_no_trees():
    with pytest.raises(SimError, match="outdoor"):
        make_scene(SceneKind.INDOOR, 7, 0, trees=True)


def test_a_crown_is_porous_and_deep_to_a_laser():
    """Rays at a lone tree's crown from 12 m: most hit a clump, some pass through a gap to the far wall, and
    the clumps hit lie at depths spread over the crown's outer metre (range jumps along a scan line)."""
    b = SceneBuilder()
    b.box((30.0, -20.0, 0.0), (31.0, 20.0, 20.0), 0.5)  # a wall behind the tree
    tree(b, np.random.default_rng(3), (0.0, 0.0, 0.0))
    lighting = Lighting(np.array([0.0, 0.0, 1.0]), ambient=0.3, sun=0.7, shadows=True)
    scene = b.build(SceneKind.OUTDOOR, lighting, (-20, -15, -1, 1), 0.0, (1.5, 1.5))
    crown_z = (scene.box_min[2:, 2].min() + scene.box_max[2:, 2].max()) / 2
    origin = np.array([-12.0, 0.0, crown_z])
    half = np.arctan(1.0 / 12.0)  # a cone 1 m across at the crown's centre, well inside its silhouette
    az, el = np.meshgrid(np.linspace(-half, half, 40), np.linspace(-half, half, 40))
    rays = np.c_[np.cos(el.ravel()) * np.cos(az.ravel()), np.cos(el.ravel()) * np.sin(az.ravel()), np.sin(el.ravel())]
    depth = cast(scene, origin, rays).depth_m
    on_clumps = depth < 20.0
    assert 0.5 < on_clumps.mean() < 0.98
    assert np.std(depth[on_clumps]) > 0.25

