"""calib.methods: each method's settings differ from rigd's exactly where its name says, and the photometric
methods refuse what they cannot honour."""

from dataclasses import replace

import numpy as np
import pytest

from calib.errors import CalibError
from calib.gmm import SigmaModel
from calib.methods import Method, calibrate_method, gmm_params, photo_params
from calib.photometric import PhotoCost
from calib.pipeline import CalibParams, PointEdgeMethod, paper_params
from calib.prior import Prior
from tests.calib.test_photometric import TRUTH, ideal_pair


def test_ablations_change_one_thing_each():
    rigd = CalibParams()
    assert gmm_params(Method.RIGD) == rigd
    assert gmm_params(Method.GMM_W1) == replace(rigd, gmm=replace(rigd.gmm, weighted=False))
    uniform = gmm_params(Method.GMM_UNIFORM)
    assert uniform is not None and uniform.gmm.sigma_model is SigmaModel.UNIFORM
    assert np.allclose(uniform.optim.sigmas_deg, np.array(rigd.optim.sigmas_deg) / 2)
    assert uniform.head_sigmas_deg is None
    assert gmm_params(Method.GMM_PAPER_EDGES) == replace(rigd, point_method=PointEdgeMethod.PAPER)
    # the schedule ablation runs the paper's ladder on every camera, a head's too
    assert gmm_params(Method.GMM_PAPER_SCHEDULE) == replace(rigd, optim=paper_params().optim, head_sigmas_deg=None)
    assert gmm_params(Method.PAPER) == paper_params()
    paper = paper_params().optim  # eq. 24: the paper steps along the plain negative gradient
    assert not paper.quasi_newton and not paper.precondition


def test_photometric_methods_have_no_gmm_and_the_hybrid_has_both():
    for method, cost in ((Method.MI, PhotoCost.MI), (Method.NID, PhotoCost.NID), (Method.GOM, PhotoCost.GOM)):
        opts = photo_params(method)
        assert gmm_params(method) is None and opts is not None and opts.cost is cost
        assert method.uses_photometric and not method.uses_gmm
    assert gmm_params(Method.RIGD_NID) == CalibParams() and photo_params(Method.RIGD_NID) is not None
    assert photo_params(Method.GMM_W1) is None


def test_photometric_method_refuses_a_gaussian_prior_and_has_no_assessment():
    pair = ideal_pair(4)
    prior = Prior(np.array([0.05, -0.1, 0.02]), np.full(3, 0.01))
    with pytest.raises(CalibError, match="GMM cost only"):
        calibrate_method(Method.NID, None, [pair], TRUTH, prior=prior)
    with pytest.raises(CalibError, match="photometric pairs"):
        calibrate_method(Method.NID, None, None, TRUTH)
    with pytest.raises(CalibError, match="GMM edge features"):
        calibrate_method(Method.RIGD, None, [pair], TRUTH)
