"""Is an existing calibration still right for new pairs? A short search and a drift verdict (docs/check.md).

From the given extrinsics, only the finest ``levels`` of the schedule are run (the pose is expected to be
close), then the per-axis uncertainty of :mod:`calib.assess` (without restarts: the search starts at the
answer being checked). Per axis, in the local axes of docs/conventions.md:
- drifted: the change exceeds the threshold and ``significance`` sigmas (it is real and it matters); also
  when the rotation (or translation) change as a whole, the length of its 3-vector, exceeds the threshold
  and ``significance`` sigmas along its own direction: a 3 cm drift matters whichever way it points, though
  along a diagonal no single axis moves 2 cm;
- held: the change plus ``sigma_factor`` sigmas stays within the threshold (it is known not to matter);
- otherwise undetermined: the pairs cannot tell.
The status is ``drifted`` if any axis drifted, ``ok`` if every axis held, else ``unknown`` (naming the axes).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from calib.assess import TrustOptions, assess
from calib.geometry import Transform
from calib.gmm import PairFeatures
from calib.optimize import optimise, tail_options
from calib.pipeline import CalibParams, check_initial_guess, schedule
from calib.prior import Prior
from calib.uncertainty import AXES, TO_DISPLAY, xi_of

F64 = NDArray[np.float64]


class DriftStatus(Enum):
    OK = "ok"
    DRIFTED = "drifted"
    UNKNOWN = "unknown"


@dataclass(frozen=True)
class DriftOptions:
    """Thresholds of a change that matters (default the field tolerance, 0.2 deg / 2 cm per axis)."""

    threshold_rot_deg: float = 0.2
    threshold_trans_cm: float = 2.0
    levels: int = 2
    significance: float = 3.0
    sigma_factor: float = 2.5

    @property
    def threshold_display(self) -> F64:
        return np.array([self.threshold_rot_deg] * 3 + [self.threshold_trans_cm] * 3)


@dataclass(frozen=True)
class DriftResult:
    """``found`` the pose the pairs prefer; ``change`` (6,) deg/cm from the checked pose to it; ``sigma`` (6,)
    deg/cm its uncertainty; ``axes``: the drifted axes (drifted) or the undetermined ones (unknown)."""

    found: Transform
    change: F64
    sigma: F64
    status: DriftStatus
    axes: tuple[str, ...]
    reasons: tuple[str, ...]


def _whole_drift(change: F64, covariance: F64, group: slice, threshold: float, significance: float) -> float | None:
    """The sigma along the group's change (3 of the 6 axes) if its length is over ``threshold`` and
    ``significance`` such sigmas, else None."""
    v = change[group]
    length = float(np.linalg.norm(v))
    if length <= threshold:
        return None
    d = v / length
    sigma = float(np.sqrt(max(float(d @ covariance[group, group] @ d), 0.0)))
    return sigma if length > significance * sigma else None


def drift_verdict(change: F64, sigma: F64, opts: DriftOptions, covariance: F64 | None = None
                  ) -> tuple[DriftStatus, tuple[str, ...], tuple[str, ...]]:
    """Status, axes and reasons from the per-axis ``change`` and ``sigma`` (deg/cm) and the ``covariance``
    (6,6) deg/cm (None: independent axes with ``sigma``)."""
    thr = opts.threshold_display
    cov = np.diag(sigma**2) if covariance is None else covariance
    size = np.abs(change)
    drifted = (size > thr) & (size > opts.significance * sigma)
    held = size + opts.sigma_factor * sigma <= thr
    unit = ["deg"] * 3 + ["cm"] * 3
    reasons = [f"{AXES[k]} moved {change[k]:+.3g} {unit[k]} (threshold {thr[k]:g}, sigma {sigma[k]:.2g})"
               for k in np.flatnonzero(drifted)]
    for name, group, u in (("rotation", slice(0, 3), "deg"), ("translation", slice(3, 6), "cm")):
        along = _whole_drift(change, cov, group, float(thr[group][0]), opts.significance)
        if along is not None:
            drifted[group] |= size[group] > 0.5 * float(thr[group][0])  # name the axes that carry it
            parts = ", ".join(f"{AXES[k]} {change[k]:+.3g}" for k in range(6)[group])
            reasons.append(f"{name} moved {np.linalg.norm(change[group]):.3g} {u} ({parts}; threshold "
                           f"{thr[group][0]:g}, sigma along it {along:.2g})")
    if drifted.any():
        return DriftStatus.DRIFTED, tuple(AXES[k] for k in np.flatnonzero(drifted)), tuple(reasons)
    if held.all():
        return DriftStatus.OK, (), (f"every axis within its threshold at {opts.sigma_factor:g} sigma",)
    ks = np.flatnonzero(~held)
    return DriftStatus.UNKNOWN, tuple(AXES[k] for k in ks), tuple(
        f"{AXES[k]}: change {change[k]:+.3g} {unit[k]}, sigma {sigma[k]:.2g}: the pairs cannot tell" for k in ks)


def check_drift(feats: list[PairFeatures], checked: Transform, params: CalibParams, opts: DriftOptions,
                prior: Prior | None = None) -> DriftResult:
    """Search the finest levels from ``checked`` on ``feats`` and judge the change (module docstring)."""
    check_initial_guess(feats, checked.tau)
    full = schedule(feats, params, checked.tau)
    # A local question (is there a better pose near the checked one?): steepest descent, which stays in the
    # checked pose's basin; quasi-Newton steps along a direction few pairs pin can reach another one (measured:
    # 3 small pairs checked at their ground truth, 1.5 deg away and "drifted").
    optim = replace(tail_options(full, min(opts.levels, len(full.sigmas_deg))), quasi_newton=False)
    result = optimise(feats, checked.tau, optim, params.gmm, None, prior)
    trust = replace(TrustOptions(), tolerance_rot_deg=opts.threshold_rot_deg,
                    tolerance_trans_cm=opts.threshold_trans_cm, restarts=0)
    a = assess(feats, result, optim, params.gmm, prior, trust)
    change = xi_of(checked.tau, a.tau) * TO_DISPLAY
    sigma = a.uncertainty.sigma
    if not a.uncertainty.is_minimum:
        return DriftResult(Transform.from_tau(a.tau), change, sigma, DriftStatus.UNKNOWN, AXES,
                           ("the search did not end at a minimum of the cost",))
    cov = a.uncertainty.covariance * np.outer(TO_DISPLAY, TO_DISPLAY)
    status, axes, reasons = drift_verdict(change, sigma, opts, cov if np.all(np.isfinite(cov)) else None)
    return DriftResult(Transform.from_tau(a.tau), change, sigma, status, axes, reasons)
