"""calib.uncertainty: local coordinates, per-cluster Hessian, sandwich scale, weakest direction."""

import warnings

import numpy as np
import pytest

from calib.camera import Pinhole
from calib.edges_points import EdgePoints
from calib.geometry import Transform, so3_exp
from calib.gmm import GmmOptions, PairFeatures, pair_terms
from calib.optimize import OptimOptions, hessian_steps, level_model
from calib.uncertainty import (
    LevelModel,
    cell_ids,
    clusters_at,
    hessian,
    local_gradient,
    nll_scale,
    sandwich,
    scatter,
    tau_at,
    weakest_direction,
    xi_of,
)
from tests.calib.synthetic import TRUTH, make_pair


@pytest.fixture(scope="module")
def pairs():
    return [make_pair(1), make_pair(2)]


def test_local_coordinates_round_trip_and_rotate_about_lidar_axes():
    rng = np.random.default_rng(3)
    for _ in range(20):
        tau_hat = np.r_[rng.uniform(-2, 2, 3), rng.uniform(-1, 1, 3)]
        xi = np.r_[rng.uniform(-0.2, 0.2, 3), rng.uniform(-0.1, 0.1, 3)]
        assert np.allclose(xi_of(tau_hat, tau_at(tau_hat, xi)), xi, atol=1e-9)
    # xi = (0.01, 0, 0) turns the LiDAR about its own x axis: R = R_hat Rx(0.01).
    tau = tau_at(TRUTH.tau, np.array([0.01, 0, 0, 0, 0, 0]))
    rx = np.array([[1, 0, 0], [0, np.cos(0.01), -np.sin(0.01)], [0, np.sin(0.01), np.cos(0.01)]])
    assert np.allclose(so3_exp(tau[:3]), TRUTH.rotation @ rx, atol=1e-12)


def test_cell_ids_number_rows_as_a_row_wise_unique_does():
    rng = np.random.default_rng(4)
    cell = rng.integers(-3, 40, size=(500, 2)).astype(np.int64)
    _, expected = np.unique(cell, axis=0, return_inverse=True)
    np.testing.assert_array_equal(cell_ids(cell), np.asarray(expected).reshape(-1))
    wide = np.array([[-(2**40), 0], [2**40, 2**40], [-(2**40), 0], [0, -(2**40)]], dtype=np.int64)  # no single key
    np.testing.assert_array_equal(cell_ids(wide), [0, 2, 0, 1])
    assert cell_ids(np.zeros((0, 2), np.int64)).shape == (0,)


def test_points_a_pinhole_cannot_see_share_one_cluster_without_a_cast_warning():
    camera = Pinhole(np.array([[1000.0, 0, 960], [0, 1000.0, 600], [0, 0, 1]]), np.array([-0.3, 0.1, 0, 0, -0.2]),
                     1920, 1200)
    # optical frame: two in view in different cells, one behind, one grazing (polynomial distortion far off scale)
    points_cam = np.array([[0.0, 0.0, 10.0], [3.0, 1.0, 10.0], [0.0, 0.0, -5.0], [40.0, 30.0, 1e-2]])
    feat = PairFeatures(camera, None, EdgePoints(points_cam, np.ones(4), np.zeros(4, np.int8)))  # type: ignore[arg-type]
    model = LevelModel((feat,), (1.0,), GmmOptions())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        clusters = clusters_at(model, np.zeros(6), 1.0)
    labels = clusters.labels[0]
    assert labels[2] == labels[3] and len({labels[0], labels[1], labels[2]}) == 3 and clusters.count == 3


