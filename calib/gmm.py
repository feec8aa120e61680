"""The GMM edge-alignment cost (paper section 5, eqs. 8-23) and its analytic gradient (section 6).

Cost (eq. 8):  GMM(tau) = - sum_i sum_{j in Omega_i} w_ij G(d_ij, sigma_i)
  w_ij = (E_I(q_j)/max E_I + E_P(p_i)/max E_P) / (2 |Omega_i|)          (eq. 10)
  G    = k(sigma_i) exp(-d_ij^2 / (2 sigma_i^2)),  k = 1/(sqrt(2 pi) sigma_i) in the paper (eq. 9)
  d_ij = shortest route from the projection of p_i to q_j             (section 5.2)
  sigma_i = sigma_in * S_x / (r_i S(v_i))                             (eq. 23)

How the piecewise parts are handled (docs/method.md): sigma_i and |Omega_i| depend on tau, and the 3-sigma
truncation makes the cost jump when a pixel enters or leaves Omega_i. Each optimiser iteration *freezes*
sigma_i and |Omega_i| at the current iterate (a :class:`Frozen` state) and minimises that smooth model
along the gradient; the next iteration refreezes. The analytic gradient is the exact gradient of the
frozen model, and the finite-difference tests compare against the frozen model too. By default the
kernel height is a constant per level (``KernelNorm.LEVEL``) instead of the paper's 1/sigma_i: with
1/sigma_i a point moved farther away gets a smaller sigma and a higher peak, so the optimiser can lower
the cost by pushing points away; ``KernelNorm.PAPER`` keeps eq. 9 for the ablation.

Two evaluators give the same model: ``Evaluator.EXACT`` enumerates every (point, pixel) pair within 3 sigma
(the paper's Algorithm 2, over the pixels bucketed in a grid, in compiled code: :mod:`calib.pixel_grid`), and
``Evaluator.FIELD`` precomputes, per image, the sums over pixels as Gaussian-filtered maps at a ladder of sigmas
and samples them at the projected points (see :mod:`calib.fields`), which is what makes coarse levels with wide
sigmas cheap. The fields serve only the centres wide enough for pooled rungs (sigma >= 4 px): a narrower
centre reaches few pixels, whose exact sums cost less than building and holding a full-resolution rung
(docs/performance.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from calib.camera import CameraModel, Equirectangular
from calib.edges_image import EdgePixels
from calib.edges_points import FOLD, EdgePoints
from calib.fields import EdgeFields, sample_fields
from calib.geometry import cross_rows, left_jacobian, so3_exp
from calib.pixel_grid import PixelGrid

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
Mask = NDArray[np.bool_]

_SQRT_2PI = float(np.sqrt(2.0 * np.pi))


class SigmaModel(Enum):
    PAPER = "paper"  # eq. 23: distance and pixel-area terms
    UNIFORM = "uniform"  # sigma_i = sigma_in (ablation)


class KernelNorm(Enum):
    PAPER = "paper"  # 1 / (sqrt(2 pi) sigma_i), eq. 9
    LEVEL = "level"  # 1 / (sqrt(2 pi) sigma_in): same peak for every point of a level


class Evaluator(Enum):
    EXACT = "exact"
    FIELD = "field"
    AUTO = "auto"  # FIELD on coarse levels (wide sigma: many pairs per point), EXACT on fine ones


@dataclass(frozen=True)
class GmmOptions:
    """``weighted`` False is the paper's non-weighted ablation (w = 1). ``sigma_floor_px``: no Gaussian
    narrower than this (edge pixels sit on an integer grid; a narrower kernel falls between them).
    ``sigma_floor_deg``: the LiDAR's own angular uncertainty of an edge (a VLP-16 fires every 0.2 deg and its
    beam diverges by ~0.17 deg), added in quadrature to eq. 23 so far edges are not asked to align better than
    the sensor can place them. ``sigma_ceiling_px`` bounds the widest Gaussian (points very close by)."""

    weighted: bool = True
    sigma_model: SigmaModel = SigmaModel.PAPER
    kernel_norm: KernelNorm = KernelNorm.LEVEL
    evaluator: Evaluator = Evaluator.AUTO
    exact_below_deg: float = 2.5  # with AUTO: levels with sigma_in below this use EXACT
    sigma_range_cap_m: float = 5.0  # eq. 23's 1/r uses min(r, cap) on all levels but the finest
    use_folds: bool = True  # False: fold edge points are left out of the cost
    sigma_floor_px: float = 0.7
    sigma_floor_deg: float = 0.2
    sigma_ceiling_px: float = 48.0


@dataclass(frozen=True)
class PairFeatures:
    """What the cost needs of one image/cloud pair: the camera model, its edge pixels and edge points,
    and (for ``Evaluator.FIELD``) the precomputed fields of the edge pixels. ``place``: the place the pair was
    taken at, when several pairs share one (the sensors of a multi-camera head share one cloud); None: the
    pair is a place of its own. The assessment's jackknife leaves out whole places."""

    camera: CameraModel
    pixels: EdgePixels
    points: EdgePoints
    fields: EdgeFields | None = None
    pixel_grid: PixelGrid | None = None
    place: int | None = None

    def grid(self) -> PixelGrid:
        """The edge pixels bucketed for the exact evaluator (built here if the features came without it)."""
        if self.pixel_grid is not None:
            return self.pixel_grid
        return PixelGrid.build(self.pixels.uv, self.pixels.score, self.camera.width, self.camera.height,
                               isinstance(self.camera, Equirectangular))


