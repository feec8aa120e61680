"""The head calibration without the SDK: the lens fit to a sampled rectification, the extrinsics' Euler
convention, the head file (YAML + maps) and the rig camera file reader taking it."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from drivers.ladybug5.errors import HeadCalibrationError
from drivers.ladybug5.head import (
    HeadCalibration,
    HeadSource,
    RectificationMaps,
    euler_zyx_matrix,
    fit_lens,
    sensor_from_sdk,
)
from drivers.ladybug5.head_file import load_head, save_head
from drivers.ladybug5.rig import LADYBUG5P_SIZE_PX, default_ladybug5_rig, load_rig, save_rig
from drivers.ladybug5.sdk_head import grid

WIDTH, HEIGHT = 96, 80
K = np.array([[70.0, 0.0, 47.3], [0.0, 70.4, 39.1], [0.0, 0.0, 1.0]])
D = np.array([-0.21, 0.045, 4e-4, -3e-4, -0.004])
FOCAL, CENTRE = 68.0, (47.8, 39.6)  # the rectified pinhole


def undistort(points: np.ndarray) -> np.ndarray:
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)
    return cv2.undistortPoints(points.reshape(-1, 1, 2), K, D, None, None, None, criteria).reshape(-1, 2)


def synthetic_maps(step: int = 8) -> RectificationMaps:
    """What ladybugRectifyPixel / UnrectifyPixel would give for a lens (K, D) and a rectified pinhole."""
    gx, gy = grid(WIDTH, step), grid(HEIGHT, step)
    xx, yy = np.meshgrid(gx, gy)
    points = np.stack([xx, yy], axis=-1).reshape(-1, 2)
    raw_to_rect = undistort(points) * FOCAL + CENTRE
    rays = np.column_stack([(points - CENTRE) / FOCAL, np.ones(len(points))])
    rect_to_raw = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, D)[0].reshape(-1, 2)
    shape = (len(gy), len(gx), 2)
    return RectificationMaps(gx, gy, raw_to_rect.reshape(shape), rect_to_raw.reshape(shape))


def test_the_lens_fit_recovers_an_opencv_model():
    sensor = sensor_from_sdk("cam0", (WIDTH, HEIGHT), FOCAL, CENTRE, (0.1, 0.2, 0.3, 0.01, 0.02, 0.03),
                             synthetic_maps())
    np.testing.assert_allclose(sensor.lens.K, K, atol=1e-4)
    np.testing.assert_allclose(sensor.lens.D, D, atol=1e-5)
    assert sensor.lens.rms_px < 1e-4 and sensor.lens.points == 13 * 11 and not sensor.lens.poor


def test_a_fit_that_folds_inside_the_field_of_view_is_poor():
    xy = np.random.default_rng(0).uniform(-2.0, 2.0, (200, 2))
    r2 = np.sum(xy**2, axis=1, keepdims=True)
    raw = xy * (1 - 0.2 * r2) * 50 + 40  # a cubic that turns back at r ~ 1.3 < 2.8
    assert fit_lens(raw, xy, 50.0, (40.0, 40.0)).poor


def test_the_extrinsics_follow_craigs_zyx_convention():
    rx, ry, rz = 0.3, -1.1, 2.0
    s, c = np.sin, np.cos
    documented = np.array([  # ladybuggeom.h, ladybugGetCameraUnitExtrinsics
        [c(rz) * c(ry), c(rz) * s(ry) * s(rx) - s(rz) * c(rx), c(rz) * s(ry) * c(rx) + s(rz) * s(rx)],
        [s(rz) * c(ry), s(rz) * s(ry) * s(rx) + c(rz) * c(rx), s(rz) * s(ry) * c(rx) - c(rz) * s(rx)],
        [-s(ry), c(ry) * s(rx), c(ry) * c(rx)]])
    np.testing.assert_allclose(euler_zyx_matrix(rx, ry, rz), documented, atol=1e-14)


def test_rectification_maps_densify_for_remap():
    maps = synthetic_maps(step=4)
    map_x, map_y = maps.dense_rect_to_raw(WIDTH, HEIGHT)
    assert map_x.shape == (HEIGHT, WIDTH) and map_x.dtype == np.float32
    i, j = 8, 12  # a grid point: the dense map holds it exactly
    np.testing.assert_allclose([map_x[i, j], map_y[i, j]], maps.rect_to_raw[2, 3], atol=1e-4)


def factory_head() -> HeadCalibration:
    maps = synthetic_maps()
    sensors = tuple(sensor_from_sdk(f"cam{c}", (WIDTH, HEIGHT), FOCAL, CENTRE,
                                    (0.01 * c, np.pi / 2, np.radians(72 * c), 0.045, 0.0, 0.0), maps)
                    for c in range(6))
    return HeadCalibration(sensors, HeadSource.FACTORY, "camera 17092345 (test)", 17092345)


def test_the_head_file_round_trips_and_is_a_rig_camera_file(tmp_path):
    head = factory_head()
    save_head(head, tmp_path / "head.yaml")
    assert (tmp_path / "head.maps.npz").exists()
    back = load_head(tmp_path / "head.yaml")
    assert (back.source, back.serial, back.description) == (HeadSource.FACTORY, 17092345, head.description)
    for a, b in zip(head.sensors, back.sensors, strict=True):
        np.testing.assert_allclose(b.lens.K, a.lens.K, atol=1e-12)
        np.testing.assert_allclose(b.lens.D, a.lens.D, atol=1e-12)
        np.testing.assert_allclose(b.extrinsics, a.extrinsics, atol=1e-12)
        np.testing.assert_allclose(b.R_head_camera, a.R_head_camera, atol=1e-9)
        assert b.lens.rms_px == a.lens.rms_px and b.maps is not None and a.maps is not None
        np.testing.assert_array_equal(b.maps.raw_to_rect, a.maps.raw_to_rect)
    rig = load_rig(tmp_path / "head.yaml")  # camera.sdk.rig_file may name the head file
    assert rig.model == head.description and rig.cameras[3].width == WIDTH
    np.testing.assert_allclose(rig.cameras[3].t_head_camera_m, head.sensors[3].t_head_camera_m, atol=1e-12)


def test_a_plain_rig_file_is_a_head_of_unknown_origin(tmp_path):
    save_rig(default_ladybug5_rig(LADYBUG5P_SIZE_PX), tmp_path / "rig.yaml")
    head = load_head(tmp_path / "rig.yaml")
    assert head.source is HeadSource.FILE and head.sizes == ((2464, 2048),) * 6
    with pytest.raises(HeadCalibrationError, match="cannot read head calibration file"):
        load_head(tmp_path / "absent.yaml")


def test_the_nominal_head_says_what_it_is():
    head = HeadCalibration.nominal(LADYBUG5P_SIZE_PX)
    assert head.source is HeadSource.NOMINAL and "not a factory calibration" in head.description
    assert head.sizes == ((2464, 2048),) * 6 and head.to_rig().cameras[0].K[0, 2] == pytest.approx(1231.5)
