"""Ray casting: hand-computed hits, paint and recesses, and agreement with a brute-force reference."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.sim import Face, Lighting, SceneBuilder, SceneKind, SimError, cast

LIGHT = Lighting(sun_dir_world=np.array([0.0, 0.0, 1.0]), ambient=0.5, sun=0.5, shadows=False)


def _scene(builder: SceneBuilder):
    return builder.build(SceneKind.INDOOR, LIGHT, (0, 1, 0, 1), 0.0, (1.0, 1.5))


def _wall_scene():
    """A wall whose near face is the plane x = 2 (y, z in [-1, 1]), albedo 0.4, no texture."""
    b = SceneBuilder()
    wall = b.box((2.0, -1.0, -1.0), (2.5, 1.0, 1.0), 0.4, texture=0.0)
    return b, wall


def test_hits_on_a_plane_match_hand_geometry():
    b, _ = _wall_scene()
    scene = _scene(b)
    angles = np.radians([0.0, 10.0, -20.0, 25.0])
    dirs = np.stack([np.cos(angles), np.sin(angles), np.zeros(4)], axis=1)
    hits = cast(scene, np.zeros(3), dirs)
    # The plane x = 2 is reached after 2 / cos(angle) metres; the normal faces the origin (-x).
    np.testing.assert_allclose(hits.depth_m, 2.0 / np.cos(angles), rtol=1e-12)
    np.testing.assert_allclose(hits.normal, np.tile([-1.0, 0.0, 0.0], (4, 1)))
    np.testing.assert_allclose(hits.albedo, 0.4)


def test_misses_and_rays_starting_inside_or_behind():
    b, _ = _wall_scene()
    scene = _scene(b)
    # Away from the wall, past its edge (y = 1 at x = 2 is 26.6 deg; 40 deg misses), and from behind it.
    origins = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    dirs = np.array([[-1.0, 0.0, 0.0], [np.cos(0.7), np.sin(0.7), 0.0], [1.0, 0.0, 0.0]])
    hits = cast(scene, origins, dirs)
    assert not hits.hit.any()
    assert np.all(hits.albedo == 0) and np.all(hits.normal == 0)


def test_paint_changes_albedo_only_inside_its_rectangle_and_later_paint_wins():
    b, wall = _wall_scene()
    b.paint(wall, Face.X_MIN, (-0.5, 0.5, -0.5, 0.5), 0.9)  # (y, z) on a face normal to x
    b.paint(wall, Face.X_MIN, (0.0, 0.5, 0.0, 0.5), 0.1, emission=2.0)
    scene = _scene(b)
    targets = np.array([[2.0, -0.25, -0.25], [2.0, 0.25, 0.25], [2.0, 0.75, 0.0]])
    hits = cast(scene, np.zeros(3), targets)
    np.testing.assert_allclose(hits.albedo, [0.9, 0.1, 0.4])
    np.testing.assert_allclose(hits.emission, [0.0, 2.0, 0.0])
    np.testing.assert_allclose(hits.depth_m, np.linalg.norm(targets, axis=1), rtol=1e-12)


def test_recess_back_and_reveal():
    b, wall = _wall_scene()
    b.recess(wall, Face.X_MIN, (-0.2, 0.2, -0.2, 0.2), 0.3, 0.1)  # a pocket from x = 2 to 2.3
    scene = _scene(b)
    origin = np.zeros(3)
    straight = np.array([1.0, 0.0, 0.0])
    # Slope 0.095 in y: enters the opening at x = 2 (y = 0.19) and meets the side wall y = 0.2 at
    # x = 0.2 / 0.095 = 2.105, before the back at x = 2.3.
    slope = 0.095
    side = np.array([1.0, slope, 0.0])
    outside = np.array([1.0, 0.15, 0.0])  # y = 0.3 at the face: outside the opening
    hits = cast(scene, origin, np.stack([straight, side, outside]))
    np.testing.assert_allclose(hits.depth_m[0], 2.3, rtol=1e-12)
    np.testing.assert_allclose(hits.normal[0], [-1.0, 0.0, 0.0])
    assert hits.albedo[0] == pytest.approx(0.1)  # the back wall has the recess albedo
    x_side = 0.2 / slope
    np.testing.assert_allclose(hits.depth_m[1], x_side * np.linalg.norm(side), rtol=1e-12)
    np.testing.assert_allclose(hits.normal[1], [0.0, -1.0, 0.0])  # the reveal faces back towards -y
    assert hits.albedo[1] == pytest.approx(0.4)  # reveals take the face's albedo
    np.testing.assert_allclose(hits.depth_m[2], 2.0 * np.linalg.norm(outside), rtol=1e-12)


def _reference_depth(lo: np.ndarray, hi: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> float:
    """Plain per-ray slab test over every box, no culling: the nearest entry distance (inf if none)."""
    best = np.inf
    for box_lo, box_hi in zip(lo, hi, strict=True):
        t0, t1 = -np.inf, np.inf
        for k in range(3):
            if direction[k] == 0.0:
                if not box_lo[k] <= origin[k] <= box_hi[k]:
                    break
                continue
            a = (box_lo[k] - origin[k]) / direction[k]
            c = (box_hi[k] - origin[k]) / direction[k]
            t0, t1 = max(t0, min(a, c)), min(t1, max(a, c))
        else:
            if t0 <= t1 and t0 > 0:
                best = min(best, t0)
    return best


@pytest.mark.parametrize("shared_origin", [True, False])
def test_culled_chunked_casting_matches_brute_force(shared_origin):
    rng = np.random.default_rng(7)
    b = SceneBuilder()
    for _ in range(80):
        centre = rng.uniform(-12, 12, size=3)
        half = rng.uniform(0.05, 3.0, size=3)
        if np.all(np.abs(centre) < half + 0.5):
            continue  # keep the origins outside the boxes
        b.box(centre - half, centre + half, 0.5)
    scene = _scene(b)
    n = 600
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    origins = np.zeros(3) if shared_origin else rng.uniform(-0.3, 0.3, size=(n, 3))
    hits = cast(scene, origins, dirs, chunk_rays=64)
    o = np.broadcast_to(origins, dirs.shape)
    expected = np.array([_reference_depth(scene.box_min, scene.box_max, o[i], dirs[i]) for i in range(n)])
    assert np.isfinite(expected).sum() > n // 4 and (~np.isfinite(expected)).sum() > n // 20
    np.testing.assert_array_equal(np.isfinite(hits.depth_m), np.isfinite(expected))
    finite = np.isfinite(expected)
    np.testing.assert_allclose(hits.depth_m[finite], expected[finite], rtol=1e-9)


def test_bad_rays_are_rejected_with_a_clear_error():
    b, _ = _wall_scene()
    scene = _scene(b)
    with pytest.raises(SimError, match="directions"):
        cast(scene, np.zeros(3), np.zeros((2, 2)))
    with pytest.raises(SimError, match="non-zero"):
        cast(scene, np.zeros(3), np.zeros((2, 3)))



def test_cast_of_no_rays_returns_no_hits():
    from drivers.sim import make_scene

    hits = cast(make_scene(SceneKind.OUTDOOR, 11, 0), np.zeros(3), np.zeros((0, 3)))
    assert len(hits.depth_m) == 0 and hits.normal.shape == (0, 3)