def test_cluster_gradients_sum_to_the_cost_gradient_and_hessian_matches_second_differences(pairs):
    model = level_model(pairs, OptimOptions(), GmmOptions(), len(OptimOptions().sigmas_deg) - 1)
    tau = tau_at(TRUTH.tau, np.array([0.002, -0.001, 0.001, 0.003, -0.002, 0.001]))
    frozen = model.freeze(tau)
    clusters = clusters_at(model, tau, 5.0)
    assert clusters.count > 20 and set(clusters.pair.tolist()) == {0, 1}
    grads = local_gradient(model, frozen, tau, np.zeros(6), clusters)

    def cost(xi):
        return -sum(float(pair_terms([f], [z], tau_at(tau, xi), [s], model.gmm)[0].value.sum())
                    for f, z, s in zip(model.feats, frozen, model.sigma_in_px, strict=True))

    steps = hessian_steps(pairs, model.gmm)
    for k in range(6):  # the gradient summed over clusters is the cost's derivative in local coordinates
        e = np.zeros(6)
        e[k] = steps[k]
        numeric = (cost(e) - cost(-e)) / (2 * steps[k])
        assert grads[:, k].sum() == pytest.approx(numeric, rel=0.02, abs=1e-3 * np.abs(grads).sum() / 6)
    h = hessian(model, frozen, tau, steps, clusters).sum(axis=0)
    scale = np.sqrt(np.outer(np.diag(h), np.diag(h)))
    assert np.abs(h - h.T).max() <= 0.01 * scale.max() and np.all(np.abs(h - h.T) <= 0.02 * scale)
    for k in range(6):  # diagonal against second differences of the cost itself
        e = np.zeros(6)
        e[k] = 2 * steps[k]
        second = (cost(e) - 2 * cost(np.zeros(6)) + cost(-e)) / (2 * steps[k]) ** 2
        assert h[k, k] == pytest.approx(second, rel=0.1)
    assert np.linalg.eigvalsh(0.5 * (h + h.T)).min() > 0  # near the truth: a minimum


def test_sandwich_does_not_depend_on_the_cost_scale_but_kappa_does():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 6))
    h = a @ a.T + 6 * np.eye(6)
    grads = rng.normal(size=(40, 6)) @ np.linalg.cholesky(h).T  # scatter ~ H: a true NLL (kappa ~ 1)
    b = scatter(grads)
    cov = sandwich(h, b, np.zeros((6, 6)))
    for c in (0.01, 100.0):  # the same cost times c: H -> cH, B -> c^2 B
        assert np.allclose(sandwich(c * h, c * c * b, np.zeros((6, 6))), cov)
        assert nll_scale(c * h, c * c * b) == pytest.approx(c * nll_scale(h, b))
    # A prior adds information: every variance shrinks, and an infinitely sure axis goes to zero.
    prior = np.diag([0, 0, 0, 0, 0, 1e12])
    post = sandwich(h, b, prior)
    assert np.all(np.diag(post) <= np.diag(cov) + 1e-15) and post[5, 5] < 1e-11


def test_weakest_direction_names_the_ridge_or_the_axis():
    d = np.array([np.radians(0.05), np.radians(0.25), np.radians(0.05), 0.002, 0.002, 0.025])
    corr = np.eye(6)
    corr[1, 5] = corr[5, 1] = 0.95  # pitch and z trade off, both beyond the tolerance
    cov = corr * np.outer(d, d)
    text = weakest_direction(cov, np.array([0.2] * 3 + [2.0] * 3))
    assert "z and pitch trade off" in text or "pitch and z trade off" in text
    # 1 cm of z goes with 0.95 * 0.25 / 2.5 = 0.095 deg of pitch along the ridge.
    assert "~ 0.095 deg of pitch" in text or "~ 11 cm of z" in text or "0.1 deg of pitch ~" in text
    alone = np.diag(np.array([np.radians(0.05)] * 3 + [0.002] * 3) ** 2)
    alone[3, 3] *= 100
    assert weakest_direction(alone, np.array([0.2] * 3 + [2.0] * 3)).startswith("x is the least known axis")


def test_transform_helpers_agree_with_transform_class():
    t = Transform.from_tau(tau_at(TRUTH.tau, np.zeros(6)))
    assert np.allclose(t.matrix, TRUTH.matrix, atol=1e-12)


def test_a_direction_the_data_leave_flat_is_known_to_the_kernel_reach_not_to_the_eigenvalue_floor():
    rng = np.random.default_rng(5)
    h = np.diag([4e6, 4e6, 4e6, 9e4, 9e4, -1e-6])  # sigma 0.03 deg, 0.3 cm; z: flat (curved down a little)
    b = np.diag([4e6, 4e6, 4e6, 9e4, 9e4, 1.0]) * (1.0 + 0.01 * rng.uniform(size=6))
    reach = np.array([0.03] * 3 + [0.4] * 3)  # rad, m
    free = sandwich(h, b, np.zeros((6, 6)))
    held = sandwich(h, b, np.zeros((6, 6)), reach)
    assert free[5, 5] > 100.0  # m^2: set by positive_part's 1e-9 floor, not by the data
    assert held[5, 5] == pytest.approx(0.4**2 / 3, rel=1e-9)  # a uniform spread over +-reach
    assert np.allclose(np.diag(held)[:5], np.diag(free)[:5], rtol=1e-9)  # the known axes keep their sigma
