"""Is an existing calibration still right for new pairs? A short search and a three-way answer (docs/check.md).

From the checked extrinsics only the finest ``levels`` of the schedule are run (the pose is expected to be
close), then the uncertainty of :mod:`calib.assess` without restarts (the search starts at the answer being
checked). The change from the checked pose to the pose the pairs prefer is judged per group of axes, rotation
(deg) and translation (cm), by its length: a drift matters whichever way it points.

- ``ok``: for both groups, the largest change consistent with the pairs at ``ok_confidence`` (one-sided, along
  any direction) is within the threshold. If a group truly moved by its threshold or more, ``ok`` is answered
  with probability at most ``1 - ok_confidence``; both groups must pass, so the two tests need no correction
  (an intersection-union test).
- ``drifted``: for some group the change is longer than the threshold, and real: Hotelling's T² of the change
  over its covariance (3 axes) is beyond its quantile at ``drift_confidence``, shared between the two groups.
  With no drift at all it is answered with probability at most ``1 - drift_confidence``.
- ``unknown``: neither; and always where the pairs cannot pin the pose down: fewer than 4 places (below), or a
  calibration from them would be ``failed`` at the field tolerance ``trust`` (docs/trust.md: not a minimum, several
  axes beyond 5 tolerances, or no axis known). There the minimum the search finds may lie far from the truth
  with sigmas that describe only that minimum (measured: 11 simulated pinhole pairs checked at their ground truth
  found 1.15 deg and 9.6 cm, yaw 7.5 sigma, and every axis beyond the tolerance at 2.5 sigma).

The covariance's scale is measured across places (the jackknife leaves out a place at a time), so it is known
to ``places - 1`` degrees of freedom: the quantiles are Student's t and Hotelling's T² for that many, not the
normal's. With fewer than 4 places a group of 3 axes has no such test, and the answer is ``unknown``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray
from scipy.special import fdtri, stdtrit

from calib.assess import Status, TrustOptions, assess
from calib.geometry import Transform
from calib.gmm import PairFeatures
from calib.optimize import optimise, tail_options
from calib.pipeline import CalibParams, check_initial_guess, schedule
from calib.prior import Prior
from calib.uncertainty import AXES, TO_DISPLAY, places, xi_of

F64 = NDArray[np.float64]

GROUP_AXES = 3  # a group's dimension: Hotelling's T² needs more places than this
MAX_ADVISED_FACTOR = 4  # advise a number of pairs up to this many times the places checked


def percent(share: float) -> str:
    """0.95 -> "95 %"."""
    return f"{share * 100:g} %"


class DriftStatus(Enum):
    OK = "ok"
    DRIFTED = "drifted"
    UNKNOWN = "unknown"


class Group(Enum):
    """A group of axes judged together by the length of its change."""

    ROTATION = "rotation"
    TRANSLATION = "translation"

    @property
    def axes(self) -> slice:
        return slice(0, 3) if self is Group.ROTATION else slice(3, 6)

    @property
    def unit(self) -> str:
        return "deg" if self is Group.ROTATION else "cm"


@dataclass(frozen=True)
class DriftOptions:
    """``threshold_rot_deg`` / ``threshold_trans_cm``: the length of a rotation (deg) / translation (cm) change that
    matters (defaults: what 12 good pairs resolve at these confidences, docs/check.md). ``levels``: the finest
    levels of the schedule searched. ``trust``: the field tolerance of the pairs' own verdict (the rig's)."""

    threshold_rot_deg: float = 0.3
    threshold_trans_cm: float = 2.0
    levels: int = 2
    ok_confidence: float = 0.95
    drift_confidence: float = 0.95
    trust: TrustOptions = TrustOptions()

    def threshold(self, group: Group) -> float:
        return self.threshold_rot_deg if group is Group.ROTATION else self.threshold_trans_cm


@dataclass(frozen=True)
class Quantiles:
    """For a covariance known to ``dof`` degrees of freedom: ``t`` the one-sided Student t of the ok bound, and
    ``t2_limit`` Hotelling's T² of one group beyond which a change is real."""

    dof: int
    t: float
    t2_limit: float


def quantiles(n_places: int, opts: DriftOptions) -> Quantiles | None:
    """The quantiles for a covariance measured across ``n_places`` places; None with too few for a group test."""
    dof = n_places - 1
    if dof < GROUP_AXES:
        return None
    return Quantiles(dof, float(stdtrit(dof, opts.ok_confidence)), t2_limit(dof, GROUP_AXES, opts))