@dataclass(frozen=True)
class Frozen:
    """sigma_i (N,) px of every edge point of one pair, evaluated at an iterate and held for one iteration."""

    sigma_px: F64


@dataclass(frozen=True)
class CostGrad:
    cost: float
    gradient: F64  # (6,) d cost / d tau, tau = [omega (rad), t (m)]
    n_active: int


def transform_points(tau: F64, points_lidar: F64) -> tuple[F64, F64]:
    """p_cam = R(omega) p + t (eqs. 3-4); returns p_cam (N,3) and R p (N,3) for the gradient."""
    rotated = points_lidar @ so3_exp(tau[:3]).T
    return rotated + tau[3:], rotated


def in_image(camera: CameraModel, uv: F64, valid: Mask) -> Mask:
    """Projections inside the image (pixel centres at integers, so the border is at -0.5 and size-0.5)."""
    return (
        valid
        & (uv[:, 0] >= -0.5)
        & (uv[:, 0] < camera.width - 0.5 + (0.5 if isinstance(camera, Equirectangular) else 0.0))
        & (uv[:, 1] >= -0.5)
        & (uv[:, 1] < camera.height - 0.5)
    )


def point_sigmas(
    camera: CameraModel, points_lidar: F64, uv: F64, sigma_in_px: float | F64, opts: GmmOptions
) -> F64:
    """sigma_i (N,) px of eq. 23 (or uniform), with the LiDAR floor added in quadrature.

    Eq. 23 divides by the camera range r(p_c). We divide by the LiDAR range |p|, which equals it up to the
    camera-LiDAR baseline (decimetres against edges metres away), because a sigma that depends on the
    translation estimate can be gamed: translating the scene toward the camera widens every Gaussian,
    lets points that see no edge pixel catch some, and lowers the cost at a wrong pose (measured on the
    pinhole sample: cost -0.89 at a pose 2.5 m off against -0.34 at the reference).
    """
    if opts.sigma_model is SigmaModel.UNIFORM:
        sigma = np.broadcast_to(sigma_in_px, len(points_lidar)).astype(np.float64)
    else:
        r = np.linalg.norm(points_lidar, axis=1)
        sigma = sigma_in_px * camera.pixel_area_ratio(uv) / np.clip(r, 1e-6, opts.sigma_range_cap_m)
    floor = max(opts.sigma_floor_px, np.radians(opts.sigma_floor_deg) * camera.pixels_per_radian)
    return np.asarray(np.minimum(np.sqrt(sigma**2 + floor**2), opts.sigma_ceiling_px), dtype=np.float64)


def _kernel_height(sigma: F64, sigma_in_px: F64, opts: GmmOptions) -> F64:
    """Per point (N,); ``sigma_in_px`` (N,) the level's sigma_in of each point's pair."""
    if opts.kernel_norm is KernelNorm.PAPER:
        return 1.0 / (_SQRT_2PI * sigma)
    return np.asarray(1.0 / (_SQRT_2PI * sigma_in_px), dtype=np.float64)


