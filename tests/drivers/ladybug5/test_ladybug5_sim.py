"""Stitching against the simulator: six rendered pinhole views, stitched, vs. the directly rendered panorama."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from ladybug5_helpers import scaled_rig
from scipy import ndimage

from drivers.ladybug5.head import HeadSource
from drivers.ladybug5.rig import default_ladybug5_rig, scaled_ladybug5_rig
from drivers.ladybug5.sim import SimFrameSource, pixel_rays_optical
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher
from drivers.sim import SceneKind, render_panorama
from drivers.sim.rig import PAPER_T_CAMERA_LIDAR, make_scene, place_rig, rng_for

W, H = 512, 256
RIG = scaled_rig(default_ladybug5_rig(), 1 / 8)  # 306 x 256 px cameras
RADIUS_M = 3.0  # about the distance of the walls in the simulated rooms


@pytest.fixture(scope="module")
def scene_and_pose():
    scene = make_scene(SceneKind.INDOOR, 0, 0)
    pose = place_rig(scene, rng_for(SceneKind.INDOOR, 0, 0, "pose"), PAPER_T_CAMERA_LIDAR)
    return scene, pose


@pytest.fixture(scope="module")
def rendered(scene_and_pose):
    """(six camera images, the simulator's own panorama from the head centre), noise-free."""
    scene, pose = scene_and_pose
    source = SimFrameSource(scene, [pose], Stitcher(RIG, PanoramaSpec(W, H, RADIUS_M)), np.random.default_rng(0), 0.0)
    reference = render_panorama(scene, pose, W, H, np.random.default_rng(0), noise_grey=0.0, supersample=1)
    return source.camera_images(pose), reference


def test_pixel_rays_reproject_onto_their_pixels():
    camera = RIG.cameras[0]
    rays = pixel_rays_optical(camera)
    uv, valid = camera.project(rays)
    jj, ii = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    interior = (jj > 0) & (jj < camera.width - 1) & (ii > 0) & (ii < camera.height - 1)
    assert valid[interior.ravel()].all()  # border pixels may reproject a hair outside the image
    np.testing.assert_allclose(uv, np.stack([jj.ravel(), ii.ravel()], axis=1), atol=1e-3)


def test_stitched_panorama_matches_the_simulators_panorama(rendered):
    images, reference = rendered
    stitcher = Stitcher(RIG, PanoramaSpec(W, H, RADIUS_M))
    pano = stitcher.stitch(images)[..., 0]
    covered = stitcher.coverage
    mae = np.abs(pano.astype(float) - reference)[covered].mean()
    assert mae < 2.0  # grey levels (0..255)
    # Edges away from the overlaps (where blending acts) are within 1-2 px of the reference's. Not all within 1 px:
    # the cameras sit 6.1 cm (the top one 7.6 cm) off the head centre, and a ceiling 1-2 m above the head, off the
    # 3 m sphere, moves by up to ~1.5 px at this size (94.7 % within 1 px; 98 % when they sat 4.5 cm off).
    away = covered & ~ndimage.binary_dilation(stitcher.overlap | ~covered, iterations=3)
    edges_ref = (cv2.Canny(reference, 100, 200) > 0) & away
    distance_to_stitched_edge = ndimage.distance_transform_edt(cv2.Canny(pano, 50, 100) == 0)
    assert edges_ref.sum() > 500
    assert np.mean(distance_to_stitched_edge[edges_ref] <= 1.0) > 0.93
    assert np.mean(distance_to_stitched_edge[edges_ref] <= 2.0) > 0.99


def test_stitching_radius_models_parallax(rendered):
    """Cameras sit 6.1-7.6 cm off the head centre: a sphere at the walls' distance fits better than infinity."""
    images, reference = rendered

    def mae(radius_m: float) -> float:
        stitcher = Stitcher(RIG, PanoramaSpec(W, H, radius_m))
        return float(np.abs(stitcher.stitch(images)[..., 0].astype(float) - reference)[stitcher.coverage].mean())

    assert mae(RADIUS_M) < 0.75 * mae(math.inf)


def test_sim_frame_source_times_and_frames(scene_and_pose):
    scene, pose = scene_and_pose
    small = scaled_rig(default_ladybug5_rig(), 1 / 32)
    source = SimFrameSource(
        scene,
        [pose, pose],
        Stitcher(small, PanoramaSpec(64, 32)),
        np.random.default_rng(1),
        frame_period_s=0.1,
        device_start_s=50.0,
        host_offset_s=1000.0,
    )
    frames = list(source.frames())
    assert [(f.sequence_id, f.device_time_s, f.host_time_s) for f in frames] == [(0, 50.0, 1050.0), (1, 50.1, 1050.1)]
    assert frames[0].image.shape == (32, 64, 3) and frames[0].image.dtype == np.uint8
    assert not np.array_equal(frames[0].image, frames[1].image)  # independent read noise per frame


def test_sim_frame_source_gives_each_panorama_with_its_sensor_images(scene_and_pose):
    scene, pose = scene_and_pose
    small = scaled_ladybug5_rig(40)
    stitcher = Stitcher(small, PanoramaSpec(64, 32))
    source = SimFrameSource(scene, [pose], stitcher, np.random.default_rng(2), frame_period_s=0.1,
                            device_start_s=5.0, host_offset_s=100.0)
    (pano, sensors), = source.frames_with_sensors()
    assert (sensors.device_time_s, sensors.host_time_s, sensors.sequence_id) == (5.0, 105.0, 0)
    assert sensors.head.source is HeadSource.FACTORY and sensors.head.sizes == tuple((40, 33) for _ in range(6))
    np.testing.assert_array_equal(pano.image, stitcher.stitch(list(sensors.images)))
    for sensor, camera in zip(sensors.head.sensors, small.cameras, strict=True):
        np.testing.assert_allclose(sensor.R_head_camera, camera.R_head_camera, atol=1e-12)
        np.testing.assert_allclose(sensor.lens.K, camera.K)


def test_the_scaled_head_keeps_the_nominal_fields_of_view():
    nominal, small = default_ladybug5_rig(), scaled_ladybug5_rig(153)  # 1/16 of the width
    for big, little in zip(nominal.cameras, small.cameras, strict=True):
        corner = cv2.undistortPoints(np.array([[[0.0, 0.0]]]), big.K, big.D).ravel()
        scaled = cv2.undistortPoints(np.array([[[-0.5 + 0.5 / 16, -0.5 + 0.5 / 16]]]), little.K, little.D).ravel()
        np.testing.assert_allclose(scaled, corner, rtol=0.01)
        np.testing.assert_array_equal(little.R_head_camera, big.R_head_camera)
    assert (small.cameras[0].width, small.cameras[0].height) == (153, 128)
