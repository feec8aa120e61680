"""Overlays a person judges at a glance: edge points as range-coloured dots, before and after, and the
close-up of where they moved most."""

from __future__ import annotations

import numpy as np

from calib.camera import Equirectangular
from calib.geometry import Transform
from rigd.calibration.visuals import CLOSEUP_MIN_WIDTH_PX, dot_radius_px, edge_views, largest_change_box

CAMERA = Equirectangular(512, 256)
IDENTITY = Transform.from_rpy_xyz(np.zeros(3), np.zeros(3))


def wall(x_m: float, y_m: np.ndarray) -> np.ndarray:
    """A vertical edge of points (N,3) m at ``x_m`` ahead, lateral offsets ``y_m``, heights -1..1 m."""
    z = np.linspace(-1.0, 1.0, 20)
    return np.array([[x_m, y, h] for y in y_m for h in z])


def test_the_close_up_box_holds_the_points_that_moved_most():
    rng = np.random.default_rng(0)
    uv_before = np.c_[rng.uniform(0, 511, 200), rng.uniform(0, 255, 200)]
    uv_after = uv_before + 0.5  # everything moved a little ...
    moved = (uv_before[:, 0] > 400) & (uv_before[:, 1] < 80)
    uv_after[moved] += [6.0, -3.0]  # ... and the top right corner a lot
    idx = np.arange(200)
    u0, v0, w, h = largest_change_box(CAMERA, idx, uv_before, idx, uv_after)
    assert (w, h) == (512 // 6, 256 // 3) and 0 <= u0 <= 512 - w and 0 <= v0 <= 256 - h
    centre = (uv_before[moved] + uv_after[moved]) / 2
    inside = (centre[:, 0] >= u0) & (centre[:, 0] < u0 + w) & (centre[:, 1] >= v0) & (centre[:, 1] < v0 + h)
    assert inside.mean() > 0.5, (u0, v0, w, h)
    # Nothing seen both before and after: the centre of the image.
    assert largest_change_box(CAMERA, idx[:10], uv_before[:10], idx[10:20], uv_after[10:20]) == (
        (512 - w) // 2, (256 - h) // 2, w, h)


def test_edge_views_draw_dots_where_the_points_project_and_move_them():
    image = np.full((256, 512), 200, np.uint8)
    points = np.vstack([wall(3.0, np.array([-0.5, 0.5])), wall(12.0, np.array([4.0]))])  # near and far edges, apart
    after = IDENTITY
    before = Transform.from_rpy_xyz(np.array([0.0, 0.0, 4.0]), np.zeros(3))  # 4 deg of yaw: ~6 px
    views = edge_views(image, CAMERA, before, after, points)
    assert views.before.shape == views.after.shape == (256, 512, 3)  # full resolution, colour
    # The photo is dimmed and grey; the dots are coloured, and lie where the points project.
    coloured = lambda img: np.ptp(img.astype(int), axis=2) > 40  # noqa: E731
    uv, _ = CAMERA.project(after.apply(points))
    px = np.rint(uv).astype(int)
    assert coloured(views.after)[px[:, 1], px[:, 0]].mean() > 0.9
    assert not coloured(views.after)[0:20, 0:20].any()
    assert np.any(coloured(views.before) != coloured(views.after))
    # Near points blue-ish, far ones red-ish (turbo over range).
    near, far = views.after[px[0, 1], px[0, 0]], views.after[px[-1, 1], px[-1, 0]]
    assert near[0] > near[2] and far[2] > far[0]  # BGR
    # The close-up: two enlarged halves with a gap, at least CLOSEUP_MIN_WIDTH_PX wide each.
    h, w = views.closeup.shape[:2]
    assert w > 2 * CLOSEUP_MIN_WIDTH_PX and h >= CLOSEUP_MIN_WIDTH_PX * (256 // 3) / (512 // 6)
    assert coloured(views.closeup).sum() > 100


def test_dots_grow_with_the_image():
    assert dot_radius_px(256, 128) == 1 and dot_radius_px(2048, 1024) == 3 and dot_radius_px(8000, 4000) == 11
