"""Overlays a person judges at a glance: edge points as range-coloured dots, before and after, and the
close-up of where they moved most."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from calib.camera import Equirectangular, Mounted, Pinhole
from calib.geometry import Transform
from rigd.calibration.visuals import (
    CLOSEUP_MIN_WIDTH_PX,
    UNSEEN_BGR,
    Upright,
    cloud_top_view,
    dot_gap_px,
    dot_radius_px,
    edge_views,
    largest_change_box,
)

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
    # The photo is dimmed and grey; the dots are coloured, and lie where the points project: thinned so that
    # every point is near a dot, and every dot on a point.
    coloured = lambda img: np.ptp(img.astype(int), axis=2) > 40  # noqa: E731
    uv, _ = CAMERA.project(after.apply(points))
    px = np.rint(uv).astype(int)
    to_dot = ndimage.distance_transform_edt(~coloured(views.after))
    assert to_dot[px[:, 1], px[:, 0]].max() <= dot_gap_px(dot_radius_px(512, 256))
    to_point = np.ones((256, 512), bool)
    to_point[px[:, 1], px[:, 0]] = False
    assert ndimage.distance_transform_edt(to_point)[coloured(views.after)].max() <= dot_radius_px(512, 256) + 1
    assert coloured(views.after).sum() < 0.6 * len(px) * 9  # fewer dots than points: the wall shows between them
    assert not coloured(views.after)[0:20, 0:20].any()
    assert np.any(coloured(views.before) != coloured(views.after))
    # Near points blue-ish, far ones red-ish (turbo over range).
    dots = coloured(views.after)
    columns = np.arange(512)[None, :]
    near_wall = dots & (np.abs(columns - px[0, 0]) <= 3)  # the first points: the near wall's, 3 m away
    far_wall = dots & (np.abs(columns - px[-1, 0]) <= 3)  # the last ones: the far wall's
    near, far = views.after[near_wall].astype(int).mean(axis=0), views.after[far_wall].astype(int).mean(axis=0)
    assert near[0] > near[2] and far[2] > far[0]  # BGR
    # The close-up: two enlarged halves with a gap, at least CLOSEUP_MIN_WIDTH_PX wide each.
    h, w = views.closeup.shape[:2]
    assert w > 2 * CLOSEUP_MIN_WIDTH_PX and h >= CLOSEUP_MIN_WIDTH_PX * (256 // 3) / (512 // 6)
    assert coloured(views.closeup).sum() > 100


def test_dots_grow_with_the_image():
    assert dot_radius_px(256, 128) == 1 and dot_radius_px(2048, 1024) == 3 and dot_radius_px(8000, 4000) == 13


def test_the_top_view_colours_each_point_from_the_pixel_it_lands_on():
    # A red wall ahead (x = 4 m) on a blue ground: the panorama's upper half red, lower half blue.
    image = np.zeros((256, 512, 3), np.uint8)
    image[:128] = (0, 0, 255)
    image[128:] = (255, 0, 0)
    ground = np.array([[x, y, -1.0] for x in np.linspace(-3.5, 3.5, 40) for y in np.linspace(-3.5, 3.5, 40)])
    wall_pts = np.array([[4.0, y, z] for y in np.linspace(-3.5, 3.5, 40) for z in np.linspace(0.2, 2.0, 10)])
    size = 400
    view = cloud_top_view([(image, CAMERA, None)], IDENTITY, np.vstack([ground, wall_pts]), size)
    assert view.shape == (size, size, 3)
    # The wall is drawn red (up the picture: forward), the ground blue; nothing grey (all seen).
    reddish = (view[..., 2] > 200) & (view[..., 0] < 50)
    bluish = (view[..., 0] > 200) & (view[..., 2] < 50)
    rows_red, _ = np.nonzero(reddish)
    rows_blue, _ = np.nonzero(bluish)
    assert len(rows_red) > 30 and len(rows_blue) > 500
    assert rows_red.mean() < rows_blue.min()  # the wall lies ahead of all the ground
    assert not np.all(view[:-30] == UNSEEN_BGR, axis=2).any()  # (the bottom rows hold the legend)
    # Pitched 40 deg down, the camera sees the wall where the ground was: the wall turns blue, the far
    # ground red. The picture changes with the extrinsics, which is the point of it.
    pitched = Transform.from_rpy_xyz(np.array([0.0, 40.0, 0.0]), np.zeros(3))
    wrong = cloud_top_view([(image, CAMERA, None)], pitched, np.vstack([ground, wall_pts]), size)
    assert ((wrong[..., 2] > 200) & (wrong[..., 0] < 50)).sum() != reddish.sum()


def test_the_top_view_greys_what_the_camera_does_not_see():
    camera = Pinhole(np.array([[100.0, 0, 100.0], [0, 100.0, 50.0], [0, 0, 1]]), np.zeros(4), 200, 100)
    to_optical = Transform(np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]), np.zeros(3))
    image = np.full((100, 200, 3), (0, 200, 0), np.uint8)
    points = np.array([[5.0, 0.0, 0.0], [-5.0, 0.0, 0.0]])  # one ahead (seen), one behind (not)
    view = cloud_top_view([(image, camera, None)], to_optical, points, 200)
    ahead, behind = view[100 - 96], view[100 + 96]  # 5 m at (200/2 - 4) px per 5 m
    assert ((ahead == (0, 200, 0)).all(axis=1)).any()
    assert ((behind == UNSEEN_BGR).all(axis=1)).any()


def test_a_close_up_without_points_in_it_is_drawn():
    """A solution equal to its start moves nothing; where no point lies in the chosen box, the close-up shows
    the photo alone (OpenCV's colour map returns None for no points)."""
    image = np.full((256, 512), 200, np.uint8)
    points = wall(3.0, np.array([-0.5]))  # one edge, near the middle column of the panorama
    for pose in (IDENTITY, Transform.from_rpy_xyz(np.array([0.0, 0.0, 170.0]), np.zeros(3))):
        views = edge_views(image, CAMERA, pose, pose, points)
        assert views.closeup.shape[0] > 0 and views.closeup.shape[1] > 2 * CLOSEUP_MIN_WIDTH_PX


def ladybug_side_sensor(width: int, height: int, fy_over_fx: float = 1.0) -> Mounted:
    """A head's sensor lying on its side as a Ladybug5's: looking along the head's +x, image columns along -z (up
    is towards column 0), rows along +y."""
    fx = width / 2.0
    K = np.array([[fx, 0.0, (width - 1) / 2], [0.0, fx * fy_over_fx, (height - 1) / 2], [0.0, 0.0, 1.0]])
    R_head_sensor = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # columns: x, y, z of the sensor
    return Mounted("cam0", Pinhole(K, np.zeros(4), width, height), R_head_sensor.T, np.zeros(3))


def test_a_sensor_lying_on_its_side_is_drawn_upright():
    camera = ladybug_side_sensor(48, 40)
    above = np.array([[5.0, 0.0, 2.0]])  # ahead and above the horizon (head frame = LiDAR frame here)
    uv, valid = camera.project(above)
    assert valid[0] and uv[0, 0] < 20  # stored: towards the first columns, i.e. on the left
    image = np.full((40, 48), 60, np.uint8)
    u, v = np.rint(uv[0]).astype(int)
    image[v - 1:v + 2, u - 1:u + 2] = 255  # a bright marker where that point is
    views = edge_views(image, camera, IDENTITY, IDENTITY, wall(5.0, np.array([-1.0, 1.0])))
    assert views.after.shape == (48, 40, 3)  # turned a quarter: the long side upright
    rows, cols = np.nonzero(views.after.min(axis=2) > 140)  # the marker (dimmed, but brighter than the rest)
    assert len(rows) and rows.max() < 24  # in the upper half
    upright = Upright.of(camera)
    assert upright.turns == 1
    np.testing.assert_allclose(upright.points(uv), [[cols.mean(), rows.mean()]], atol=1.0)  # points turn with it
    # Pixels twice as tall as wide (fy = fx / 2, the Ford head's) are shown square: rows doubled, then turned.
    squashed = Upright.of(ladybug_side_sensor(48, 20, 0.5))
    assert squashed.image(np.zeros((20, 48), np.uint8)).shape == (48, 40) and squashed.turns == 1
    # A sensor looking up has no up in its image: as it is.
    up = Mounted("cam5", camera.sensor, np.eye(3), np.zeros(3))
    assert Upright.of(up).turns == 0 and Upright.of(CAMERA).turns == 0


def test_no_dot_on_a_masked_pixel():
    """A mask's left-out pixels (the rig, a sensor's dark border) get no dots, before or after."""
    image = np.full((256, 512), 200, np.uint8)
    points = np.vstack([wall(3.0, np.array([-0.5, 0.5]))])  # two edges, left and right of straight ahead
    mask = np.ones((256, 512), bool)
    mask[:, 256:] = False  # straight ahead is column 256: its right half is left out
    coloured = lambda img: np.ptp(img.astype(int), axis=2) > 40  # noqa: E731
    for name in ("before", "after"):
        shown = getattr(edge_views(image, CAMERA, IDENTITY, IDENTITY, points, mask), name)
        assert coloured(shown)[:, :250].any() and not coloured(shown)[:, 262:].any(), name
