"""Rig camera file and stitching geometry (the scene-based stitching test is test_ladybug5_sim.py)."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from ladybug5_helpers import pixel_rays_head, scaled_rig, smooth_field

from calib.camera import Equirectangular
from calib.geometry import matrix_to_quaternion_xyzw, matrix_to_rpy_deg, rpy_deg_to_matrix
from drivers import geometry as rotation
from drivers.ladybug5.errors import Ladybug5Error, RigFileError
from drivers.ladybug5.head import HeadCalibration, euler_zyx_matrix
from drivers.ladybug5.rig import (
    LADYBUG5P_SIZE_PX,
    default_ladybug5_rig,
    load_rig,
    rig_from_yaml,
    rig_to_yaml,
    save_rig,
)
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher, panorama_rays

DEFAULT_RIG_FILE = Path(__file__).resolve().parents[3] / "drivers" / "ladybug5" / "ladybug5_rig.yaml"


def test_local_rotation_helpers_match_calib():
    rng = np.random.default_rng(1)
    for rpy in rng.uniform([-180, -89, -180], [180, 89, 180], size=(200, 3)):
        m = rpy_deg_to_matrix(rpy)
        np.testing.assert_allclose(rotation.rpy_deg_to_matrix(rpy), m, atol=1e-12)
        np.testing.assert_allclose(rotation.matrix_to_rpy_deg(m), matrix_to_rpy_deg(m), atol=1e-7)
        np.testing.assert_allclose(rotation.matrix_to_quaternion_xyzw(m), matrix_to_quaternion_xyzw(m), atol=1e-9)


# A public factory calibration of a real Ladybug5 (LD5-U3-51S5C-44, serial 15402620, as the SDK's configuration
# lists it): per camera rotX, rotY, rotZ (rad; R = Rz Ry Rx maps the camera's frame into the head's) and transX,
# transY, transZ (m). docs/ladybug5.md, "Default head".
REAL_UNIT_EXTRINSICS = np.array([
    [-2.151942, 1.566552, -2.151938, 0.061564, -0.000836, -0.000023],
    [-2.806324, 1.564830, 2.220612, 0.017904, -0.058481, -0.000240],
    [-1.815490, 1.566224, 1.958800, -0.050197, -0.035245, -0.000097],
    [2.320270, 1.569067, -1.446774, -0.048999, 0.036651, 0.000180],
    [-1.787905, 1.563776, -0.526615, 0.019728, 0.057911, 0.000180],
    [0.000197, 0.001386, -3.137179, 0.000320, -0.000344, 0.076026],
])


def test_a_real_ladybug5s_cameras_lie_on_their_side():
    """What the nominal head copies, read from the real unit's numbers: camera 0 looks along +x with its image
    columns down (-z) and rows along +y; camera i looks out at -72 deg * i; the top camera's columns run along -x,
    its rows along -y."""
    rotations = [euler_zyx_matrix(*e[:3]) for e in REAL_UNIT_EXTRINSICS]
    np.testing.assert_allclose(rotations[0], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=0.005)
    for i, r in enumerate(rotations[:5]):
        azimuth = np.degrees(np.arctan2(r[1, 2], r[0, 2]))
        assert abs((azimuth + 72.0 * i + 180.0) % 360.0 - 180.0) < 1.0
        assert r[:, 0] @ [0, 0, -1] > 0.9999
    np.testing.assert_allclose(rotations[5][:, :2], [[-1, 0], [0, -1], [0, 0]], atol=0.005)


def test_the_nominal_head_is_a_ladybug5():
    rig = default_ladybug5_rig()
    assert len(rig.cameras) == 6
    side, top = rig.cameras[:5], rig.cameras[5]
    for i, c in enumerate(side):
        axis, columns, rows = c.R_head_camera[:, 2], c.R_head_camera[:, 0], c.R_head_camera[:, 1]
        np.testing.assert_allclose(axis, [np.cos(np.radians(-72.0 * i)), np.sin(np.radians(-72.0 * i)), 0.0],
                                   atol=1e-12)
        np.testing.assert_allclose(columns, [0, 0, -1], atol=1e-12)  # lying on its side: columns run down
        assert abs(rows[2]) < 1e-12  # and rows along the horizontal
        np.testing.assert_allclose(c.t_head_camera_m / np.linalg.norm(c.t_head_camera_m), axis, atol=1e-12)
        assert 0.060 <= np.linalg.norm(c.t_head_camera_m) <= 0.062  # two real units: 6.08-6.16 cm
    np.testing.assert_allclose(top.R_head_camera, [[-1, 0, 0], [0, -1, 0], [0, 0, 1]], atol=1e-12)
    assert top.t_head_camera_m[:2] == pytest.approx([0, 0]) and 0.074 <= top.t_head_camera_m[2] <= 0.077
    for c, real in zip(rig.cameras, REAL_UNIT_EXTRINSICS, strict=True):  # within the spread between units
        assert np.degrees(np.arccos((np.trace(c.R_head_camera.T @ euler_zyx_matrix(*real[:3])) - 1) / 2)) < 2.0
        assert np.linalg.norm(c.t_head_camera_m - real[3:]) < 0.002
        assert np.linalg.det(c.R_head_camera) == pytest.approx(1.0)
        assert c.K[0, 0] == pytest.approx(4.4e-3 / 3.45e-6)  # the raw image's: a 4.4 mm lens on 3.45 um pixels


def test_the_nominal_heads_rectified_pinhole_is_a_real_units():
    for size in ((2448, 2048), LADYBUG5P_SIZE_PX):
        head = HeadCalibration.nominal(size)
        for s in head.sensors:  # the SDK's rectified focal length at 2448x2048: 443-464 px in two units
            assert 443.0 <= s.focal_px * 2448 / size[0] <= 464.0


def test_rig_file_round_trip_and_shipped_default(tmp_path):
    rig = default_ladybug5_rig()
    save_rig(rig, tmp_path / "rig.yaml")
    back = load_rig(tmp_path / "rig.yaml")
    shipped = load_rig(DEFAULT_RIG_FILE)
    for a, b, c in zip(rig.cameras, back.cameras, shipped.cameras, strict=True):
        for other in (b, c):
            np.testing.assert_allclose(other.K, a.K)
            np.testing.assert_allclose(other.D, a.D)
            np.testing.assert_allclose(other.R_head_camera, a.R_head_camera, atol=1e-12)
            np.testing.assert_allclose(other.t_head_camera_m, a.t_head_camera_m, atol=1e-12)


def test_rig_file_accepts_rpy_and_rejects_bad_entries():
    data = rig_to_yaml(default_ladybug5_rig())
    entry = data["cameras"][1]["T_head_camera"]
    del entry["matrix"]
    expected = default_ladybug5_rig().cameras[1].R_head_camera
    np.testing.assert_allclose(rig_from_yaml(data, "x").cameras[1].R_head_camera, expected, atol=1e-9)
    data["cameras"][2]["K"] = [[1, 0], [0, 1]]
    with pytest.raises(RigFileError, match=r"cameras\[2\]"):
        rig_from_yaml(data, "rig.yaml")
    with pytest.raises(RigFileError, match="cameras"):
        rig_from_yaml({"model": "x"}, "rig.yaml")


def test_projection_matches_opencv():
    camera = default_ladybug5_rig().cameras[2]
    rng = np.random.default_rng(3)
    points = rng.uniform([-1, -1, 0.5], [1, 1, 2], size=(500, 3))
    uv, valid = camera.project(points)
    expected, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), camera.K, camera.D)
    np.testing.assert_allclose(uv, expected.reshape(-1, 2), atol=1e-6)
    assert valid.any() and not valid.all()


def test_panorama_rays_follow_the_project_convention():
    w, h = 64, 32
    rays = panorama_rays(w, h).reshape(-1, 3)
    jj, ii = np.meshgrid(np.arange(w), np.arange(h))
    expected = Equirectangular(w, h).back_project(np.stack([jj.ravel(), ii.ravel()], axis=1).astype(float))
    np.testing.assert_allclose(rays, expected, atol=1e-12)


def test_direction_only_stitch_reproduces_a_field_of_directions():
    rig = scaled_rig(default_ladybug5_rig(), 1 / 8)
    stitcher = Stitcher(rig, PanoramaSpec(256, 128, math.inf))
    images = [smooth_field(pixel_rays_head(c)).reshape(c.height, c.width).astype(np.float32) for c in rig.cameras]
    pano = stitcher.stitch(images)
    expected = smooth_field(panorama_rays(256, 128))
    assert np.abs(pano - expected)[stitcher.coverage].max() < 0.5  # of a 0..255 range
    # Everything above 45 deg below the horizon is seen; the nadir under the head is not.
    rows = np.arange(128)
    assert stitcher.coverage[rows < 96].all()
    assert not stitcher.coverage[-1].any()


def test_stitch_keeps_dtype_and_checks_image_sizes():
    rig = scaled_rig(default_ladybug5_rig(), 1 / 16)
    stitcher = Stitcher(rig, PanoramaSpec(128, 64))
    images = [np.full((c.height, c.width, 3), 200, np.uint8) for c in rig.cameras]
    pano = stitcher.stitch(images)
    assert pano.dtype == np.uint8 and pano.shape == (64, 128, 3)
    assert np.all(pano[stitcher.coverage] == 200)  # weights sum to one wherever a camera sees
    with pytest.raises(Ladybug5Error, match="cam0"):
        stitcher.stitch([np.zeros((5, 5, 3), np.uint8)] * 6)
