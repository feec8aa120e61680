"""How well each axis of ``T_camera_lidar`` is known: Laplace (sandwich) covariance of the finest level.

Local coordinates (docs/conventions.md): ``xi = [delta (3) rad, dt (3) m]`` around a solution
``(R_hat, t_hat)`` with ``R = R_hat exp(delta^)`` and ``t = t_hat + dt``. ``delta`` rotates the LiDAR about its
own x, y, z axes (roll, pitch, yaw: well defined for a pinhole camera too, where the Euler angles of
``T_camera_lidar`` sit at the gimbal lock), ``dt`` moves the LiDAR origin in the camera frame (x, y, z of
``xyz_m``).

The GMM cost (eq. 8) is not a log-likelihood: its scale depends on sigma_in, the kernel height and the
number of points. So the Laplace covariance ``H^-1`` (H = Hessian of the finest-level cost at the solution)
is scaled by the data, not by an assumption: the M-estimator sandwich ``H^-1 B H^-1``, with ``B`` the
scatter of the cost's gradient summed over independent clusters of edge points. Points of one edge share
their errors (a silhouette's mixed returns, one image edge), so clusters are angular cells of the image
(``cell_deg``) in each pair, not single points. The same pieces give the cost's scale in log-likelihood
units, ``kappa``: for a true negative log-likelihood ``B = H`` axis by axis (``kappa = 1``), so ``kappa`` is the
median over the axes of ``B_kk / H_kk``; it is how a prior is weighed against the images.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from calib.geometry import cross_rows, so3_exp, so3_log
from calib.gmm import Frozen, GmmOptions, PairFeatures, freeze_all, pair_terms, transform_points

if TYPE_CHECKING:  # calib.photometric imports this module
    from calib.photometric import PhotoPair

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

AXES = ("roll", "pitch", "yaw", "x", "y", "z")
TO_DISPLAY = np.array([np.degrees(1.0)] * 3 + [100.0] * 3)  # rad -> deg, m -> cm
UNITS = ("deg", "deg", "deg", "cm", "cm", "cm")


def tau_at(tau_hat: F64, xi: F64) -> F64:
    """Optimiser parameters ``[omega, t]`` of the pose ``xi`` (local coordinates) away from ``tau_hat``."""
    rotation = so3_exp(tau_hat[:3]) @ so3_exp(xi[:3])
    return np.concatenate([so3_log(rotation), tau_hat[3:] + xi[3:]])


def xi_of(tau_hat: F64, tau: F64) -> F64:
    """Local coordinates (6,) of ``tau`` around ``tau_hat`` (inverse of :func:`tau_at`)."""
    delta = so3_log(so3_exp(tau_hat[:3]).T @ so3_exp(tau[:3]))
    return np.concatenate([delta, tau[3:] - tau_hat[3:]])


@dataclass(frozen=True)
class LevelModel:
    """One coarse-to-fine level as a function of the pose: the pairs, sigma_in (px) per pair, the options."""

    feats: tuple[PairFeatures, ...]
    sigma_in_px: tuple[float, ...]
    gmm: GmmOptions

    def freeze(self, tau: F64) -> list[Frozen]:
        return freeze_all(list(self.feats), tau, list(self.sigma_in_px), self.gmm)


@dataclass(frozen=True)
class Clusters:
    """Edge points grouped into independent clusters: ``labels`` per pair, (N_i,) int64 cluster id of each
    edge point (the angular image cell it projects into at the solution, and with ``by_ring`` its ring too;
    unique over all pairs), ``pair`` (C,) int64 the place of each cluster (:func:`places`), ``cell`` (C,) int64
    the image cell of each (several clusters per cell when they are split by ring), ``ring`` (C,) int64 the
    ring of each (-1: not split by ring)."""

    labels: tuple[I64, ...]
    pair: I64
    cell: I64
    ring: I64

    @property
    def count(self) -> int:
        return len(self.pair)

    @property
    def cells(self) -> int:
        return int(self.cell.max()) + 1 if self.cell.size else 0

    def per_cell(self, values: F64) -> F64:
        """``values`` (C, ...) summed over the clusters of each image cell: (cells, ...)."""
        out = np.zeros((self.cells, *values.shape[1:]))
        np.add.at(out, self.cell, values)
        return out


def places(feats: Sequence[PairFeatures] | Sequence[PhotoPair]) -> I64:
    """(P,) int64: the place of each pair, numbered 0.. in order of first appearance (a pair without a
    ``place`` is a place of its own)."""
    given: list[int | None] = [f.place for f in feats]
    keys = [("place", p) if p is not None else ("pair", i) for i, p in enumerate(given)]
    numbers: dict[tuple[str, int], int] = {}
    return np.array([numbers.setdefault(k, len(numbers)) for k in keys], dtype=np.int64)


def cell_ids(cell: I64) -> I64:
    """(N,) int64 ids of the distinct rows of ``cell`` (N,2) int64, numbered in their lexicographic order (as
    ``np.unique(cell, axis=0, return_inverse=True)`` numbers them), through one int64 key per row: a row-wise
    unique sorts structured rows, ten times slower."""
    if cell.size == 0:
        return np.zeros(0, np.int64)
    low = cell.min(axis=0)
    span = cell.max(axis=0) - low + 1
    if float(span[0]) * float(span[1]) >= 2.0**62:
        _, inverse = np.unique(cell, axis=0, return_inverse=True)
        return np.asarray(inverse, dtype=np.int64).reshape(-1)
    key = (cell[:, 0] - low[0]) * span[1] + (cell[:, 1] - low[1])
    _, inverse = np.unique(key, return_inverse=True)
    return np.asarray(inverse, dtype=np.int64).reshape(-1)


def clusters_at(model: LevelModel, tau_hat: F64, cell_deg: float, by_ring: bool = False) -> Clusters:
    """Cluster each pair's edge points by the ``cell_deg`` angular cell of their projection at ``tau_hat`` (and,
    with ``by_ring``, by the ring they were found on; every pair's points must carry one)."""
    labels: list[I64] = []
    pairs: list[I64] = []
    cells: list[I64] = []
    rings: list[I64] = []
    first = first_cell = 0
    place = places(model.feats)
    for i, feat in enumerate(model.feats):
        uv, valid = feat.camera.project(transform_points(tau_hat, feat.points.points_lidar)[0])
        # Points the camera cannot see share one cluster: a pinhole's uv there is not finite or is far beyond
        # the int64 range (distortion polynomial), and they carry no cost terms.
        uv = np.where((valid & np.isfinite(uv).all(axis=1))[:, None], uv, -1.0)
        cell = cell_ids(np.floor(uv / (np.radians(cell_deg) * feat.camera.pixels_per_radian)).astype(np.int64))
        ring = feat.points.ring if by_ring else None
        if ring is None:
            inverse, cell_of, ring_of = cell, np.arange(int(cell.max()) + 1 if cell.size else 0), None
        else:
            inverse = cell_ids(np.stack([cell, ring], axis=1))
            first_of = np.zeros(int(inverse.max()) + 1 if inverse.size else 0, np.int64)
            first_of[inverse] = np.arange(len(inverse))  # any member: all share the cell and the ring
            cell_of, ring_of = cell[first_of], ring[first_of]
        n = len(cell_of)
        labels.append(inverse + first)
        pairs.append(np.full(n, place[i], dtype=np.int64))
        cells.append(cell_of + first_cell)
        rings.append(np.full(n, -1, np.int64) if ring_of is None else ring_of.astype(np.int64))
        first += n
        first_cell += int(cell.max()) + 1 if cell.size else 0
    empty = np.zeros(0, np.int64)
    return Clusters(tuple(labels), *(np.concatenate(a) if a else empty for a in (pairs, cells, rings)))


