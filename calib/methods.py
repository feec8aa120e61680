"""Calibration methods by name, their settings in one table, and :func:`solve`: one request, one path.

The methods: rigd's GMM (``gmm``, the default), NID with the trust assessment (``nid-assessed``,
calib.assess_photo), and for `rigd evaluate` only the paper's GMM as printed, its ablations (paper 8.3), the
photometric baselines of the paper's comparison (MI, NID, GOM; calib.photometric) and ``gmm+nid`` (the GMM,
then NID from its solution).

Every method runs on the same pairs, camera models and initial guess. The trust assessment is the GMM's
(calib.assess) for the GMM methods and calib.assess_photo's for nid-assessed; the photometric baselines
return no assessment (the caller reports the verdict as not assessed). A request a method cannot honour is
refused by name (:meth:`SolveRequest.check`), never quietly changed.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from calib.assess import TrustOptions
from calib.assess_photo import as_optim, assess_photometric, photo_elevation_slope
from calib.errors import CalibError, InitialGuessError
from calib.geometry import Transform
from calib.gmm import PairFeatures, SigmaModel
from calib.handed import Progress, collect, hand
from calib.optimize import OptimResult, optimise, tail_options
from calib.photometric import PhotoCost, PhotoPair, PhotoParams, PhotoResult, optimise_photometric
from calib.pipeline import (
    CalibParams,
    CalibResult,
    PairStats,
    PointEdgeMethod,
    calibrate,
    paper_params,
    schedule,
    solve_prior,
    with_sigmas,
)
from calib.prior import Prior
from calib.search import SearchOptions
from calib.uncertainty import xi_of

F64 = NDArray[np.float64]


class Method(Enum):
    GMM = "gmm"  # the paper's GMM with the changes of docs/method.md (default)
    NID_ASSESSED = "nid-assessed"  # NID with restarts, per-axis sigma and verdict (calib.assess_photo)
    PAPER = "paper"  # the GMM with the paper's settings as printed (section 8.2)
    MI = "mi"  # Pandey et al. 2015
    NID = "nid"  # koide3's direct_visual_lidar_calibration
    GOM = "gom"  # Taylor et al. 2015
    GMM_NID = "gmm+nid"  # the GMM, then NID's two finest levels from its solution
    GMM_W1 = "gmm-w1"  # ablation: w_ij = 1 (paper 8.3, non-weighted)
    GMM_UNIFORM = "gmm-uniform"  # ablation: sigma_i = sigma_in (paper 8.3, uniform sigma)
    GMM_PAPER_EDGES = "gmm-paper-edges"  # ablation: the paper's point edge score (eqs. 5-7)
    GMM_PAPER_SCHEDULE = "gmm-paper-schedule"  # ablation: the paper's three levels, plain descent

    @property
    def spec(self) -> MethodSpec:
        return METHODS[self]

    @property
    def uses_gmm(self) -> bool:
        return self.spec.gmm is not None

    @property
    def uses_photometric(self) -> bool:
        return self.spec.photo is not None


@dataclass(frozen=True)
class MethodSpec:
    """What a method solves with: ``gmm`` the GMM's settings (None: no GMM), ``photo`` the photometric cost's
    (None: none; both: the GMM, then the photometric cost from its solution), whether it has a trust
    assessment, whether `rigd calibrate` offers it (the others are research methods of `rigd evaluate`), and
    its name in words. ``cross_check``: an assessed photometric method's second opinion, the GMM's settings its
    edges are refined with from the solution (calib.assess.with_cross_check)."""

    label: str
    gmm: CalibParams | None
    photo: PhotoParams | None
    assessed: bool
    field: bool
    cross_check: CalibParams | None = None


# MI and NID compare values, not gradients: blurring the image by degrees flattens them (measured on the pinhole
# sample: NID changes by < 0.002 over +-1 deg at 4.2 deg of blur, by 0.012-0.029 at none), so their ladder
# is short and narrow. GOM keeps the paper's 12, 6, 3, 0 px of a 1024-wide panorama (section 8.2.1).
_HISTOGRAM = {"blur_deg": (1.0, 0.25, 0.0), "step_rot_deg": (2.0, 1.0, 0.3), "step_trans_m": (0.06, 0.04, 0.01)}


_RIGD = CalibParams()
# the paper's uniform sigma is half its sigma_in per level (7.5, 5, 2.5 px against 15, 10, 5)
_UNIFORM = replace(with_sigmas(_RIGD, tuple(0.5 * s for s in _RIGD.optim.sigmas_deg)),
                   gmm=replace(_RIGD.gmm, sigma_model=SigmaModel.UNIFORM))

METHODS: dict[Method, MethodSpec] = {
    Method.GMM: MethodSpec("GMM edge alignment", _RIGD, None, assessed=True, field=True),
    Method.NID_ASSESSED: MethodSpec("NID (image against LiDAR reflectivity)", None,
                                    PhotoParams(cost=PhotoCost.NID, **_HISTOGRAM),  # type: ignore[arg-type]
                                    assessed=True, field=True, cross_check=_RIGD),
    Method.PAPER: MethodSpec("the paper's GMM as printed", paper_params(), None, assessed=True, field=False),
    Method.MI: MethodSpec("MI baseline", None, PhotoParams(cost=PhotoCost.MI, **_HISTOGRAM),  # type: ignore[arg-type]
                          assessed=False, field=False),
    Method.NID: MethodSpec("NID baseline", None, PhotoParams(cost=PhotoCost.NID, **_HISTOGRAM),  # type: ignore[arg-type]
                           assessed=False, field=False),
    Method.GOM: MethodSpec("GOM baseline", None, PhotoParams(cost=PhotoCost.GOM), assessed=False, field=False),
    Method.GMM_NID: MethodSpec("GMM, then NID", _RIGD, PhotoParams(
        cost=PhotoCost.NID, blur_deg=(0.25, 0.0), step_rot_deg=(0.5, 0.2), step_trans_m=(0.04, 0.01)),
        assessed=False, field=False),
    Method.GMM_W1: MethodSpec("GMM with w_ij = 1", replace(_RIGD, gmm=replace(_RIGD.gmm, weighted=False)), None,
                              assessed=True, field=False),
    Method.GMM_UNIFORM: MethodSpec("GMM with a uniform sigma", _UNIFORM, None, assessed=True, field=False),
    Method.GMM_PAPER_EDGES: MethodSpec("GMM with the paper's point edges",
                                       replace(_RIGD, point_method=PointEdgeMethod.PAPER), None, assessed=True,
                                       field=False),
    # the ladder it names on every camera, a head's too
    Method.GMM_PAPER_SCHEDULE: MethodSpec("GMM with the paper's schedule", replace(
        _RIGD, optim=paper_params().optim, head_sigmas_deg=None), None, assessed=True, field=False),
}

FIELD_METHODS = tuple(m for m in Method if m.spec.field)  # what `rigd calibrate` and the service offer


@dataclass(frozen=True, kw_only=True)
class SolveRequest:
    """One calibration as :func:`solve` takes it: ``method``; ``initial`` the start (None: the global search of
    :mod:`calib.search`, with ``search``'s options); ``sigmas_deg`` the GMM's coarse-to-fine ladder (None: the
    method's own); ``prior`` the rig's drawing's; ``trust`` the assessment's options (None: not assessed);
    ``fit_elevation`` the LiDAR's common elevation offset fitted with the pose (calib.elevation)."""

    method: Method = Method.GMM
    initial: Transform | None = None
    sigmas_deg: tuple[float, ...] | None = None
    prior: Prior | None = None
    trust: TrustOptions | None = field(default_factory=TrustOptions)
    search: SearchOptions | None = None
    fit_elevation: bool = False

    @property
    def gmm(self) -> CalibParams | None:
        """The GMM's settings with the request's ladder (None: the method has no GMM)."""
        params = self.method.spec.gmm
        if params is None or self.sigmas_deg is None:
            return params
        return with_sigmas(params, self.sigmas_deg)

    @property
    def photo(self) -> PhotoParams | None:
        return self.method.spec.photo

    @property
    def edges(self) -> CalibParams | None:
        """The settings the GMM's edge features are extracted with: the method's GMM, or its cross-check's when
        assessed (None: the request needs no edges)."""
        if self.gmm is not None:
            return self.gmm
        return self.method.spec.cross_check if self.assessed else None

    @property
    def assessed(self) -> bool:
        return self.trust is not None and self.method.spec.assessed

    def check(self) -> None:
        """CalibError (InitialGuessError for a missing start) naming what ``method`` cannot do of this request."""
        name = self.method.value
        gmm = self.method.uses_gmm
        if self.sigmas_deg is not None and not gmm:
            raise CalibError(f"method {name} has no coarse-to-fine sigma ladder (it blurs by its own): the sigmas "
                             "apply to the GMM methods")
        if self.sigmas_deg is not None and not all(np.isfinite(s) and s > 0 for s in self.sigmas_deg):
            raise CalibError(f"sigmas must be positive angles in degrees, got {self.sigmas_deg}")
        if self.fit_elevation and (not gmm or self.method.uses_photometric):
            raise CalibError(f"method {name} cannot fit the LiDAR's elevation offset: only the GMM methods can")
        if self.initial is None and not gmm:
            raise InitialGuessError(f"method {name} needs an initial guess (the global search scores the GMM's "
                                    "edges): give a start, or calibrate with the GMM first")
        if self.prior is not None and self.prior.active and not gmm:
            raise CalibError(f"method {name}: a Gaussian prior is defined for the GMM cost only (its scale is not a "
                             "likelihood for MI, NID or GOM); fix the translation instead, or use the GMM")


def solve(request: SolveRequest, *, feats: list[PairFeatures] | None = None, photo: list[PhotoPair] | None = None,
          search_photo: list[PhotoPair] | None = None, executor: Executor | None = None,
          on_iter: Callable[[int, int, float], None] | None = None,
          on_search: Callable[[int, int], None] | None = None, on_assess: Progress | None = None) -> CalibResult:
    """Calibrate as ``request`` asks. ``feats``: the GMM features (GMM methods; for an assessed photometric one its
    cross-check's edges, or None to go without), ``photo``: the photometric pairs (photometric methods),
    ``search_photo``: the pairs' images and reflectivity for the global search's score (calib.search_mi).
    ``executor``: the application's pool for the independent solves. The result has an assessment when the
    request is assessed (:attr:`SolveRequest.assessed`); ``on_assess(done, total)``: its restarts."""
    request.check()
    gmm, photo_opts = request.gmm, request.photo
    trust = request.trust if request.assessed else None
    result: CalibResult | None = None
    if gmm is not None:
        if feats is None:
            raise CalibError(f"method {request.method.value} needs the GMM edge features")
        result = calibrate(feats, request.initial, gmm, on_iter=on_iter, prior=request.prior,
                           trust=None if photo_opts is not None else trust, search=request.search,
                           on_search=on_search, executor=executor, search_photo=search_photo,
                           fit_elevation=request.fit_elevation, on_assess=on_assess)
    if photo_opts is None:
        assert result is not None
        return result
    if photo is None:
        raise CalibError(f"method {request.method.value} needs the photometric pairs (image and LiDAR reflectivity)")
    edges = feats if gmm is None else None
    return _photometric(request, photo, photo_opts, result, trust, executor, on_iter, edges, on_assess)


def _photometric(request: SolveRequest, photo: list[PhotoPair], opts: PhotoParams, gmm: CalibResult | None,
                 trust: TrustOptions | None, executor: Executor | None,
                 on_iter: Callable[[int, int, float], None] | None,
                 edges: list[PairFeatures] | None = None, on_assess: Progress | None = None) -> CalibResult:
    """The photometric solve from the request's start (or from the GMM's solution, ``gmm``), assessed with
    ``trust`` (nid-assessed; a declared elevation offset's sigma enters as in the GMM's: calib.assess_photo)."""
    prior = request.prior
    fixed = prior is not None and prior.fix_translation
    start = gmm.T_camera_lidar if gmm is not None else request.initial
    assert start is not None
    if fixed and prior is not None and prior.xyz_m is not None and gmm is None:
        start = Transform(start.rotation, prior.xyz_m)
    solved = optimise_photometric(photo, start.tau, opts, fixed_translation=fixed, on_iter=on_iter)
    stats = gmm.pairs if gmm is not None else tuple(PairStats(0, 0, int(len(p.points_lidar))) for p in photo)
    if trust is not None:
        cross = request.method.spec.cross_check
        refined = hand(executor, refine_edges, edges, solved.tau, cross, prior, trust.restart_levels) \
            if edges and cross is not None else None
        if trust.elevation_sigma_deg > 0:
            slope = photo_elevation_slope(photo, solved, opts, fixed, executor)
            trust = replace(trust, elevation_sigma_pose=tuple(float(v) for v in slope * trust.elevation_sigma_deg))
        if refined is not None:
            trust = _cross_check(solved, collect([refined])[0], trust)
        a = assess_photometric(photo, solved, opts, trust, fixed_translation=fixed, starts=(start.tau,),
                               executor=executor, on_progress=on_assess)
        return CalibResult(Transform.from_tau(a.tau), a.optim, stats, a)
    return CalibResult(Transform.from_tau(np.asarray(solved.tau)), _levels(solved, gmm), stats, None)


def refine_edges(feats: list[PairFeatures], tau: F64, params: CalibParams, prior: Prior | None, levels: int) -> F64:
    """The GMM's edges refined from ``tau`` (6,) over the last ``levels`` levels of their schedule from there (one
    more when folds are on every level, as the restarts of calib.assess), its lever arm a weak prior as a GMM solve's
    guess is (calib.pipeline.solve_prior): where the edges put the pose near it."""
    optim = schedule(feats, params, tau)
    levels += 1 if optim.fold_levels >= len(optim.sigmas_deg) else 0
    tail = tail_options(optim, min(levels, len(optim.sigmas_deg)))
    anchored = solve_prior(prior, Transform.from_tau(tau), params.guess_sigma_m)
    return np.asarray(optimise(feats, tau, tail, params.gmm, prior=anchored).tau, dtype=np.float64)


def _cross_check(solved: PhotoResult, refined: F64, trust: TrustOptions) -> TrustOptions:
    """``trust`` with the edges' offset from NID's answer, if they stayed within the restarts' reach of it (every
    axis within +-2 deg / +-5 cm): farther, the edges have no minimum near it (a pinhole's edges often have none,
    docs/baselines.md), which says nothing of NID's bias."""
    offset = xi_of(np.asarray(solved.tau, dtype=np.float64), refined)
    reach = np.array([np.radians(trust.restart_rot_deg)] * 3 + [trust.restart_trans_m] * 3)
    if np.any(np.abs(offset) > reach):
        return trust
    return replace(trust, cross_check_pose=tuple(float(v) for v in offset))


def _levels(solved: PhotoResult, gmm: CalibResult | None) -> OptimResult:
    """The photometric solve as optimiser levels, after the GMM's when it started from its solution."""
    optim = as_optim(solved)
    if gmm is None:
        return optim
    return OptimResult(solved.tau, gmm.optim.levels + optim.levels, gmm.optim.converged, solved.final_cost)