def _camera_groups(feats: list[PairFeatures]) -> list[list[int]]:
    """Indices of the pairs, in runs that share one camera model object (a dataset's pairs all do), so
    projections and the per-point algebra run once per run instead of once per pair."""
    groups: list[list[int]] = []
    for i, f in enumerate(feats):
        if groups and feats[groups[-1][0]].camera is f.camera:
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups


def freeze_all(feats: list[PairFeatures], tau: F64, sigma_in_px: list[float], opts: GmmOptions) -> list[Frozen]:
    """sigma_i at ``tau`` (eq. 23) of every pair, held fixed by the optimiser for one iteration."""
    out: list[Frozen] = []
    for group in _camera_groups(feats):
        camera = feats[group[0]].camera
        points = np.concatenate([feats[i].points.points_lidar for i in group])
        sizes = [len(feats[i].points) for i in group]
        uv, _ = camera.project(transform_points(tau, points)[0])
        s_in = np.repeat(np.array([sigma_in_px[i] for i in group], dtype=np.float64), sizes)
        sigma = point_sigmas(camera, points, uv, s_in, opts)
        out += [Frozen(part) for part in np.split(sigma, np.cumsum(sizes)[:-1])]
    return out


def freeze(feat: PairFeatures, tau: F64, sigma_in_px: float, opts: GmmOptions) -> Frozen:
    """sigma_i at ``tau`` (eq. 23), held fixed by the optimiser for one iteration."""
    return freeze_all([feat], tau, [sigma_in_px], opts)[0]


def _sums_exact(feats: list[PairFeatures], parts: list[slice], uv: F64, sigma: F64) -> F64:
    """(N, 9) like :func:`calib.fields.sample_fields`, by enumerating the pixels near each centre: centres
    ``uv[parts[k]]`` (px) with widths ``sigma[parts[k]]`` on the pixels of ``feats[k]`` (:mod:`calib.pixel_grid`)."""
    out = np.zeros((len(uv), 9))
    for f, part in zip(feats, parts, strict=True):
        if part.stop > part.start:
            out[part] = f.grid().sums(uv[part], sigma[part])
    return out


def _sums_field(feats: list[PairFeatures], fields: list[EdgeFields], parts: list[slice], uv: F64, sigma: F64) -> F64:
    """(N, 9) sums for ``Evaluator.FIELD``: sampled from the fields where a centre is wide enough to read only
    pooled rungs, exact (:func:`_sums_exact`) where it is narrower."""
    wide = fields[0].reads_pooled(sigma)
    out = np.zeros((len(uv), 9))
    if wide.any():
        out[wide] = sample_fields(fields, [int(np.count_nonzero(wide[p])) for p in parts], uv[wide], sigma[wide])
    if not wide.all():
        narrow = ~wide
        counts = [int(np.count_nonzero(narrow[p])) for p in parts]
        out[narrow] = _sums_exact(feats, _slices(counts), uv[narrow], sigma[narrow])
    return out


def _point_terms(sums: F64, sigma: F64, sigma_in_px: F64, opts: GmmOptions, p_score: F64) -> tuple[F64, F64]:
    """Per point: V_i = sum_j w_ij G_ij (eqs. 8-10) and dV_i / d centre (N,2), from the (N, 9) sums over the
    pixels near each centre (:meth:`EdgeFields.sample` or :func:`_sums_exact`).

    Weighted: V = k (A + s_p B) / (2 |Omega|) with A = sum_j e_j G_ij, B = sum_j G_ij and the soft count
    |Omega|; its gradient includes the count's, so it is the exact gradient of a differentiable cost.
    """
    a, da, b, db = sums[:, 0], sums[:, 1:3], sums[:, 3], sums[:, 4:6]
    height = _kernel_height(sigma, sigma_in_px, opts)
    if not opts.weighted:  # the paper's non-weighted ablation: w = 1
        return height * b, height[:, None] * db
    # |Omega_i| of eq. 10, but never fewer than the 6 sigma pixels of one straight edge through the disk
    # (a smooth max, 4-norm): with the bare count, a lone speckle pixel gives a point the full weight and
    # attracts it more than a real edge does.
    soft = np.maximum(sums[:, 6], 0.0)
    line = 6.0 * sigma
    count = (soft**4 + line**4) ** 0.25
    dcount = ((soft / count) ** 3)[:, None] * sums[:, 7:9]
    num = a + p_score * b
    dnum = da + p_score[:, None] * db
    value = height * num / (2.0 * count)
    grad = height[:, None] * (dnum / (2.0 * count)[:, None] - (num / (2.0 * count**2))[:, None] * dcount)
    return value, grad