def local_gradient(model: LevelModel, frozen: list[Frozen], tau_hat: F64, xi: F64, clusters: Clusters) -> F64:
    """d cost / d xi at ``xi`` summed per cluster, (C,6): rotation part ``(R p x d_pcam) R``, translation
    ``d_pcam`` (the column sums are the gradient)."""
    tau = tau_at(tau_hat, xi)
    r_at = so3_exp(tau[:3])
    out = np.zeros((clusters.count, 6))
    all_terms = pair_terms(list(model.feats), frozen, tau, list(model.sigma_in_px), model.gmm)
    for terms, labels in zip(all_terms, clusters.labels, strict=True):
        if terms.index.size == 0:
            continue
        # d p_cam / d delta = -R_at (p^) for R = R_at exp(delta^): a^T(-R_at p^) = (p x R_at^T a)^T.
        g = np.concatenate([cross_rows(terms.rotated, terms.d_pcam) @ r_at, terms.d_pcam], axis=1)
        lab = labels[terms.index]
        for k in range(6):
            out[:, k] += np.bincount(lab, weights=g[:, k], minlength=clusters.count)
    return out


def matched_points(model: LevelModel, frozen: list[Frozen], tau: F64) -> int:
    """Edge points of the level whose Gaussian holds at least one edge pixel at ``tau``."""
    return sum(int(np.count_nonzero(t.value))
               for t in pair_terms(list(model.feats), frozen, tau, list(model.sigma_in_px), model.gmm))


def hessian(model: LevelModel, frozen: list[Frozen], tau_hat: F64, steps: F64, clusters: Clusters) -> F64:
    """(C,6,6) per-cluster Hessians of the frozen level cost in local coordinates, by central differences of
    the analytic gradient (12 evaluations); their sum is the Hessian."""
    h = np.zeros((clusters.count, 6, 6))
    for k in range(6):
        e = np.zeros(6)
        e[k] = steps[k]
        plus = local_gradient(model, frozen, tau_hat, e, clusters)
        minus = local_gradient(model, frozen, tau_hat, -e, clusters)
        h[:, :, k] = (plus - minus) / (2.0 * steps[k])
    return h


