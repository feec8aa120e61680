"""Calibration methods by name: rigd's GMM, the paper's GMM as printed, its ablations (paper 8.3), the
photometric baselines of the paper's comparison (MI, NID, GOM; calib.photometric), rigd+nid (the GMM, then
NID from its solution) and nid-assessed (NID with the trust assessment of calib.assess_photo).

Every method runs on the same pairs, camera models and initial guess. The trust assessment is the GMM's
(calib.assess) for the GMM methods and calib.assess_photo's for nid-assessed; the photometric baselines
return no assessment (the caller reports the verdict as not assessed).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import replace
from enum import Enum

import numpy as np

from calib.assess import TrustOptions
from calib.assess_photo import as_optim, assess_photometric
from calib.errors import CalibError, InitialGuessError
from calib.geometry import Transform
from calib.gmm import PairFeatures, SigmaModel
from calib.initial import SearchOptions
from calib.optimize import OptimResult
from calib.photometric import PhotoCost, PhotoPair, PhotoParams, optimise_photometric
from calib.pipeline import CalibParams, CalibResult, PairStats, PointEdgeMethod, calibrate, paper_params, with_sigmas
from calib.prior import Prior


class Method(Enum):
    RIGD = "rigd"  # the GMM with the changes of docs/method.md (default)
    PAPER = "paper"  # the GMM with the paper's settings as printed (section 8.2)
    MI = "mi"  # Pandey et al. 2015
    NID = "nid"  # koide3's direct_visual_lidar_calibration
    GOM = "gom"  # Taylor et al. 2015
    RIGD_NID = "rigd+nid"  # rigd's GMM, then NID's two finest levels from its solution
    NID_ASSESSED = "nid-assessed"  # NID with restarts, per-axis sigma and verdict (calib.assess_photo)
    GMM_W1 = "gmm-w1"  # ablation: rigd with w_ij = 1 (paper 8.3, non-weighted)
    GMM_UNIFORM = "gmm-uniform"  # ablation: rigd with sigma_i = sigma_in (paper 8.3, uniform sigma)
    GMM_PAPER_EDGES = "gmm-paper-edges"  # ablation: rigd with the paper's point edge score (eqs. 5-7)
    GMM_PAPER_SCHEDULE = "gmm-paper-schedule"  # ablation: rigd with the paper's three levels, plain descent

    @property
    def uses_gmm(self) -> bool:
        return self not in (Method.MI, Method.NID, Method.GOM, Method.NID_ASSESSED)

    @property
    def uses_photometric(self) -> bool:
        return self in (Method.MI, Method.NID, Method.GOM, Method.RIGD_NID, Method.NID_ASSESSED)


# MI and NID compare values, not gradients: blurring the image by degrees flattens them (measured on the pinhole
# sample: NID changes by < 0.002 over +-1 deg at 4.2 deg of blur, by 0.012-0.029 at none), so their ladder
# is short and narrow. GOM keeps the paper's 12, 6, 3, 0 px of a 1024-wide panorama (section 8.2.1).
_HISTOGRAM_LEVELS = {"blur_deg": (1.0, 0.25, 0.0), "step_rot_deg": (2.0, 1.0, 0.3),
                     "step_trans_m": (0.06, 0.04, 0.01)}


def photo_params(method: Method) -> PhotoParams | None:
    """The photometric settings of ``method`` (None for the GMM-only methods)."""
    if method is Method.GOM:
        return PhotoParams(cost=PhotoCost.GOM)
    if method in (Method.MI, Method.NID):
        return PhotoParams(cost=PhotoCost(method.value), **_HISTOGRAM_LEVELS)  # type: ignore[arg-type]
    if method is Method.NID_ASSESSED:
        return PhotoParams(cost=PhotoCost.NID, **_HISTOGRAM_LEVELS)  # type: ignore[arg-type]
    if method is Method.RIGD_NID:
        return PhotoParams(cost=PhotoCost.NID, blur_deg=(0.25, 0.0), step_rot_deg=(0.5, 0.2),
                           step_trans_m=(0.04, 0.01))
    return None


def gmm_params(method: Method) -> CalibParams | None:
    """The GMM settings of ``method`` (None for the photometric-only methods)."""
    rigd = CalibParams()
    if not method.uses_gmm:
        return None
    if method is Method.PAPER:
        return paper_params()
    if method is Method.GMM_W1:
        return replace(rigd, gmm=replace(rigd.gmm, weighted=False))
    if method is Method.GMM_UNIFORM:
        # the paper's uniform sigma is half its sigma_in per level (7.5, 5, 2.5 px against 15, 10, 5)
        sigmas = tuple(0.5 * s for s in rigd.optim.sigmas_deg)
        return replace(with_sigmas(rigd, sigmas), gmm=replace(rigd.gmm, sigma_model=SigmaModel.UNIFORM))
    if method is Method.GMM_PAPER_EDGES:
        return replace(rigd, point_method=PointEdgeMethod.PAPER)
    if method is Method.GMM_PAPER_SCHEDULE:
        return replace(rigd, optim=paper_params().optim, head_sigmas_deg=None)  # the ladder it names, a head's too
    return rigd


def _fixed_translation(prior: Prior | None, method: Method) -> bool:
    if prior is None:
        return False
    if prior.active:
        raise CalibError(f"method {method.value}: a Gaussian prior is defined for the GMM cost only (its scale is "
                         "not a likelihood for MI, NID or GOM); use --fix translation or a GMM method")
    return prior.fix_translation


def calibrate_method(
    method: Method,
    feats: list[PairFeatures] | None,
    photo: list[PhotoPair] | None,
    initial: Transform | None,
    params: CalibParams | None = None,
    on_iter: Callable[[int, int, float], None] | None = None,
    prior: Prior | None = None,
    trust: TrustOptions | None = None,
    search: SearchOptions | None = None,
    on_search: Callable[[int, int], None] | None = None,
    executor: Executor | None = None,
    search_photo: list[PhotoPair] | None = None,
    fit_elevation: bool = False,
) -> CalibResult:
    """Calibrate with ``method`` from ``initial``. ``feats``: the GMM features (GMM methods), ``photo``: the
    photometric pairs (MI, NID, GOM, rigd+nid). ``params`` overrides :func:`gmm_params` (GMM methods only).
    The result has an assessment only for GMM-only methods and nid-assessed, with ``trust``. ``initial`` None:
    the global search of :mod:`calib.initial` (it scores the GMM's edge fields, so the photometric-only methods
    need a guess).
    ``executor``: the GMM's independent solves side by side (:func:`calib.pipeline.calibrate`).
    ``search_photo``: the pairs' images and reflectivity for the global search's score (calib.search_mi).
    ``fit_elevation``: the LiDAR's elevation offset fitted with the pose (calib.elevation; GMM-only methods)."""
    gmm = (params if params is not None else gmm_params(method)) if method.uses_gmm else None
    photo_opts = photo_params(method)
    result: CalibResult | None = None
    if fit_elevation and (gmm is None or photo_opts is not None):
        raise CalibError(f"method {method.value} cannot fit the LiDAR's elevation offset: only the GMM methods can")
    if gmm is not None:
        if feats is None:
            raise CalibError(f"method {method.value} needs the GMM edge features")
        result = calibrate(feats, initial, gmm, on_iter, prior, None if photo_opts is not None else trust,
                           search, on_search, executor, search_photo, fit_elevation)
    if photo_opts is None:
        assert result is not None
        return result
    if photo is None:
        raise CalibError(f"method {method.value} needs the photometric pairs (image and LiDAR reflectivity)")
    if initial is None and result is None:
        raise InitialGuessError(f"method {method.value} needs an initial guess (the global search scores the GMM's "
                                "edges): give --init, or calibrate with the default method first")
    fixed = _fixed_translation(prior, method) if result is None else bool(prior is not None and prior.fix_translation)
    start = result.T_camera_lidar if result is not None else initial
    assert start is not None
    if fixed and prior is not None and prior.xyz_m is not None and result is None:
        start = Transform(start.rotation, prior.xyz_m)
    solved = optimise_photometric(photo, start.tau, photo_opts, fixed_translation=fixed)
    if method is Method.NID_ASSESSED and trust is not None:
        a = assess_photometric(photo, solved, photo_opts, trust, fixed, starts=(start.tau,), executor=executor)
        stats = tuple(PairStats(0, int(len(p.points_lidar))) for p in photo)
        return CalibResult(Transform.from_tau(a.tau), a.optim, stats, a)
    optim = as_optim(solved)
    if result is not None:  # rigd+nid: the GMM's levels, then NID's
        optim = OptimResult(solved.tau, result.optim.levels + optim.levels, result.optim.converged,
                            solved.final_cost)
        stats = result.pairs
    else:
        stats = tuple(PairStats(0, int(len(p.points_lidar))) for p in photo)
    return CalibResult(Transform.from_tau(np.asarray(solved.tau)), optim, stats, None)
