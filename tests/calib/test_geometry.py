"""Round trips and peer checks of calib/geometry.py.

Expected values come from scipy's Rotation (a peer implementation), hand geometry, finite differences
and round trips -- never from re-running the function under test.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from calib.errors import GeometryError
from calib.geometry import (
    Transform,
    cross_rows,
    left_jacobian,
    matrix_to_quaternion_xyzw,
    matrix_to_rpy_deg,
    quaternion_xyzw_to_matrix,
    rotation_angle_deg,
    rpy_deg_to_matrix,
    skew,
    so3_exp,
    so3_log,
)

finite = st.floats(-1.0, 1.0, allow_nan=False, allow_subnormal=False)
unit_vectors = (
    st.tuples(finite, finite, finite)
    .map(np.array)
    .filter(lambda v: np.linalg.norm(v) > 0.1)
    .map(lambda v: v / np.linalg.norm(v))
)
# Angles that stress so3_log: generic, tiny (series branch), and within a hair of pi (axis branch).
angles = st.one_of(
    st.floats(0.0, np.pi),
    st.floats(0.0, 1e-5),
    st.floats(0.0, 1e-3).map(lambda e: np.pi - e),
    st.sampled_from([0.0, 1e-12, 1e-7, np.pi - 1e-9, np.pi]),
)
rotation_vectors = st.builds(lambda axis, angle: axis * angle, unit_vectors, angles)
rotations = rotation_vectors.map(lambda w: Rotation.from_rotvec(w).as_matrix())
translations = st.tuples(*[st.floats(-50.0, 50.0)] * 3).map(np.array)
transforms = st.builds(Transform, rotations, translations)
degrees = st.floats(-180.0, 180.0)


def wrap_deg(a: np.ndarray) -> np.ndarray:
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


# --- roll/pitch/yaw -------------------------------------------------------------------------------


def test_rpy_hand_cases() -> None:
    # yaw 90 deg turns +x (forward) into +y (left); pitch 90 deg turns +x into -z; roll 90 turns +y into +z.
    np.testing.assert_allclose(rpy_deg_to_matrix(np.array([0, 0, 90.0])) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rpy_deg_to_matrix(np.array([0, 90.0, 0])) @ [1, 0, 0], [0, 0, -1], atol=1e-15)
    np.testing.assert_allclose(rpy_deg_to_matrix(np.array([90.0, 0, 0])) @ [0, 1, 0], [0, 0, 1], atol=1e-15)


@given(degrees, st.floats(-90.0, 90.0), degrees)
def test_rpy_to_matrix_matches_scipy(roll: float, pitch: float, yaw: float) -> None:
    # scipy's lower-case "xyz" is extrinsic x, then y, then z: Rz(yaw) @ Ry(pitch) @ Rx(roll).
    expected = Rotation.from_euler("xyz", [roll, pitch, yaw], degrees=True).as_matrix()
    np.testing.assert_allclose(rpy_deg_to_matrix(np.array([roll, pitch, yaw])), expected, atol=1e-12)


@given(degrees, st.floats(-89.0, 89.0), degrees)
def test_rpy_round_trip_away_from_gimbal_lock(roll: float, pitch: float, yaw: float) -> None:
    rpy = np.array([roll, pitch, yaw])
    back = matrix_to_rpy_deg(rpy_deg_to_matrix(rpy))
    np.testing.assert_allclose(wrap_deg(back - rpy), 0.0, atol=1e-8)


@given(
    degrees,
    st.sampled_from([-1.0, 1.0]),
    st.one_of(st.just(0.0), st.floats(1e-14, 1e-3)),
    degrees,
)
def test_rpy_round_trip_at_and_near_gimbal_lock(roll: float, sign: float, offset: float, yaw: float) -> None:
    # At pitch = +-90 deg only roll -/+ yaw is defined: compare matrices, not angles.
    pitch = sign * (90.0 - offset)
    matrix = rpy_deg_to_matrix(np.array([roll, pitch, yaw]))
    back = matrix_to_rpy_deg(matrix)
    assert -90.0 <= back[1] <= 90.0
    np.testing.assert_allclose(rpy_deg_to_matrix(back), matrix, atol=1e-12)


@given(unit_vectors, st.floats(1e-12, 1e-5), st.sampled_from([-1.0, 1.0]), degrees)
def test_rpy_round_trip_of_any_matrix_near_gimbal_lock(
    axis: np.ndarray, eps: float, sign: float, yaw: float
) -> None:
    # Matrices made by scipy rather than by rpy_deg_to_matrix: their tiny entries (r[2, 1], r[2, 2] ~
    # cos(pitch)) carry rounding that rpy_deg_to_matrix's own entries would share.
    locked = Rotation.from_euler("xyz", [0.0, sign * 90.0, yaw], degrees=True)
    matrix = (Rotation.from_rotvec(eps * axis) * locked).as_matrix()
    np.testing.assert_allclose(rpy_deg_to_matrix(matrix_to_rpy_deg(matrix)), matrix, atol=1e-9)


def test_gimbal_lock_puts_everything_in_yaw() -> None:
    back = matrix_to_rpy_deg(rpy_deg_to_matrix(np.array([30.0, 90.0, 50.0])))
    # With pitch = +90, Rz(y) Ry(90) Rx(r) has first row [0, sin(r - y), cos(r - y)]: only yaw - roll = 20
    # deg is defined, and it all goes into yaw.
    np.testing.assert_allclose(back, [0.0, 90.0, 20.0], atol=1e-9)


# --- quaternions ----------------------------------------------------------------------------------


def same_quaternion(a: np.ndarray, b: np.ndarray) -> None:
    # q and -q are the same rotation; the w >= 0 convention leaves the sign open only when w == 0.
    sign = 1.0 if np.dot(a, b) >= 0 else -1.0
    np.testing.assert_allclose(a, sign * b, atol=1e-9)


@given(rotations)
def test_matrix_to_quaternion_matches_scipy(matrix: np.ndarray) -> None:
    q = matrix_to_quaternion_xyzw(matrix)
    assert q[3] >= 0.0
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12
    same_quaternion(q, Rotation.from_matrix(matrix).as_quat())  # scipy's as_quat is (x, y, z, w)


@given(st.tuples(finite, finite, finite, finite).map(np.array).filter(lambda q: np.linalg.norm(q) > 0.1))
def test_quaternion_to_matrix_matches_scipy_and_round_trips(q: np.ndarray) -> None:
    matrix = quaternion_xyzw_to_matrix(q)
    np.testing.assert_allclose(matrix, Rotation.from_quat(q).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(quaternion_xyzw_to_matrix(3.0 * q), matrix, atol=1e-12)  # scale-free
    same_quaternion(matrix_to_quaternion_xyzw(matrix), q / np.linalg.norm(q))


def test_quaternion_hand_case_and_bad_input() -> None:
    # 90 deg about z: (0, 0, sin 45, cos 45).
    s = np.sqrt(0.5)
    np.testing.assert_allclose(
        matrix_to_quaternion_xyzw(rpy_deg_to_matrix(np.array([0, 0, 90.0]))), [0, 0, s, s], atol=1e-15
    )
    with pytest.raises(GeometryError, match="quaternion_xyzw"):
        quaternion_xyzw_to_matrix(np.zeros(4))


# --- so(3) exponential and logarithm --------------------------------------------------------------


@given(rotation_vectors)
def test_so3_exp_matches_scipy(omega: np.ndarray) -> None:
    np.testing.assert_allclose(so3_exp(omega), Rotation.from_rotvec(omega).as_matrix(), atol=1e-12)


@given(rotations)
def test_so3_log_round_trip(matrix: np.ndarray) -> None:
    omega = so3_log(matrix)
    assert np.linalg.norm(omega) <= np.pi + 1e-12
    np.testing.assert_allclose(so3_exp(omega), matrix, atol=1e-12)


@given(unit_vectors, st.one_of(st.floats(0.0, np.pi - 1e-6), st.floats(0.0, 1e-6)))
def test_so3_log_inverts_exp_below_pi(axis: np.ndarray, angle: float) -> None:
    omega = axis * angle
    np.testing.assert_allclose(so3_log(so3_exp(omega)), omega, atol=1e-9)


@given(unit_vectors, st.floats(1e-9, 1e-3))
def test_so3_log_near_pi_keeps_the_axis(axis: np.ndarray, eps: float) -> None:
    # Below pi the rotation vector is unique; the axis must survive even when sin(angle) ~ 1e-9.
    omega = axis * (np.pi - eps)
    np.testing.assert_allclose(so3_log(so3_exp(omega)), omega, atol=1e-8)


def test_so3_log_at_pi_gives_either_axis() -> None:
    axis = np.array([1.0, 2.0, -2.0]) / 3.0
    omega = so3_log(so3_exp(np.pi * axis))
    assert min(np.abs(omega - np.pi * axis).max(), np.abs(omega + np.pi * axis).max()) < 1e-12


def test_skew_is_the_cross_product() -> None:
    v, x = np.array([0.3, -1.2, 2.0]), np.array([-0.5, 0.7, 0.1])
    np.testing.assert_allclose(skew(v) @ x, np.cross(v, x), atol=1e-15)


# --- left Jacobian (paper eqs. 30-31) --------------------------------------------------------------


@given(
    st.one_of(rotation_vectors.filter(lambda w: np.linalg.norm(w) < np.pi - 1e-3), st.just(np.zeros(3))),
    st.tuples(*[st.floats(-20.0, 20.0)] * 3).map(np.array),
)
def test_left_jacobian_against_finite_differences(omega: np.ndarray, point: np.ndarray) -> None:
    # d/d(omega) of exp(omega^) p equals -(R p)^ J (paper eq. 30); columns by central differences.
    h = 1e-6
    numeric = np.stack(
        [(so3_exp(omega + h * e) @ point - so3_exp(omega - h * e) @ point) / (2 * h) for e in np.eye(3)],
        axis=1,
    )
    analytic = -skew(so3_exp(omega) @ point) @ left_jacobian(omega)
    np.testing.assert_allclose(analytic, numeric, atol=1e-7 * (1.0 + np.linalg.norm(point)))


def test_left_jacobian_hand_values() -> None:
    np.testing.assert_allclose(left_jacobian(np.zeros(3)), np.eye(3), atol=1e-15)
    # About z by pi/2: J = (2/pi) I + (1 - 2/pi) e_z e_z^T + (2/pi) e_z^ (eq. 31 with a = e_z).
    c = 2.0 / np.pi
    expected = np.array([[c, -c, 0.0], [c, c, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(left_jacobian(np.array([0, 0, np.pi / 2])), expected, atol=1e-15)


# --- Transform --------------------------------------------------------------------------------------

points = st.lists(st.tuples(*[st.floats(-100.0, 100.0)] * 3), min_size=1, max_size=8).map(np.array)


@given(transforms, points)
def test_inverse_undoes_apply(transform: Transform, pts: np.ndarray) -> None:
    np.testing.assert_allclose(transform.inverse().apply(transform.apply(pts)), pts, atol=1e-9)
    identity = transform.compose(transform.inverse())
    np.testing.assert_allclose(identity.matrix, np.eye(4), atol=1e-12)


@given(transforms, transforms, points)
def test_compose_applies_other_first(a: Transform, b: Transform, pts: np.ndarray) -> None:
    np.testing.assert_allclose(a.compose(b).apply(pts), a.apply(b.apply(pts)), atol=1e-9)
    np.testing.assert_allclose(a.compose(b).matrix, a.matrix @ b.matrix, atol=1e-12)


@given(transforms)
def test_matrix_tau_rpy_round_trips(transform: Transform) -> None:
    again = Transform.from_matrix(transform.matrix)
    np.testing.assert_allclose(again.matrix, transform.matrix, atol=1e-15)
    np.testing.assert_allclose(Transform.from_tau(transform.tau).matrix, transform.matrix, atol=1e-12)
    from_rpy = Transform.from_rpy_xyz(transform.rpy_deg, transform.translation_m)
    np.testing.assert_allclose(from_rpy.matrix, transform.matrix, atol=1e-12)
    from_quaternion = quaternion_xyzw_to_matrix(transform.quaternion_xyzw)
    np.testing.assert_allclose(from_quaternion, transform.rotation, atol=1e-12)


def test_apply_follows_p_cam_equals_r_p_plus_t() -> None:
    # yaw 90 deg, t = (1, 2, 3): the point (1, 0, 0) goes to (0, 1, 0) + t.
    transform = Transform.from_rpy_xyz(np.array([0, 0, 90.0]), np.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(transform.apply(np.array([[1.0, 0.0, 0.0]])), [[1.0, 3.0, 3.0]], atol=1e-15)


@given(rotations, rotations)
def test_rotation_angle_matches_scipy(a: np.ndarray, b: np.ndarray) -> None:
    expected = np.degrees(Rotation.from_matrix(a.T @ b).magnitude())
    assert abs(rotation_angle_deg(a, b) - expected) < 1e-6


def test_bad_inputs_raise_geometry_error() -> None:
    with pytest.raises(GeometryError):
        Transform.from_matrix(np.ones((4, 4)))
    with pytest.raises(GeometryError):
        Transform(np.diag([1.0, 1.0, -1.0]), np.zeros(3))  # a reflection is not a rotation
    with pytest.raises(GeometryError):
        Transform(np.eye(3), np.array([0.0, np.nan, 0.0]))


@pytest.mark.parametrize("n", [0, 1, 5, 400])
def test_cross_rows_is_np_cross_to_the_last_bit(n):
    rng = np.random.default_rng(n)
    a, b = rng.normal(size=(n, 3)) * 10.0, rng.normal(size=(n, 3))
    assert np.array_equal(cross_rows(a, b), np.cross(a, b).reshape(n, 3))
    assert np.array_equal(cross_rows(a, a), np.zeros((n, 3)))