def t2_limit(dof: int, axes: int, opts: DriftOptions) -> float:
    """Hotelling's T² limit of ``axes`` axes judged together, the covariance known to ``dof`` degrees of freedom."""
    alpha = (1.0 - opts.drift_confidence) / len(Group)  # Bonferroni: either group may raise the alarm
    denominator = dof - axes + 1
    return dof * axes / denominator * float(fdtri(axes, denominator, 1.0 - alpha))


def _secular_root(terms: list[tuple[float, float]], lo: float, hi: float) -> float:
    """lam in (lo, hi] where sum (b / (lam - a))^2 = 1 over ``terms`` (b, a), the sum falling in lam: Newton on
    1 / |w| - 1, nearly linear in lam (More and Sorensen), kept in the bracket by bisection. Floats: 3 terms."""
    lam = hi
    for _ in range(100):
        d = [(bi, max(lam - ai, 1e-300)) for bi, ai in terms]
        s = sum((bi / di) ** 2 for bi, di in d)
        if abs(s - 1.0) < 1e-13 or s == 0.0:
            break
        lo, hi = (lam, hi) if s > 1.0 else (lo, lam)
        slope = sum(bi * bi / di**3 for bi, di in d) * s**-1.5  # d(1/|w|)/dlam
        step = lam - (s**-0.5 - 1.0) / slope
        lam = step if lo < step < hi else 0.5 * (lo + hi)
    return lam


def farthest_change(change: F64, covariance: F64, k: float) -> F64:
    """The point of the ellipsoid ``change + k cov^1/2 w`` (|w| <= 1) farthest from no change. Its length is the
    largest of ``u . change + k sqrt(u' cov u)`` over unit directions u: the one-sided bound, at k, on the length
    of the true change along its own (unknown) direction."""
    values, vectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
    a2 = k * k * np.maximum(values, 0.0)  # squared semi-axes
    b = np.sqrt(a2) * (vectors.T @ change)
    # On the sphere |w| = 1 the maximum has w_i = b_i / (lam - a2_i) with lam >= max(a2) (eigen coordinates).
    lo = float(a2.max())
    longest = a2 >= lo * (1.0 - 1e-12)
    if np.all(np.abs(b[longest]) <= 1e-12 * (1.0 + float(np.linalg.norm(b)))):
        # no component along the longest axes: the rest may reach the sphere short of lam = max(a2)
        w = np.where(longest, 0.0, b / np.where(longest, 1.0, lo - a2))
        if float(w @ w) <= 1.0:
            w[int(np.argmax(longest))] = np.sqrt(1.0 - float(w @ w))
            return np.asarray(change + vectors @ (np.sqrt(a2) * w), dtype=np.float64)
    hi = lo + float(np.linalg.norm(b)) + 1e-300
    lam = _secular_root(list(zip(b.tolist(), a2.tolist(), strict=True)), lo, hi)
    return np.asarray(change + vectors @ (np.sqrt(a2) * (b / np.maximum(lam - a2, 1e-300))), dtype=np.float64)


def hotelling_t2(change: F64, covariance: F64) -> float:
    """``change' cov^-1 change`` (a direction the covariance leaves at zero, as a held translation, adds nothing)."""
    return float(change @ np.linalg.pinv(covariance, rcond=1e-12, hermitian=True) @ change)


@dataclass(frozen=True)
class GroupChange:
    """One group's change (deg or cm): ``change`` per axis, ``length`` its length, ``upper`` the largest length
    consistent with the pairs at the ok confidence, ``farthest`` the change of that length (which axes carry
    it), ``t2`` Hotelling's T² of the change over its covariance along the determined axes and ``t2_limit`` its
    limit, ``threshold``."""

    group: Group
    change: tuple[float, ...]
    length: float
    upper: float
    farthest: tuple[float, ...]
    t2: float
    t2_limit: float
    threshold: float
    known_length: float  # the length of the change along the axes the pairs determine
    known: tuple[bool, ...]  # per axis of the group: determined by the pairs (:func:`determined`)
    sigma: tuple[float, ...]  # per axis of the group

    @property
    def within(self) -> bool:
        return self.upper <= self.threshold

    @property
    def drifted(self) -> bool:
        return self.known_length > self.threshold and self.t2 > self.t2_limit

    @property
    def open_axes(self) -> list[str]:
        """The axes of the group the pairs do not determine."""
        return [AXES[k] for k, known in zip(range(6)[self.group.axes], self.known, strict=True) if not known]


