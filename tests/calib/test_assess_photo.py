"""calib.assess_photo: the NID solution's restarts, per-axis sigma and verdict (docs/trust.md)."""

from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np
import pytest

from calib import methods
from calib.assess import Status, TrustOptions
from calib.assess_photo import (
    _cluster_hists,
    _gradient,
    _hessian,
    _means_without,
    _nids,
    _offsets,
    assess_photometric,
    photo_uncertainty,
)
from calib.errors import CalibError
from calib.geometry import Transform
from calib.gmm import transform_points
from calib.methods import Method, SolveRequest, solve
from calib.photometric import (
    PhotoCost,
    PhotoPair,
    PhotoParams,
    level_pairs,
    nid,
    optimise_photometric,
    photo_pair,
    project_level,
    sample,
)
from calib.uncertainty import TO_DISPLAY, tau_at, xi_of
from tests.calib.test_photometric import TRUTH, ideal_pair, soft_joint_histogram

SMALL = PhotoParams(cost=PhotoCost.NID, blur_deg=(0.5, 0.0), step_rot_deg=(0.6, 0.2), step_trans_m=(0.03, 0.01),
                    max_evals=300, restarts=1, rotation_only_levels=0)


def test_stencil_derivatives_are_exact_on_a_quadratic():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 6))
    hess, grad = a @ a.T + np.eye(6), rng.normal(size=6)
    h = np.array([1e-3] * 3 + [1e-2] * 3)
    values = np.array([grad @ x + 0.5 * x @ hess @ x for x in _offsets(h)])
    assert _gradient(values[:13], h) == pytest.approx(grad, rel=1e-9, abs=1e-9)
    assert _hessian(values, h) == pytest.approx(hess, rel=1e-6, abs=1e-6)


def test_cluster_histograms_add_up_to_the_pair_histogram():
    """The soft histogram is additive over samples: 'without a cluster' is a subtraction."""
    pair = ideal_pair(5)
    lp = level_pairs([pair], TRUTH.tau, SMALL, 1, [(pair.points_lidar, pair.reflectivity)])[0]
    labels = np.arange(len(lp.points_lidar)) % 7
    per = _cluster_hists(lp, TRUTH.tau, labels, 7, SMALL.n_bins)
    uv, inside = project_level(lp, TRUTH.tau)
    whole = soft_joint_histogram(lp.reflectivity[inside], sample(lp.grey, lp.camera, uv[inside]), SMALL.n_bins)
    assert per.sum(axis=0) == pytest.approx(whole, abs=1e-9)


def test_histograms_are_scored_at_once_as_one_by_one():
    """The stencil scores its histograms in stacks: the same NID as calib.photometric's, 1 for an empty one, and a
    pair left empty leaves the mean."""
    rng = np.random.default_rng(3)
    hists = rng.gamma(0.3, 5.0, size=(3, 16, 16))
    hists[1, :8] = 0.0
    drops = hists[None] * rng.uniform(0.0, 0.5, size=(4, 3, 1, 1))
    drops[2, 0] = hists[0]  # pair 0 left empty by group 2
    expected = [np.mean([nid(h - d) for h, d in zip(hists, g, strict=True) if (h - d).sum() > 1e-9]) for g in drops]
    assert _means_without(hists, drops) == pytest.approx(expected, rel=1e-12)
    assert _nids(np.stack([hists[0], np.zeros((16, 16))])) == pytest.approx([nid(hists[0]), 1.0], rel=1e-12)


def test_an_ideal_pair_is_assessed():
    pair = ideal_pair(2)
    start = tau_at(TRUTH.tau, np.array([np.radians(0.4), np.radians(-0.3), np.radians(0.2), 0.02, -0.01, 0.01]))
    solved = optimise_photometric([pair], start, SMALL)
    trust = replace(TrustOptions(), restarts=2)
    a = assess_photometric([pair], solved, SMALL, trust, starts=(start,))
    u = a.uncertainty
    assert u.is_minimum and u.kappa > 0 and u.jackknife is not None and u.restart_spread is not None
    assert len(a.restarts) == 2 and a.verdict.status is not Status.FAILED
    error = np.abs(xi_of(TRUTH.tau, a.tau) * TO_DISPLAY)
    assert np.all(error <= [0.05] * 3 + [0.5] * 3)  # deg, cm
    assert np.all(np.isfinite(u.sigma)) and np.all(u.sigma > 0)
    assert np.all(u.sigma >= u.restart_spread)  # the restarts' landing spread is part of the sigma
    # the restarts came back to the solution (a statistical tie): the answer is the solve's own, to the bit
    assert all(abs(r.delta_nll) < trust.ambiguity_nll for r in a.restarts)
    assert np.array_equal(a.tau, solved.tau)


