"""calib.methods: each method's settings differ from the GMM's exactly where its name says, and a request a method
cannot honour is refused by name before any work."""

import math
from dataclasses import replace

import numpy as np
import pytest

from calib.assess import TrustOptions
from calib.errors import CalibError
from calib.gmm import SigmaModel
from calib.methods import FIELD_METHODS, Method, SolveRequest, _cross_check, solve
from calib.photometric import PhotoCost, PhotoResult
from calib.pipeline import CalibParams, PointEdgeMethod, paper_params
from calib.prior import Prior
from calib.uncertainty import tau_at
from tests.calib.test_photometric import TRUTH, ideal_pair


def test_ablations_change_one_thing_each():
    rigd = CalibParams()
    assert Method.GMM.spec.gmm == rigd
    assert Method.GMM_W1.spec.gmm == replace(rigd, gmm=replace(rigd.gmm, weighted=False))
    uniform = Method.GMM_UNIFORM.spec.gmm
    assert uniform is not None and uniform.gmm.sigma_model is SigmaModel.UNIFORM
    assert np.allclose(uniform.optim.sigmas_deg, np.array(rigd.optim.sigmas_deg) / 2)
    assert uniform.head_sigmas_deg is None
    assert Method.GMM_PAPER_EDGES.spec.gmm == replace(rigd, point_method=PointEdgeMethod.PAPER)
    # the schedule ablation runs the paper's ladder on every camera, a head's too
    assert Method.GMM_PAPER_SCHEDULE.spec.gmm == replace(rigd, optim=paper_params().optim, head_sigmas_deg=None)
    assert Method.PAPER.spec.gmm == paper_params()
    paper = paper_params().optim  # eq. 24: the paper steps along the plain negative gradient
    assert not paper.quasi_newton and not paper.precondition


def test_photometric_methods_have_no_gmm_and_the_hybrid_has_both():
    for method, cost in ((Method.MI, PhotoCost.MI), (Method.NID, PhotoCost.NID), (Method.GOM, PhotoCost.GOM)):
        opts = method.spec.photo
        assert method.spec.gmm is None and opts is not None and opts.cost is cost
        assert method.uses_photometric and not method.uses_gmm
    assert Method.GMM_NID.spec.gmm == CalibParams() and Method.GMM_NID.spec.photo is not None
    assert Method.GMM_W1.spec.photo is None


def test_a_request_a_method_cannot_honour_is_refused_by_name():
    pair = ideal_pair(4)
    prior = Prior(np.array([0.05, -0.1, 0.02]), np.full(3, 0.01))
    refused = [(SolveRequest(method=Method.NID, initial=TRUTH, prior=prior), "GMM cost only"),
               (SolveRequest(method=Method.NID_ASSESSED, initial=TRUTH, sigmas_deg=(1.0,)), "no coarse-to-fine"),
               (SolveRequest(method=Method.NID_ASSESSED), "needs an initial guess"),
               (SolveRequest(method=Method.NID_ASSESSED, initial=TRUTH, fit_elevation=True), "elevation offset"),
               (SolveRequest(method=Method.GMM, initial=TRUTH, sigmas_deg=(1.0, -2.0)), "positive angles")]
    for request, words in refused:
        with pytest.raises(CalibError, match=words):
            solve(request, photo=[pair])
    with pytest.raises(CalibError, match="photometric pairs"):
        solve(SolveRequest(method=Method.NID, initial=TRUTH))
    with pytest.raises(CalibError, match="GMM edge features"):
        solve(SolveRequest(method=Method.GMM, initial=TRUTH), photo=[pair])


def test_the_field_offers_the_gmm_and_nid_with_its_assessment_only():
    assert FIELD_METHODS == (Method.GMM, Method.NID_ASSESSED)
    assert all(m.spec.assessed for m in FIELD_METHODS)


def test_a_given_ladder_replaces_both_the_default_and_the_heads():
    params = SolveRequest(sigmas_deg=(5.0, 2.0)).gmm
    assert params is not None and params.optim.sigmas_deg == (5.0, 2.0) and params.head_sigmas_deg is None


@pytest.mark.parametrize("bad", [(3.0, 0.0), (3.0, -1.0), (math.nan,), (math.inf, 1.0)])
def test_a_ladder_that_is_not_positive_angles_is_refused_naming_it(bad):
    with pytest.raises(CalibError, match="sigmas must be positive angles in degrees"):
        SolveRequest(initial=TRUTH, sigmas_deg=bad).check()


def test_the_edges_second_opinion_counts_only_near_nids_answer():
    """Within the restarts' reach (2 deg / 5 cm) the edges' offset joins NID's sigma; farther, they found no minimum
    near it (a pinhole's edges often have none) and say nothing of NID's bias."""
    solved = PhotoResult(TRUTH.tau, (), 0.0, TRUTH.tau)
    trust = TrustOptions()
    near = np.array([0.0, np.radians(0.6), 0.0, 0.0, 0.04, 0.0])
    assert _cross_check(solved, tau_at(TRUTH.tau, near), trust).cross_check_pose == pytest.approx(tuple(near))
    far = np.array([0.0, np.radians(0.6), 0.0, 0.0, 0.07, 0.0])  # 7 cm along one axis: beyond the reach
    assert _cross_check(solved, tau_at(TRUTH.tau, far), trust) is trust