def group_change(group: Group, change: F64, covariance: F64, q: Quantiles, opts: DriftOptions) -> GroupChange:
    """The change of ``group`` from the 6-vector ``change`` and the (6,6) ``covariance`` (deg/cm). Whether it is
    real is asked of the axes the pairs determine (:func:`determined`) alone: along an axis they leave open the
    minimum the search finds says nothing of a drift (its covariance describes that minimum only)."""
    c, cov = change[group.axes], covariance[group.axes, group.axes]
    far = farthest_change(c, cov, q.t)
    sigma = np.sqrt(np.maximum(np.diag(cov), 0.0))
    known = determined(sigma, q, opts.threshold(group))
    c_known = np.where(known, c, 0.0)
    limit = t2_limit(q.dof, int(known.sum()), opts) if known.any() else q.t2_limit  # nothing known: no drift
    return GroupChange(group, tuple(c.tolist()), float(np.linalg.norm(c)), float(np.linalg.norm(far)),
                       tuple(far.tolist()), hotelling_t2(c[known], cov[np.ix_(known, known)]), limit,
                       opts.threshold(group), float(np.linalg.norm(c_known)), tuple(bool(k) for k in known),
                       tuple(sigma.tolist()))


def determined(sigma: F64, q: Quantiles, threshold: float) -> NDArray[np.bool_]:
    """Per axis of a group (sigma in its unit): whether the pairs pin it finely enough to resolve a change of
    ``threshold``, the one-sided bound ``t sigma`` within it."""
    return np.asarray(q.t * sigma <= threshold)


@dataclass(frozen=True)
class Judgement:
    """The answer, the axes it names, its reasons in words, and each group's change (deg / cm)."""

    status: DriftStatus
    axes: tuple[str, ...]  # the drifted axes (drifted) or those the pairs cannot tell (unknown)
    reasons: tuple[str, ...]
    groups: tuple[GroupChange, ...]  # empty when no group could be judged


def _carriers(group: Group, values: tuple[float, ...]) -> list[str]:
    """The axes of ``group`` that carry at least half of the length of ``values``."""
    length = float(np.linalg.norm(values))
    return [AXES[k] for k, v in zip(range(6)[group.axes], values, strict=True) if abs(v) >= 0.5 * length]


def _drift_reason(g: GroupChange) -> str:
    parts = ", ".join(f"{AXES[k]} {v:+.3g}" for k, v, known in zip(range(6)[g.group.axes], g.change, g.known,
                                                                   strict=True) if known)
    return (f"{g.group.value} moved {g.known_length:.3g} {g.group.unit} ({parts}; threshold {g.threshold:g}); "
            f"real: T² {g.t2:.3g} > {g.t2_limit:.3g}")


def _unknown_reason(g: GroupChange, n_places: int, opts: DriftOptions) -> str:
    text = (f"{g.group.value} changed {g.length:.2g} {g.group.unit}, up to {g.upper:.2g} at "
            f"{percent(opts.ok_confidence)} confidence (threshold {g.threshold:g}): the pairs cannot tell")
    # sigma falls as 1/sqrt(places): the margin upper - length must shrink into threshold - length
    needed = math.ceil(n_places * ((g.upper - g.length) / max(g.threshold - g.length, 1e-12)) ** 2)
    if needed > MAX_ADVISED_FACTOR * n_places:
        return text + (f"; with a spread of {g.upper - g.length:.2g} {g.group.unit} more than "
                       f"{MAX_ADVISED_FACTOR * n_places} pairs would be needed")
    return text + f"; about {needed} pairs at varied places would"