def test_only_nid_is_assessed():
    pair = ideal_pair(3)
    with pytest.raises(CalibError, match="defined for NID"):
        assess_photometric([pair], optimise_photometric([pair], TRUTH.tau, replace(SMALL, cost=PhotoCost.MI)),
                           replace(SMALL, cost=PhotoCost.MI), TrustOptions(restarts=0))


def test_nid_assessed_method_has_a_verdict_the_edges_second_opinion_and_the_baseline_none(monkeypatch):
    pair = ideal_pair(4)
    start = Transform.from_tau(tau_at(TRUTH.tau, np.array([np.radians(0.2), 0, 0, 0.01, 0, 0])))
    trust = TrustOptions(restarts=1)
    assert solve(SolveRequest(method=Method.NID, initial=start, trust=trust), photo=[pair]).assessment is None
    # The edges (stood in for: their solve is calib.pipeline's) land 0.5 deg of pitch from NID's answer.
    offset = np.array([0.0, np.radians(0.5), 0.0, 0.0, 0.0, 0.0])
    asked = []
    monkeypatch.setattr(methods, "refine_edges", lambda feats, tau, *_: asked.append(feats) or tau_at(tau, offset))
    edges = [object()]
    result = solve(SolveRequest(method=Method.NID_ASSESSED, initial=start, trust=trust), photo=[pair], feats=edges)
    a = result.assessment
    assert a is not None and a.verdict.status is not Status.NOT_ASSESSED and asked == [edges]
    assert a.uncertainty.cross_check is not None and a.uncertainty.cross_check[1] == pytest.approx(0.5 / np.sqrt(2))
    assert "pitch" in a.verdict.weak_axes and any("edges refined from this answer" in r for r in a.verdict.reasons)


def test_restarts_in_a_pool_give_the_same_assessment():
    pair = ideal_pair(2)
    start = tau_at(TRUTH.tau, np.array([np.radians(0.3), 0.0, np.radians(-0.2), 0.01, 0.0, -0.01]))
    solved = optimise_photometric([pair], start, SMALL)
    trust = replace(TrustOptions(), restarts=3)
    alone = assess_photometric([pair], solved, SMALL, trust, starts=(start,))
    with ThreadPoolExecutor(1) as pool:
        pooled = assess_photometric([pair], solved, SMALL, trust, starts=(start,), executor=pool)
    assert np.array_equal(alone.tau, pooled.tau)
    assert [r.offset.tolist() for r in alone.restarts] == [r.offset.tolist() for r in pooled.restarts]
    assert alone.verdict == pooled.verdict


