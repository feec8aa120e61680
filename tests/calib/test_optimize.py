"""calib.optimize: the quasi-Newton (BFGS) directions against the paper's steepest descent."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import calib.optimize as optimize
from calib.geometry import Transform
from calib.gmm import Evaluator, GmmOptions
from calib.optimize import OptimOptions, _bfgs_update, optimise
from tests.calib.synthetic import TRUTH, make_pair

FIELD = dataclasses.replace(GmmOptions(), evaluator=Evaluator.FIELD)


def test_bfgs_update_meets_the_secant_equation_and_keeps_held_axes_out() -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=(6, 6))
    hessian = a @ a.T + 6 * np.eye(6)
    scale = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])  # a rotation-only level: translation held
    s = np.r_[rng.normal(size=3) * 0.01, np.zeros(3)]
    y = hessian @ s
    inverse = _bfgs_update(None, scale, s, y)
    assert inverse is not None
    np.testing.assert_allclose(inverse @ y, s, atol=1e-12)  # H_{k+1} y = s
    assert np.all(inverse[3:] == 0) and np.all(inverse[:, 3:] == 0)
    s2 = np.r_[rng.normal(size=3) * 0.01, np.zeros(3)]
    inverse2 = _bfgs_update(inverse, scale, s2, hessian @ s2)
    assert inverse2 is not None and np.all(inverse2[3:] == 0) and np.all(np.linalg.eigvalsh(inverse2[:3, :3]) > 0)
    assert _bfgs_update(inverse, scale, s, -y) is inverse  # no positive curvature: no update


@pytest.fixture(scope="module")
def pairs():
    return [make_pair(1), make_pair(2)]


def _solve_counting(pairs, start: Transform, quasi_newton: bool, monkeypatch) -> tuple[optimize.OptimResult, int]:
    calls = {"n": 0}
    real = optimize.cost_and_gradient

    def counted(*args, **kwargs):
        calls["n"] += 1
        return real(*args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(optimize, "cost_and_gradient", counted)
        opts = dataclasses.replace(OptimOptions(), quasi_newton=quasi_newton, alternative_schedules=0)
        return optimise(pairs, start.tau, opts, FIELD), calls["n"]


def test_quasi_newton_ends_where_steepest_descent_does_with_fewer_evaluations(pairs, monkeypatch) -> None:
    start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [3.0, -2.0, 2.5], TRUTH.translation_m + [0.06, -0.05, 0.04])
    qn, n_qn = _solve_counting(pairs, start, True, monkeypatch)
    gd, n_gd = _solve_counting(pairs, start, False, monkeypatch)
    for result in (qn, gd):
        assert np.degrees(np.linalg.norm(result.tau[:3] - TRUTH.tau[:3])) < 0.05
        assert np.linalg.norm(result.tau[3:] - TRUTH.translation_m) < 0.01
    assert qn.final_cost == pytest.approx(gd.final_cost, rel=1e-4)  # the same minimum, to the fields' resolution
    assert n_qn < 0.8 * n_gd, (n_qn, n_gd)


def test_coarse_levels_stop_at_small_steps_and_the_finest_ends_at_the_same_minimum(pairs) -> None:
    start = Transform.from_rpy_xyz(TRUTH.rpy_deg + [3.0, -2.0, 2.5], TRUTH.translation_m + [0.06, -0.05, 0.04])
    base = dataclasses.replace(OptimOptions(), alternative_schedules=0)
    full = optimise(pairs, start.tau, dataclasses.replace(base, coarse_step_share=0.0), FIELD)
    cut = optimise(pairs, start.tau, base, FIELD)
    coarse_full = sum(level.iterations for level in full.levels[:-1])
    coarse_cut = sum(level.iterations for level in cut.levels[:-1])
    assert coarse_cut < coarse_full, (coarse_cut, coarse_full)
    assert np.degrees(np.linalg.norm(cut.tau[:3] - full.tau[:3])) < 0.01
    assert np.linalg.norm(cut.tau[3:] - full.tau[3:]) < 0.001
    assert cut.final_cost == pytest.approx(full.final_cost, rel=1e-4)
