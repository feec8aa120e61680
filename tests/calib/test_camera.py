"""Checks of calib/camera.py against hand geometry, OpenCV and finite differences."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from calib.camera import Equirectangular, Fisheye, Mounted, Pinhole, project_rotated
from calib.errors import GeometryError
from calib.geometry import Transform
from tests.testdata import PINHOLE_FRAME

W, H = 2048, 1024
PANO = Equirectangular(W, H)

coordinate = st.floats(-50.0, 50.0, allow_nan=False)
points = st.tuples(*[coordinate] * 3).map(np.array).filter(lambda p: np.linalg.norm(p) > 1e-3)


def spherical(theta: float, phi: float, r: float = 1.0) -> np.ndarray:
    """Point at azimuth theta (from +x towards +y) and polar angle phi (from +z), camera frame."""
    return r * np.array([[np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta), np.cos(phi)]])


def wrap_u(du: np.ndarray, width: float = W) -> np.ndarray:
    return (du + width / 2) % width - width / 2


# --- Equirectangular: conventions -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("point", "uv"),
    [
        ([1.0, 0.0, 0.0], (W / 2, H / 2)),  # forward: image centre
        ([0.0, 1.0, 0.0], (W / 4, H / 2)),  # left: a quarter of the width
        ([0.0, -1.0, 0.0], (3 * W / 4, H / 2)),  # right
        ([-1.0, 0.0, 0.0], (0.0, H / 2)),  # behind: the seam
        ([0.0, 0.0, 5.0], (None, 0.0)),  # zenith: top row, any azimuth
        ([0.0, 0.0, -5.0], (None, H)),  # nadir
        ([2.0, 0.0, 2.0], (W / 2, H / 4)),  # 45 deg up, forward
    ],
)
def test_equirectangular_conventions(point: list[float], uv: tuple[float | None, float]) -> None:
    got, valid = PANO.project(np.array([point]))
    assert valid[0]
    if uv[0] is not None:
        assert got[0, 0] == pytest.approx(uv[0], abs=1e-9)
    assert got[0, 1] == pytest.approx(uv[1], abs=1e-9)


def test_pixel_centres_are_at_integer_coordinates() -> None:
    # Pixel (row i, column j) looks at polar angle pi i / h and azimuth pi - 2 pi j / w (eqs. 15-16
    # solved by hand), so its ray projects to exactly (u, v) = (j, i).
    rows, cols = np.array([1, 100, 512, 1023]), np.array([0, 7, 1024, 2047])
    rays = np.concatenate(
        [spherical(np.pi - 2 * np.pi * j / W, np.pi * i / H) for i, j in zip(rows, cols, strict=True)]
    )
    uv, _ = PANO.project(rays)
    np.testing.assert_allclose(uv, np.stack([cols, rows], axis=1), atol=1e-9)
    pixel_centres = np.stack([cols, rows], axis=1).astype(np.float64)
    np.testing.assert_allclose(PANO.back_project(pixel_centres), rays, atol=1e-12)


def test_origin_is_invalid() -> None:
    _, valid = PANO.project(np.zeros((1, 3)))
    assert not valid[0]


# --- Equirectangular: round trips ---------------------------------------------------------------------


@given(points)
def test_project_then_back_project_gives_the_ray(point: np.ndarray) -> None:
    uv, valid = PANO.project(point[None])
    assert valid[0]
    assert 0.0 <= uv[0, 0] < W and 0.0 <= uv[0, 1] <= H
    # acos(z / r) (eq. 13) keeps only ~1e-8 rad near the poles: 3e-6 px, far below anything that matters.
    np.testing.assert_allclose(PANO.back_project(uv)[0], point / np.linalg.norm(point), atol=2e-8)


@given(st.floats(0.0, W, exclude_max=True), st.floats(0.01, H - 0.01))
def test_back_project_then_project_gives_the_pixel(u: float, v: float) -> None:
    uv, _ = PANO.project(PANO.back_project(np.array([[u, v]])))
    assert abs(wrap_u(uv[0, 0] - u)) < 1e-8
    assert abs(uv[0, 1] - v) < 1e-8


# --- Equirectangular: seam and poles ----------------------------------------------------------------


@pytest.mark.parametrize("delta", [1e-6, 1e-3, 0.01])
def test_seam_behind_the_camera(delta: float) -> None:
    # Just left of -x (azimuth pi - delta) and just right of it (azimuth -pi + delta): 2 delta apart.
    left = spherical(np.pi - delta, np.pi / 2)
    right = spherical(-np.pi + delta, np.pi / 2)
    uv, _ = PANO.project(np.concatenate([left, right]))
    px = W * delta / (2 * np.pi)
    assert uv[0, 0] == pytest.approx(px, abs=1e-6)  # near u = 0
    assert uv[1, 0] == pytest.approx(W - px, abs=1e-6)  # near u = w
    d = PANO.displacement(uv[:1], uv[1:])
    np.testing.assert_allclose(d, [[2 * px, 0.0]], atol=1e-6)  # across the seam, not w - 2 px


@pytest.mark.parametrize("v", [0.5, 3.0])
def test_displacement_over_the_north_pole(v: float) -> None:
    # Two points at polar angle phi = pi v / h on opposite meridians are 2 phi apart over the pole,
    # i.e. 2 v pixels of v; the direct route would be w/2 pixels long.
    centre = np.array([[300.0, v]])
    pixel = np.array([[300.0 + W / 2, v]])
    d = PANO.displacement(pixel, centre)
    assert np.linalg.norm(d) == pytest.approx(2 * v, abs=1e-9)


@pytest.mark.parametrize("v", [0.5, 3.0])
def test_displacement_over_the_south_pole(v: float) -> None:
    centre = np.array([[1700.0, H - v]])
    pixel = np.array([[1700.0 - W / 2, H - v]])
    assert np.linalg.norm(PANO.displacement(pixel, centre)) == pytest.approx(2 * v, abs=1e-9)


def test_pole_neighbours_through_projection() -> None:
    # Points 0.1 deg from +z on opposite sides are 0.2 deg apart: 0.2 deg * h / pi pixels.
    a = spherical(0.3, np.radians(0.1))
    b = spherical(0.3 + np.pi, np.radians(0.1))
    uv, _ = PANO.project(np.concatenate([a, b]))
    assert uv[0, 1] < 1.0 and uv[1, 1] < 1.0
    d = PANO.displacement(uv[:1], uv[1:])
    assert np.linalg.norm(d) == pytest.approx(np.radians(0.2) * H / np.pi, rel=1e-9)


uv_anywhere = st.tuples(st.floats(0.0, W, exclude_max=True), st.floats(0.0, H)).map(np.array)


@given(uv_anywhere, uv_anywhere)
def test_displacement_is_shortest_and_minus_identity(pixel: np.ndarray, centre: np.ndarray) -> None:
    d = PANO.displacement(pixel[None], centre[None])[0]
    direct = np.array([wrap_u(pixel[0] - centre[0]), pixel[1] - centre[1]])
    assert np.linalg.norm(d) <= np.linalg.norm(direct) + 1e-9
    # d(displacement)/d(centre) = -I on every route. Where two routes tie, the route can change on one
    # side of the centre, but one one-sided difference always stays on the route taken at the centre.
    h = 1e-6
    for step in np.eye(2) * h:
        forward = PANO.displacement(pixel[None], (centre + step)[None])[0] - d
        backward = d - PANO.displacement(pixel[None], (centre - step)[None])[0]
        assert min(np.abs(forward + step).max(), np.abs(backward + step).max()) < 1e-7


def test_displacement_vector_over_the_pole() -> None:
    # Its length is v_p + v_c; with derivative -1 in v_c the vertical component must be -(v_p + v_c).
    d = PANO.displacement(np.array([[1324.0, 2.0]]), np.array([[300.0, 3.0]]))
    np.testing.assert_allclose(d, [[0.0, -5.0]], atol=1e-12)


# --- Equirectangular: Jacobian and pixel area -------------------------------------------------------


def finite_difference_jacobian(project, point: np.ndarray, h: float, wrap: float | None = None) -> np.ndarray:
    cols = []
    for e in np.eye(3):
        plus, _ = project((point + h * e)[None])
        minus, _ = project((point - h * e)[None])
        diff = plus[0] - minus[0]
        if wrap is not None:
            diff[0] = wrap_u(diff[0], wrap)
        cols.append(diff / (2 * h))
    return np.stack(cols, axis=1)


@given(points.filter(lambda p: np.hypot(p[0], p[1]) > 0.05 * np.linalg.norm(p)))
def test_equirectangular_jacobian_matches_finite_differences(point: np.ndarray) -> None:
    r = np.linalg.norm(point)
    numeric = finite_difference_jacobian(PANO.project, point, 1e-6 * r, wrap=W)
    analytic = PANO.project_jacobian(point[None])[0]
    np.testing.assert_allclose(analytic, numeric, atol=1e-4 * np.abs(analytic).max())


@given(st.floats(0.1 * H, 0.9 * H))
def test_pixel_area_ratio_is_the_solid_angle_ratio(v: float) -> None:
    # A pixel spans 2 pi / w of azimuth and [v - 1/2, v + 1/2] pi / h of polar angle; integrating
    # sin(phi) gives its solid angle (2 pi / w) (cos phi_top - cos phi_bottom).
    def solid_angle(vv: float) -> float:
        return 2 * np.pi / W * (np.cos(np.pi * (vv - 0.5) / H) - np.cos(np.pi * (vv + 0.5) / H))

    ratio = PANO.pixel_area_ratio(np.array([[10.0, v]]))[0]
    assert ratio == pytest.approx(solid_angle(H / 2) / solid_angle(v), rel=1e-9)


def test_pixels_per_radian_at_the_equator() -> None:
    uv, _ = PANO.project(np.concatenate([spherical(0.0, np.pi / 2), spherical(1e-3, np.pi / 2)]))
    assert abs(uv[1, 0] - uv[0, 0]) == pytest.approx(1e-3 * PANO.pixels_per_radian, rel=1e-9)
    assert PANO.pixels_per_radian == pytest.approx(W / (2 * np.pi))


# --- Pinhole --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def calibration() -> dict:
    with (PINHOLE_FRAME / "calibration.yaml").open() as fh:
        return yaml.safe_load(fh)


@pytest.fixture(scope="module")
def pinhole(calibration: dict) -> Pinhole:
    c = calibration["camera"]
    return Pinhole(np.array(c["K"]), np.array(c["D"]), c["width"], c["height"])


@pytest.fixture(scope="module")
def lidar_points() -> np.ndarray:
    """x y z of the real 64-ring cloud (layout documented in the sample README), every 4th point."""
    raw = (PINHOLE_FRAME / "cloud.pcd").read_bytes()
    body = raw[raw.index(b"DATA binary\n") + len(b"DATA binary\n") :]
    dtype = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2")])
    data = np.frombuffer(body, dtype=dtype)
    return np.ascontiguousarray(np.stack([data["x"], data["y"], data["z"]], axis=1)[::4], dtype=np.float64)


def test_pinhole_project_matches_opencv_on_real_points(
    pinhole: Pinhole, calibration: dict, lidar_points: np.ndarray
) -> None:
    matrix = np.array(calibration["T_camera_lidar"]["matrix"])
    rotation, t = matrix[:3, :3], matrix[:3, 3]
    points_cam = lidar_points @ rotation.T + t
    uv, valid = pinhole.project(points_cam)
    expected, _ = cv2.projectPoints(points_cam, np.zeros(3), np.zeros(3), pinhole.K, pinhole.D)
    expected = expected.reshape(-1, 2)
    assert valid.sum() > 1000
    np.testing.assert_allclose(uv[valid], expected[valid], atol=1e-6)
    inside = (expected[:, 0] >= 0) & (expected[:, 0] < 1920) & (expected[:, 1] >= 0) & (expected[:, 1] < 1200)
    # Every point in front that OpenCV puts inside the image is valid; no point behind is.
    assert valid[inside & (points_cam[:, 2] > 0.1)].all()
    assert not valid[points_cam[:, 2] <= 0].any()


@settings(max_examples=50)
@given(st.floats(-0.45, 0.45), st.floats(-0.3, 0.3), st.floats(0.5, 80.0))
def test_pinhole_project_matches_opencv(pinhole: Pinhole, x: float, y: float, z: float) -> None:
    cam = pinhole
    point = np.array([[x * z, y * z, z]])
    uv, valid = cam.project(point)
    expected, _ = cv2.projectPoints(point, np.zeros(3), np.zeros(3), cam.K, cam.D)
    assert valid[0]
    np.testing.assert_allclose(uv, expected.reshape(-1, 2), atol=1e-6)


@pytest.mark.parametrize("point", [[0.0, 0.0, -1.0], [0.5, 0.2, -3.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
def test_points_behind_the_camera_are_invalid(pinhole: Pinhole, point: list[float]) -> None:
    _, valid = pinhole.project(np.array([point]))
    assert not valid[0]


def test_far_off_axis_points_are_invalid(pinhole: Pinhole) -> None:
    # 80 deg off axis is far outside a 48 deg wide image; the polynomial must not fold it back in.
    _, valid = pinhole.project(np.array([[np.tan(np.radians(80.0)), 0.0, 1.0]]))
    assert not valid[0]


@settings(max_examples=50)
@given(st.floats(-0.5, 0.5), st.floats(-0.3, 0.3), st.floats(0.5, 50.0))
def test_pinhole_jacobian_matches_finite_differences(pinhole: Pinhole, x: float, y: float, z: float) -> None:
    cam = pinhole
    point = np.array([x * z, y * z, z])
    numeric = finite_difference_jacobian(cam.project, point, 1e-6 * z)
    analytic = cam.project_jacobian(point[None])[0]
    np.testing.assert_allclose(analytic, numeric, rtol=1e-6, atol=1e-6 * np.abs(analytic).max())


def test_pinhole_back_project_round_trip(pinhole: Pinhole) -> None:
    u, v = np.meshgrid(np.linspace(0, 1919, 25), np.linspace(0, 1199, 16))
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    rays = pinhole.back_project(uv)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0, atol=1e-12)
    assert (rays[:, 2] > 0).all()
    again, valid = pinhole.project(3.0 * rays)
    assert valid.all()
    np.testing.assert_allclose(again, uv, atol=1e-3)


def test_pinhole_back_project_of_projection_is_the_ray(pinhole: Pinhole) -> None:
    points = np.array([[0.0, 0.0, 2.0], [1.0, -0.5, 4.0], [-3.0, 2.0, 9.0]])
    uv, _ = pinhole.project(points)
    rays = points / np.linalg.norm(points, axis=1)[:, None]
    np.testing.assert_allclose(pinhole.back_project(uv), rays, atol=1e-7)


def test_pinhole_area_ratio(pinhole: Pinhole) -> None:
    principal = pinhole.K[:2, 2][None]
    assert pinhole.pixel_area_ratio(principal)[0] == pytest.approx(1.0, abs=1e-12)
    off_axis = np.array([[0.0, 0.0], [1919.0, 1199.0], [1500.0, 656.0], [924.0, 100.0]])
    assert (pinhole.pixel_area_ratio(off_axis) > 1.0).all()


def test_pinhole_area_ratio_is_the_solid_angle_ratio() -> None:
    # Without distortion, a pixel's solid angle is the area of the quad its corner rays cut out of
    # the unit sphere; compare the ratio to the principal point's by explicit corner rays.
    k = np.array([[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]])
    cam = Pinhole(k, np.zeros(5), 640, 480)

    def solid_angle(u: float, v: float) -> float:
        corners = np.array([[u - 0.5, v - 0.5], [u + 0.5, v - 0.5], [u + 0.5, v + 0.5], [u - 0.5, v + 0.5]])
        rays = np.concatenate([(corners - k[:2, 2]) / 800.0, np.ones((4, 1))], axis=1)
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        return 0.5 * np.linalg.norm(np.cross(rays[2] - rays[0], rays[3] - rays[1]))

    for u, v in [(0.0, 0.0), (600.0, 100.0), (320.0, 470.0)]:
        expected = solid_angle(320.0, 240.0) / solid_angle(u, v)
        assert cam.pixel_area_ratio(np.array([[u, v]]))[0] == pytest.approx(expected, rel=1e-4)


def test_pinhole_pixels_per_radian(pinhole: Pinhole) -> None:
    # A 1 mrad turn about the optical centre moves the principal point's image by ~fx * 1e-3 px.
    uv, _ = pinhole.project(np.array([[0.0, 0.0, 1.0], [np.tan(1e-3), 0.0, 1.0]]))
    assert uv[1, 0] - uv[0, 0] == pytest.approx(pinhole.K[0, 0] * 1e-3, rel=1e-3)
    assert pinhole.pixels_per_radian == pytest.approx(np.sqrt(2117.31 * 2113.29))


# --- A sensor of a multi-camera head ---------------------------------------------------------------------


def _mounted(pinhole: Pinhole) -> Mounted:
    """The sample's camera as a head sensor turned 72 deg about the head's up axis, 4 cm off its centre
    (a Ladybug side camera), its optical axis along head x rotated by that yaw."""
    T_head_sensor = Transform.from_rpy_xyz(np.array([-90.0, 0.0, -90.0 + 72.0]), np.array([0.012, 0.038, 0.0]))
    inverse = T_head_sensor.inverse()
    return Mounted("cam1", pinhole, inverse.rotation, inverse.translation_m)


def test_a_mounted_sensor_projects_head_points_as_the_sensor_does(pinhole: Pinhole) -> None:
    mounted = _mounted(pinhole)
    yaw = np.radians(72.0)
    ahead = np.array([[10.0 * np.cos(yaw), 10.0 * np.sin(yaw), 0.0]])  # on the sensor's optical axis
    uv, valid = mounted.project(ahead)
    assert valid[0]
    np.testing.assert_allclose(uv[0], pinhole.K[:2, 2], atol=3.0)  # 4 cm of lever arm at 10 m: ~0 px off axis
    points = np.random.default_rng(1).normal(size=(50, 3)) * 5.0
    expected, ok = pinhole.project(points @ mounted.rotation.T + mounted.translation_m)
    got, ok2 = mounted.project(points)
    np.testing.assert_array_equal(ok, ok2)
    np.testing.assert_allclose(got[ok], expected[ok])


@settings(max_examples=30)
@given(st.floats(-0.4, 0.4), st.floats(-0.25, 0.25), st.floats(1.0, 40.0))
def test_mounted_jacobian_matches_finite_differences(pinhole: Pinhole, x: float, y: float, z: float) -> None:
    mounted = _mounted(pinhole)
    in_sensor = np.array([x * z, y * z, z])
    head = (in_sensor - mounted.translation_m) @ mounted.rotation  # the head point that lands there
    numeric = finite_difference_jacobian(mounted.project, head, 1e-6 * z)
    analytic = mounted.project_jacobian(head[None])[0]
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-6 * np.abs(analytic).max())


def test_mounted_back_project_gives_head_rays(pinhole: Pinhole) -> None:
    mounted = _mounted(pinhole)
    uv = np.array([[300.0, 200.0], [960.0, 600.0], [1700.0, 1100.0]])
    rays = mounted.back_project(uv)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0)
    origin = -mounted.rotation.T @ mounted.translation_m  # the sensor's centre in the head
    back, valid = mounted.project(origin + 100.0 * rays)
    assert valid.all()
    np.testing.assert_allclose(back, uv, atol=1e-6)


def test_a_rectified_pinhole_back_projects_through_k_alone() -> None:
    K = np.array([[408.4, 0.0, 806.6], [0.0, 204.2, 315.5], [0.0, 0.0, 1.0]])  # fy = fx / 2, as the Ford images
    uv = np.array([[0.0, 0.0], [806.6, 315.5], [1615.0, 615.0], [300.25, 520.75]])
    rays = Pinhole(K, np.zeros(0), 1616, 616).back_project(uv)
    expected = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, np.zeros(5)).reshape(-1, 2)
    np.testing.assert_allclose(rays[:, :2] / rays[:, 2:], expected, atol=1e-12)
    skewed = Pinhole(K + [[0.0, 1.5, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], np.zeros(0), 1616, 616)
    back, valid = skewed.project(skewed.back_project(uv) * 7.0)  # OpenCV's undistortPoints ignores a skew
    assert valid.all()
    np.testing.assert_allclose(back, uv, atol=1e-9)


# --- Fisheye (OpenCV's equidistant model) ------------------------------------------------------------------

FISHEYE = Fisheye(np.array([[300.0, 0.0, 511.5], [0.0, 300.0, 383.5], [0.0, 0.0, 1.0]]),
                  np.array([0.02, -0.01, 0.004, -0.001]), 1024, 768)


@settings(max_examples=50)
@given(st.floats(-1.5, 1.5), st.floats(-1.2, 1.2), st.floats(0.5, 30.0))
def test_fisheye_projects_as_opencv_in_front(x: float, y: float, z: float) -> None:
    point = np.array([[x * z, y * z, z]])
    uv, valid = FISHEYE.project(point)
    expected, _ = cv2.fisheye.projectPoints(point.reshape(1, 1, 3), np.zeros(3), np.zeros(3), FISHEYE.K, FISHEYE.D)
    np.testing.assert_allclose(uv, expected.reshape(1, 2), atol=1e-6)
    assert valid[0]


@settings(max_examples=50)
@given(st.floats(0.0, np.radians(100.0)), st.floats(-np.pi, np.pi), st.floats(0.5, 30.0))
def test_fisheye_jacobian_matches_finite_differences(theta: float, phi: float, r: float) -> None:
    point = r * np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    if np.hypot(point[0], point[1]) < 1e-3 * r:
        point[0] += 1e-3 * r  # on the axis the azimuth's direction is undefined; the test stays off it
    numeric = finite_difference_jacobian(FISHEYE.project, point, 1e-6 * r)
    analytic = FISHEYE.project_jacobian(point[None])[0]
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-5 * np.abs(analytic).max())


def test_fisheye_sees_past_ninety_degrees_and_back_projects_there() -> None:
    rays = np.array([[np.sin(a), 0.0, np.cos(a)] for a in np.radians([0.0, 30.0, 85.0, 100.0, 110.0])])
    uv, valid = FISHEYE.project(10.0 * rays)
    assert valid.all() and uv[4, 0] > uv[3, 0] > uv[2, 0]  # further out with the angle, past 90 deg too
    np.testing.assert_allclose(FISHEYE.back_project(uv), rays, atol=1e-9)
    _, behind = FISHEYE.project(np.array([[0.0, 0.0, -1.0]]))
    assert not behind[0]  # 180 deg is beyond the image's corners


def test_fisheye_area_ratio_of_an_ideal_equidistant_lens() -> None:
    ideal = Fisheye(FISHEYE.K, np.zeros(4), 1024, 768)
    theta = np.radians([1e-4, 30.0, 60.0, 95.0])
    uv, _ = ideal.project(np.stack([np.sin(theta), np.zeros(4), np.cos(theta)], axis=1))
    np.testing.assert_allclose(ideal.pixel_area_ratio(uv), theta / np.sin(theta), rtol=1e-6)


def test_projecting_under_many_rotations_equals_projecting_each(pinhole: Pinhole) -> None:
    rotations = np.stack([Transform.from_rpy_xyz(np.array(r), np.zeros(3)).rotation
                          for r in ([0.0, 0.0, 0.0], [5.0, -3.0, 40.0], [-20.0, 10.0, 170.0])])
    t = np.array([0.1, -0.2, 0.3])
    points = np.random.default_rng(3).normal(size=(40, 3)) * 8.0
    for camera in (pinhole, _mounted(pinhole), PANO):
        uv, valid = project_rotated(camera, rotations, t, points)
        for k, r in enumerate(rotations):
            one_uv, one_valid = camera.project(points @ r.T + t)
            np.testing.assert_array_equal(valid[k * 40:(k + 1) * 40], one_valid)
            np.testing.assert_allclose(uv[k * 40:(k + 1) * 40][one_valid], one_uv[one_valid], atol=1e-9)


# --- Intrinsics validation ---------------------------------------------------------------------------------

GOOD_K = [[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]]


def _k_with(i: int, j: int, value: float) -> np.ndarray:
    k = np.array(GOOD_K)
    k[i, j] = value
    return k


BAD_K = {
    # an all-zero K used to reach the search's field of view and divide by zero there
    "all zero": (np.zeros((3, 3)), r"K: fx must be > 0, got 0$"),
    # a negative fx used to turn the texture radius into NaN (a ValueError far from rig.yaml)
    "negative fx": (_k_with(0, 0, -500.0), r"K: fx must be > 0, got -500$"),
    "zero fy": (_k_with(1, 1, 0.0), r"K: fy must be > 0, got 0$"),
    "NaN cx": (_k_with(0, 2, np.nan), r"K: cx must be finite, got nan$"),
    "infinite skew": (_k_with(0, 1, np.inf), r"K: skew must be finite, got inf$"),
    "lower triangle": (_k_with(1, 0, 3.0), r"K: K\[1,0\] must be 0 \(K is upper triangular\), got 3$"),
    "last row": (_k_with(2, 2, 2.0), r"K: the last row must be \[0, 0, 1\], got \[0.0, 0.0, 2.0\]$"),
}


@pytest.mark.parametrize("name", list(BAD_K))
@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_a_bad_k_is_a_geometry_error_naming_the_value(model: str, name: str) -> None:
    k, message = BAD_K[name]
    with pytest.raises(GeometryError, match=f"^{model} {message}"):
        if model == "pinhole":
            Pinhole(k, np.zeros(5), 640, 480)
        else:
            Fisheye(k, np.zeros(4), 640, 480)


def test_a_skewed_k_is_accepted() -> None:
    k = _k_with(0, 1, 1.5)
    assert Pinhole(k, np.zeros(5), 640, 480).K[0, 1] == 1.5
    assert Fisheye(k, np.zeros(4), 640, 480).K[0, 1] == 1.5


def test_a_non_finite_distortion_is_a_geometry_error() -> None:
    with pytest.raises(GeometryError, match=r"^pinhole D must be finite"):
        Pinhole(np.array(GOOD_K), np.array([0.1, np.nan, 0.0, 0.0]), 640, 480)
    with pytest.raises(GeometryError, match=r"^fisheye D must be finite"):
        Fisheye(np.array(GOOD_K), np.array([0.1, 0.0, np.inf, 0.0]), 640, 480)