def _banded_pair(seed: int, shifted_band: int | None) -> PhotoPair:
    """The ideal pair with its points in horizontal bands of 6 px (about 2 deg: a VLP-16's ring spacing), each
    band one ring; the ``shifted_band``'s reflectivity is the image's 3 px to the right of where its points
    land, as a laser whose azimuth is off would see it."""
    base = ideal_pair(seed)
    uv, _ = base.camera.project(transform_points(TRUTH.tau, base.points_lidar)[0])
    ring = (uv[:, 1] // 6).astype(np.int16)
    refl = sample(base.grey, base.camera, uv)
    if shifted_band is not None:
        mine = ring == shifted_band
        refl[mine] = sample(base.grey, base.camera, uv[mine] + [3.0, 0.0])
    image = np.rint(base.grey * 255).astype(np.uint8)
    return photo_pair(image, base.points_lidar, refl.astype(np.float32), ring, base.camera, PhotoParams(per_ring=False))


def test_a_ring_that_disagrees_with_the_image_widens_the_ring_jackknife():
    """Every place sees the scene through the same lasers: a ring whose reflectivity sits a few pixels off pulls
    the pose alike in every pair, which leaving out pairs cannot see and the jackknife over rings does."""
    found = {}
    for name, band in (("clean", None), ("shifted", 12)):
        pairs = [_banded_pair(s, band) for s in (7, 8)]
        found[name] = photo_uncertainty(pairs, optimise_photometric(pairs, TRUTH.tau, SMALL).tau, SMALL,
                                        TrustOptions())
        assert found[name].ring_groups == 25  # 150 px in 6 px bands, all in view
    clean, shifted = found["clean"], found["shifted"]
    assert clean.jackknife_rings is not None and shifted.jackknife_rings is not None and shifted.jackknife is not None
    # roll (about the optical axis) is where the band's pull shows here: 0.009 deg against 0.003 deg clean
    assert shifted.jackknife_rings[0] > 2.0 * clean.jackknife_rings[0]
    assert shifted.jackknife_rings[0] > 2.0 * shifted.jackknife[0]
    assert shifted.sigma[0] >= shifted.jackknife_rings[0]


def _edged_pair(seed: int) -> PhotoPair:
    """The ideal pair and 40 points on the edge of the view's 10 % margin (calib.photometric.point_subsets): a
    turn of a fraction of a degree changes which points are in view, and so the random subset a solve keeps."""
    base = ideal_pair(seed)
    rng = np.random.default_rng(seed)
    rays = base.camera.back_project(np.stack([rng.uniform(-21, -19, 40), rng.uniform(5, 145, 40)], axis=1))
    edge = (rays / rays[:, 2:] * 8.0 - TRUTH.translation_m) @ TRUTH.rotation
    uv, _ = base.camera.project(transform_points(TRUTH.tau, base.points_lidar)[0])
    refl = np.r_[sample(base.grey, base.camera, uv), rng.uniform(0, 1, 40)].astype(np.float32)
    image = np.rint(base.grey * 255).astype(np.uint8)
    return photo_pair(image, np.vstack([base.points_lidar, edge]), refl, None, base.camera,
                      PhotoParams(per_ring=False))


SUBSET = replace(SMALL, max_points=800, min_points_per_pair=100)  # a random fifth of the points in view


def test_restarts_are_compared_on_the_points_the_solve_minimised():
    """The solve keeps a random subset of the points in view at its start, and the solution's view keeps
    another: restarts solved and scored on the solution's subset ended well over a tie 'below' the solution (a fit
    of other points, not a better pose of these) and replaced it. On the solve's own points they
    come back to it, and the assessment answers with the plain solve's pose."""
    pair = _edged_pair(5)
    start = tau_at(TRUTH.tau, np.array([np.radians(0.4), np.radians(-0.3), np.radians(0.2), 0.02, -0.01, 0.01]))
    solved = optimise_photometric([pair], start, SUBSET)
    trust = replace(TrustOptions(), restarts=2)
    a = assess_photometric([pair], solved, SUBSET, trust, starts=(start,))
    assert all(r.origin == "restart" and abs(r.delta_nll) < trust.ambiguity_nll for r in a.restarts)
    assert np.array_equal(a.tau, solved.tau)


def test_a_restart_clearly_lower_is_taken():
    """A solve stopped short of its minimum: the restarts around it end lower by far more than a tie and
    closer to the truth, and the assessment answers with the lowest."""
    pair = _edged_pair(5)
    start = tau_at(TRUTH.tau, np.array([np.radians(0.4), np.radians(-0.3), np.radians(0.2), 0.02, -0.01, 0.01]))
    short = optimise_photometric([pair], start, replace(SUBSET, blur_deg=(0.0,), step_rot_deg=(0.2,),
                                                        step_trans_m=(0.01,), max_evals=10, restarts=0))
    trust = replace(TrustOptions(), restarts=2)
    a = assess_photometric([pair], short, SUBSET, trust, starts=(start,))
    solution = [r for r in a.restarts if r.origin == "solution"]
    assert len(solution) == 1 and solution[0].delta_nll > trust.ambiguity_nll
    error = np.linalg.norm(xi_of(TRUTH.tau, a.tau)[:3]), np.linalg.norm(xi_of(TRUTH.tau, short.tau)[:3])
    assert error[0] < error[1]
