"""The simulated camera against peer projections: calib.camera.Equirectangular and cv2.projectPoints."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from calib.camera import Equirectangular
from calib.geometry import rpy_deg_to_matrix
from drivers.sim import ROTATION_PANORAMA_OPTICAL, Lighting, Pose, SceneBuilder, SceneKind, render_rays
from drivers.sim.camera import render_panorama, render_pinhole

DARK = Lighting(sun_dir_world=np.array([0.0, 0.0, 1.0]), ambient=1.0, sun=0.0, shadows=False,
                sky_horizon=0.0, sky_zenith=0.0)


def _marker_scene(centres: np.ndarray, half: float = 0.15):
    """Black sky, one small white cube per centre (ambient light only, so every face has the same value)."""
    b = SceneBuilder()
    for c in centres:
        b.box(c - half, c + half, 1.0, texture=0.0)
    return b.build(SceneKind.OUTDOOR, DARK, (0, 1, 0, 1), 0.0, (1.0, 1.5))


def _blob_centroids(image: np.ndarray) -> np.ndarray:
    """Intensity-weighted centroids (u, v) of the bright blobs, px (pixel centres at integers)."""
    n, labels = cv2.connectedComponents((image > 20).astype(np.uint8))
    rows, cols = np.indices(image.shape)
    w = image.astype(np.float64)
    return np.array([[np.sum(cols * w * (labels == k)) / np.sum(w * (labels == k)),
                      np.sum(rows * w * (labels == k)) / np.sum(w * (labels == k))] for k in range(1, n)])


def _match(found: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """Distance (px) from each expected point to the nearest found blob."""
    return np.min(np.linalg.norm(expected[:, None, :] - found[None, :, :], axis=2), axis=1)


def test_panorama_puts_objects_where_calib_projects_them():
    rng = np.random.default_rng(1)
    camera = Pose(rpy_deg_to_matrix(np.array([4.0, -7.0, 33.0])), np.array([0.5, -0.2, 1.4]))
    # Markers 8 m away around the camera, away from the poles and the u = 0 seam (behind).
    az = np.radians([-150, -100, -40, 10, 60, 120, 170])
    el = np.radians([-30, 20, 0, 45, -10, 10, -50])
    dirs_cam = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    centres = camera.apply(8.0 * dirs_cam)
    scene = _marker_scene(centres)
    width, height = 512, 256
    image = render_panorama(scene, camera, width, height, rng, noise_grey=0.0)
    expected, valid = Equirectangular(width, height).project(camera.inverse().apply(centres))
    assert valid.all()
    found = _blob_centroids(image)
    assert len(found) == len(centres)
    # A cube is not a point: its projection is not quite symmetric about the centre's; 0.3 px is far below
    # any convention error (a half-pixel offset, a flipped axis or the seam in the wrong place).
    assert _match(found, expected).max() < 0.3


def test_pinhole_view_matches_cv2_project_points():
    rng = np.random.default_rng(2)
    K = np.array([[300.0, 0.0, 161.0], [0.0, 310.0, 118.0], [0.0, 0.0, 1.0]])
    D = np.array([-0.2, 0.05, 0.001, -0.002, 0.0])
    width, height = 320, 240
    r_world_cam = rpy_deg_to_matrix(np.array([0.0, 5.0, -20.0]))  # a panorama-frame camera orientation
    origin = np.array([1.0, 2.0, 1.5])
    r_world_optical = r_world_cam @ ROTATION_PANORAMA_OPTICAL
    points_optical = np.array([[0.0, 0.0, 6.0], [-1.5, -1.0, 7.0], [2.0, 0.8, 6.5], [-1.2, 1.1, 5.0]])
    centres = points_optical @ r_world_optical.T + origin
    scene = _marker_scene(centres, half=0.08)
    image = render_pinhole(scene, origin, r_world_optical, K, width, height, rng, D=D, noise_grey=0.0)
    expected = cv2.projectPoints(points_optical, np.zeros(3), np.zeros(3), K, D)[0].reshape(-1, 2)
    found = _blob_centroids(image)
    assert len(found) == len(centres)
    assert _match(found, expected).max() < 0.3


def test_forward_optical_axis_is_panorama_forward():
    """ROTATION_PANORAMA_OPTICAL: optical z (forward) is panorama x, optical x (right) is panorama -y."""
    np.testing.assert_allclose(ROTATION_PANORAMA_OPTICAL @ [0, 0, 1], [1, 0, 0])
    np.testing.assert_allclose(ROTATION_PANORAMA_OPTICAL @ [1, 0, 0], [0, -1, 0])
    np.testing.assert_allclose(ROTATION_PANORAMA_OPTICAL @ [0, 1, 0], [0, 0, -1])


def test_lambertian_shading_gamma_and_noise():
    """A floor lit by a sun at 60 deg elevation: display value = (albedo (ambient + sun sin 60))^(1/2.2)."""
    b = SceneBuilder()
    b.box((-50.0, -50.0, -1.0), (50.0, 50.0, 0.0), 0.5, texture=0.0)
    el = np.radians(60.0)
    light = Lighting(sun_dir_world=np.array([np.cos(el), 0.0, np.sin(el)]), ambient=0.3, sun=0.6, shadows=True)
    scene = b.build(SceneKind.OUTDOOR, light, (0, 1, 0, 1), 0.0, (1.0, 1.5))
    rays = np.array([[0.3, 0.1, -1.0], [0.0, 0.5, -1.0]])
    value = render_rays(scene, np.array([0.0, 0.0, 1.5]), np.eye(3), rays)
    expected = (0.5 * (0.3 + 0.6 * np.sin(el))) ** (1 / 2.2)
    assert value.dtype == np.float32
    np.testing.assert_allclose(value, expected, rtol=1e-6)
    # Read noise: the bottom rows of a panorama all see the floor: their spread is the noise sigma.
    pose = Pose(np.eye(3), np.array([0.0, 0.0, 1.5]))
    image = render_panorama(scene, pose, 256, 128, np.random.default_rng(3), noise_grey=2.0)
    floor = image[100:].astype(np.float64)
    assert floor.std() == pytest.approx(2.0, rel=0.1)
    assert floor.mean() == pytest.approx(255 * expected, abs=0.2)


def test_shadow_of_a_box_is_darker_and_colour_output_is_bgr():
    b = SceneBuilder()
    b.box((-50.0, -50.0, -1.0), (50.0, 50.0, 0.0), 0.5, texture=0.0)
    b.box((2.0, -0.5, 0.0), (3.0, 0.5, 3.0), 0.5, texture=0.0)  # a pillar between the floor and the sun
    el = np.radians(45.0)
    light = Lighting(sun_dir_world=np.array([np.cos(el), 0.0, np.sin(el)]), ambient=0.3, sun=0.6, shadows=True)
    scene = b.build(SceneKind.OUTDOOR, light, (0, 1, 0, 1), 0.0, (1.0, 1.5))
    origin = np.array([0.0, 0.0, 1.5])
    # Floor points at (1.5, 0, 0) (the pillar is between it and the sun) and (1.5, 3, 0) (in the sun).
    value = render_rays(scene, origin, np.eye(3), np.array([[1.5, 0.0, -1.5], [1.5, 3.0, -1.5]]))
    np.testing.assert_allclose(value, [(0.5 * 0.3) ** (1 / 2.2), (0.5 * (0.3 + 0.6 * np.sin(el))) ** (1 / 2.2)],
                               rtol=1e-6)
    image = render_panorama(scene, Pose(np.eye(3), origin), 64, 32, np.random.default_rng(0), color=True)
    assert image.shape == (32, 64, 3) and image.dtype == np.uint8


def _stitched_direction(point_cam: np.ndarray, sensor_centre: np.ndarray, sphere_m: float) -> np.ndarray:
    """The panorama direction d at which a stitched head shows ``point_cam``: the sensor at ``sensor_centre``
    sees it along its ray towards the stitching sphere point sphere_m * d (the stitching's definition)."""
    ray = (point_cam - sensor_centre) / np.linalg.norm(point_cam - sensor_centre)
    b = float(sensor_centre @ ray)  # |c + s ray| = sphere_m, s > 0
    s = -b + np.sqrt(b * b - (sensor_centre @ sensor_centre - sphere_m**2))
    return (sensor_centre + s * ray) / sphere_m


def test_stitched_head_shows_near_objects_with_parallax_and_far_ones_in_place():
    from drivers.sim import StitchConfig
    from drivers.sim.stitched import sensor_axes

    # An exaggerated 0.3 m sensor radius so the parallax is several pixels at 512 px; no gains or falloff.
    stitch = StitchConfig(sensor_radius_m=0.3, sphere_radius_m=20.0, blend_deg=0.0, vignetting=0.0, gain_sigma=0.0)
    camera = Pose(np.eye(3), np.array([0.0, 0.0, 1.5]))
    az = np.radians([20.0, -100.0])  # sensor 0 (20 deg off its axis) and sensor 4 (axis at -72 deg)
    near = np.stack([np.cos(az), np.sin(az), np.zeros(2)], axis=1) * 1.5
    far = np.array([[np.cos(np.radians(60.0)), np.sin(np.radians(60.0)), 0.0]]) * 20.0
    b = SceneBuilder()
    for c, half in zip(camera.apply(np.vstack([near, far])), (0.02, 0.02, 0.3), strict=True):
        b.box(c - half, c + half, 1.0, texture=0.0)
    scene = b.build(SceneKind.OUTDOOR, DARK, (0, 1, 0, 1), 0.0, (1.0, 1.5))
    width, height = 512, 256
    image = render_panorama(scene, camera, width, height, np.random.default_rng(0), noise_grey=0.0, stitch=stitch)
    centres = 0.3 * sensor_axes()[[0, 4, 1]]
    dirs = np.array([_stitched_direction(p, c, 20.0) for p, c in zip(np.vstack([near, far]), centres, strict=True)])
    expected, _ = Equirectangular(width, height).project(dirs)
    single, _ = Equirectangular(width, height).project(np.vstack([near, far]))
    found = _blob_centroids(image)
    assert len(found) == 3
    assert _match(found, expected).max() < 0.3
    shift = np.linalg.norm(expected - single, axis=1)
    assert shift[:2].min() > 3.0 and shift[2] < 0.05  # near: pixels of parallax; at the sphere: in place


def test_stitched_seams_cross_fade_two_sensors():
    from drivers.sim import StitchConfig
    from drivers.sim.stitched import split_rays

    stitch = StitchConfig(blend_deg=3.0)
    az = np.radians([0.0, 30.0, 34.5, 36.0, 37.5, 42.0])
    rays = np.stack([np.cos(az), np.sin(az), np.zeros(len(az))], axis=1)
    first, second = split_rays(rays, stitch, np.ones(5))
    np.testing.assert_allclose(first.weight + second.weight, 1.0)
    np.testing.assert_allclose(second.weight, [0.0, 0.0, 0.25, 0.5, 0.25, 0.0])
    np.testing.assert_allclose(np.linalg.norm(first.directions, axis=1), 1.0)