@dataclass(frozen=True)
class PointTerms:
    """Per-point pieces of the cost of one pair at one pose: ``index`` (K,) of the active edge points,
    ``value`` (K,) V_i >= 0 (the cost is -sum V_i), ``d_pcam`` (K,3) d cost_i / d p_cam (1/m), ``rotated``
    (K,3) R p_i in m, ``uv`` (K,2) px of the projections."""

    index: I64
    value: F64
    d_pcam: F64
    rotated: F64
    uv: F64


def pair_terms(
    feats: list[PairFeatures], frozen: list[Frozen], tau: F64, sigma_in_px: list[float], opts: GmmOptions
) -> list[PointTerms]:
    """Eqs. 8-10 and 28-29 point by point for every pair (the frozen model at ``tau``); the projections and
    the per-point algebra run once for all pairs that share a camera, the sums over pixels pair by pair."""
    out: list[PointTerms] = []
    for group in _camera_groups(feats):
        camera = feats[group[0]].camera
        sizes = [len(feats[i].points) for i in group]
        starts = np.concatenate([[0], np.cumsum(sizes)])
        p_cam, rotated = transform_points(tau, np.concatenate([feats[i].points.points_lidar for i in group]))
        uv, valid = camera.project(p_cam)
        kind = np.concatenate([feats[i].points.kind for i in group])
        # Points just outside the image still see edge pixels inside it; taking every valid projection
        # (not only those inside) keeps the cost continuous when a point crosses the image border.
        active = valid & (opts.use_folds | (kind != FOLD))
        sel = [np.flatnonzero(active[starts[k]:starts[k + 1]]) for k in range(len(group))]
        parts = _slices([len(x) for x in sel])
        glob = np.concatenate([starts[k] + sel[k] for k in range(len(group))])
        uv_g, sigma = uv[glob], np.concatenate([frozen[i].sigma_px for i in group])[glob]
        fields = [feats[i].fields for i in group]
        if opts.evaluator is Evaluator.FIELD and all(f is not None for f in fields):
            sums = _sums_field([feats[i] for i in group], [f for f in fields if f is not None], parts, uv_g, sigma)
        else:
            sums = _sums_exact([feats[i] for i in group], parts, uv_g, sigma)
        s_in = np.repeat(np.array([sigma_in_px[i] for i in group], dtype=np.float64), [len(x) for x in sel])
        p_score = np.concatenate([feats[i].points.score for i in group])[glob]
        value, d_centre = _point_terms(sums, sigma, s_in, opts, p_score)
        # eqs. 28-29: d cost / d p_cam = - dV/d(u,v) . d(u,v)/d p_cam
        d_pcam = -np.einsum("ni,nij->nj", d_centre, camera.project_jacobian(p_cam[glob]))
        rotated_g = rotated[glob]
        out += [PointTerms(idx, value[part], d_pcam[part], rotated_g[part], uv_g[part])
                for idx, part in zip(sel, parts, strict=True)]
    return out


def _slices(sizes: list[int]) -> list[slice]:
    ends = np.cumsum(sizes)
    return [slice(int(e - n), int(e)) for e, n in zip(ends, sizes, strict=True)]


def cost_and_gradient(
    feats: list[PairFeatures], frozen: list[Frozen], tau: F64, sigma_in_px: list[float], opts: GmmOptions
) -> CostGrad:
    """Cost (eq. 8) at ``tau`` with sigma_i held at ``frozen`` and its analytic gradient (eqs. 27-31)."""
    total = 0.0
    grad = np.zeros(6)
    n_active = 0
    jac_l = left_jacobian(tau[:3])
    for terms in pair_terms(feats, frozen, tau, sigma_in_px, opts):
        if terms.index.size == 0:
            continue
        total -= float(terms.value.sum())
        n_active += int(np.count_nonzero(terms.value))
        # eq. 30: d p_cam / d omega = -(R p)^ J (left Jacobian, eq. 31);  d p_cam / d t = I.
        # a^T (-(Rp)^) = (Rp x a)^T.
        grad[3:] += terms.d_pcam.sum(axis=0)
        grad[:3] += cross_rows(terms.rotated, terms.d_pcam).sum(axis=0) @ jac_l
    return CostGrad(total, grad, n_active)