def symmetric(h: F64) -> F64:
    return np.asarray(0.5 * (h + h.T), dtype=np.float64)


def scatter(clusters: F64) -> F64:
    """B (6,6): scatter of the per-cluster gradients about their mean, with the small-sample factor
    C / (C - 6) (the mean gradient is not zero away from the optimum, and 6 parameters were fitted)."""
    c = len(clusters)
    if c <= 6:
        return np.full((6, 6), np.nan)
    centred = clusters - clusters.mean(axis=0)
    return np.asarray(centred.T @ centred * (c / (c - 6.0)), dtype=np.float64)


def positive_part(h: F64, rel_floor: float = 1e-9) -> tuple[F64, bool]:
    """H with eigenvalues below ``rel_floor * max`` raised to it, and whether H was positive definite."""
    w, v = np.linalg.eigh(h)
    floor = rel_floor * max(float(w.max()), 1e-300)
    return np.asarray((v * np.maximum(w, floor)) @ v.T, dtype=np.float64), bool(w.min() > floor)


def nll_scale(h: F64, b: F64) -> float:
    """kappa: the cost's scale in negative-log-likelihood units (module docstring). For a true NLL, B = H
    axis by axis; the median over axes of B_kk / H_kk is used, which stays finite where H is not (yet)
    positive definite, as away from the optimum, where tr(B H^-1) explodes along a flat direction."""
    diag_h, diag_b = np.diag(h), np.diag(b)
    ratios = diag_b[diag_h > 0] / diag_h[diag_h > 0]
    kappa = float(np.median(ratios)) if ratios.size else float("nan")
    return kappa if np.isfinite(kappa) and kappa > 0 else 1.0


def sandwich(h: F64, b: F64, information_prior: F64, reach: F64 | None = None) -> F64:
    """Covariance (n,n) of the estimated local coordinates: the sandwich H^-1 B H^-1 of the data (``h`` the GMM cost's
    Hessian alone), combined with the prior's information (NLL units) as a posterior: (H B^-1 H + I_prior)^-1.

    ``reach`` (n,) rad/m: how far the quadratic model of the cost holds along each coordinate (the finest
    kernel's width; n the estimated coordinates). A direction the data leave flat is known no worse than a
    uniform spread over +-reach: the data's information, in coordinates scaled by ``reach``, is floored at 3
    (that spread's). Without it a flat direction's variance was set by the eigenvalue floor's 1e-9 (metres of
    lever arm, tens of degrees), a number from the arithmetic rather than the data."""
    h_data, _ = positive_part(h)
    b_pd, _ = positive_part(b)
    info = h_data @ np.linalg.solve(b_pd, h_data)
    if reach is not None:
        scaled = info * np.outer(reach, reach)
        w, v = np.linalg.eigh(0.5 * (scaled + scaled.T))
        info = ((v * np.maximum(w, 3.0)) @ v.T) / np.outer(reach, reach)
    info_pd, _ = positive_part(0.5 * (info + info.T) + information_prior)
    cov: F64 = np.asarray(np.linalg.inv(info_pd), dtype=np.float64)
    return 0.5 * (cov + cov.T)


def sigmas_display(cov: F64) -> F64:
    """Per-axis sigma (6,) in deg, deg, deg, cm, cm, cm of a local-coordinate covariance."""
    return np.asarray(np.sqrt(np.maximum(np.diag(cov), 0.0)) * TO_DISPLAY, dtype=np.float64)


def weakest_direction(cov: F64, tolerance_display: F64) -> str:
    """The least-known direction in words, measured against the tolerance: one axis, or two that trade off
    ("z and pitch trade off: 1 cm of z ~ 0.1 deg of pitch")."""
    cov_u = cov * np.outer(TO_DISPLAY, TO_DISPLAY)
    scaled = cov_u / np.outer(tolerance_display, tolerance_display)
    w, v = np.linalg.eigh(scaled)
    vec = v[:, -1]
    order = np.argsort(-np.abs(vec))
    a, b = int(order[0]), int(order[1])
    sigma = np.sqrt(np.maximum(np.diag(cov_u), 0.0))
    if abs(vec[b]) < 0.35 * abs(vec[a]) or sigma[a] == 0:
        return f"{AXES[a]} is the least known axis (sigma {sigma[a]:.3g} {UNITS[a]})"
    slope = cov_u[a, b] / cov_u[a, a]  # change of b per unit of a along the ridge
    unit_a = 1.0 if UNITS[a] == "cm" else 0.1
    return (f"{AXES[a]} and {AXES[b]} trade off: {unit_a:g} {UNITS[a]} of {AXES[a]} ~ "
            f"{abs(slope) * unit_a:.2g} {UNITS[b]} of {AXES[b]} "
            f"({'same' if slope > 0 else 'opposite'} sign; sigma {sigma[a]:.3g} {UNITS[a]}, "
            f"{sigma[b]:.3g} {UNITS[b]})")