def judge(change: F64, covariance: F64, n_places: int, opts: DriftOptions) -> Judgement:
    """The answer for the 6-vector ``change`` and its (6,6) ``covariance`` (deg/cm), measured across
    ``n_places`` places (module docstring)."""
    q = quantiles(n_places, opts)
    if q is None:
        return Judgement(DriftStatus.UNKNOWN, AXES, (
            f"{n_places} places: the uncertainty is measured across places, and judging 3 axes together needs "
            f"at least {GROUP_AXES + 1}",), ())
    if not np.all(np.isfinite(covariance)):
        return Judgement(DriftStatus.UNKNOWN, AXES, ("the uncertainty could not be measured",), ())
    groups = tuple(group_change(group, change, covariance, q, opts) for group in Group)
    drifted = [g for g in groups if g.drifted]
    if drifted:
        return Judgement(DriftStatus.DRIFTED, tuple(a for g in drifted for a in _carriers(g.group, _known(g))),
                         tuple(_drift_reason(g) for g in drifted), groups)
    if all(g.within for g in groups):
        rot, trans = groups
        return Judgement(DriftStatus.OK, (), (
            f"within {rot.threshold:g} deg and {trans.threshold:g} cm at {percent(opts.ok_confidence)} confidence: "
            f"rotation at most {rot.upper:.2g} deg, translation at most {trans.upper:.2g} cm",), groups)
    open_groups = [g for g in groups if not g.within]
    axes = [a for g in open_groups for a in (*g.open_axes, *_carriers(g.group, g.farthest))]
    reasons = [_unknown_reason(g, n_places, opts) for g in open_groups]
    reasons += [_open_reason(g, q) for g in groups if g.open_axes]
    return Judgement(DriftStatus.UNKNOWN, tuple(dict.fromkeys(axes)), tuple(reasons), groups)


def _known(g: GroupChange) -> tuple[float, ...]:
    """The change along the determined axes (0 along the others)."""
    return tuple(v if known else 0.0 for v, known in zip(g.change, g.known, strict=True))


def _open_reason(g: GroupChange, q: Quantiles) -> str:
    """Why the open axes of ``g`` are not judged, and what would pin them."""
    sigmas = ", ".join(f"{a} sigma {s:.2g} {g.group.unit}" for a, s, known in zip(
        AXES[g.group.axes], g.sigma, g.known, strict=True) if not known)
    what = ("pairs with structure 2-10 m from the rig, or the lever arm from the rig's drawing"
            if g.group is Group.TRANSLATION else "more pairs at varied places, with edges in several directions")
    return (f"{', '.join(g.open_axes)}: the pairs do not pin {'it' if len(g.open_axes) == 1 else 'them'} "
            f"({sigmas}; resolving {g.threshold:g} {g.group.unit} needs a sigma below {g.threshold / q.t:.2g}): "
            f"not judged; {what} would")


@dataclass(frozen=True)
class DriftResult:
    """``found`` the pose the pairs prefer; ``change`` (6,) deg/cm from the checked pose to it, ``sigma`` (6,)
    deg/cm and ``covariance`` (6,6) deg/cm its uncertainty; ``places`` how many places the pairs show;
    ``judgement`` the answer."""

    found: Transform
    change: F64
    sigma: F64
    covariance: F64
    places: int
    judgement: Judgement

    @property
    def status(self) -> DriftStatus:
        return self.judgement.status

    @property
    def axes(self) -> tuple[str, ...]:
        return self.judgement.axes

    @property
    def reasons(self) -> tuple[str, ...]:
        return self.judgement.reasons


def check_drift(feats: list[PairFeatures], checked: Transform, params: CalibParams, opts: DriftOptions,
                prior: Prior | None = None) -> DriftResult:
    """Search the finest levels from ``checked`` on ``feats`` and judge the change (module docstring)."""
    check_initial_guess(feats, checked.tau)
    full = schedule(feats, params, checked.tau)
    # A local question (is there a better pose near the checked one?): steepest descent, which stays in the
    # checked pose's basin; quasi-Newton steps along a direction few pairs pin can reach another one (measured:
    # 3 small pairs checked at their ground truth, 1.5 deg away and "drifted").
    optim = replace(tail_options(full, min(opts.levels, len(full.sigmas_deg))), quasi_newton=False)
    result = optimise(feats, checked.tau, optim, params.gmm, prior=prior)
    a = assess(feats, result, optim, params.gmm, prior=prior, trust=replace(opts.trust, restarts=0))
    change = xi_of(checked.tau, a.tau) * TO_DISPLAY
    covariance = a.uncertainty.covariance * np.outer(TO_DISPLAY, TO_DISPLAY)
    n_places = int(places(feats).max()) + 1
    if a.verdict.status is Status.FAILED:
        judgement = Judgement(DriftStatus.UNKNOWN, AXES, (
            "the pairs cannot pin the pose down: a calibration from them would be failed", *a.verdict.reasons), ())
    else:
        judgement = judge(change, covariance, n_places, opts)
    return DriftResult(Transform.from_tau(a.tau), change, a.uncertainty.sigma, covariance, n_places, judgement)
