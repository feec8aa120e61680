"""Photometric baselines of the paper's comparison (section 8.2): MI, NID and GOM between LiDAR reflectivity
and the image, each optimised coarse to fine over image blur levels by Nelder-Mead.

Each LiDAR point p_k with reflectivity r_k projects (the same camera models and eq. 3 as the GMM) to
q_k = q(R p_k + t); the image is sampled there with bilinear interpolation.

- MI (Pandey, McBride, Savarese & Eustice 2015, eqs. 1-4 of their section 3): X = reflectivity, Y = grey
  level, ``MI(X, Y) = H(X) + H(Y) - H(X, Y)`` with ``H(X) = -sum_x p(x) log p(x)`` and the joint distribution a
  kernel density estimate: the joint histogram of all pairs' samples smoothed by a Gaussian whose bandwidth
  follows Silverman's rule ``h = 1.06 sigma n^(-1/5)`` (their eq. 5). Cost: ``-MI``.
- NID (as koide3/direct_visual_lidar_calibration, CostCalculatorNID): per pair, a 16x16 joint histogram,
  ``NID = (H(X, Y) - MI(X, Y)) / H(X, Y)``; the cost is the mean over pairs (koide3 sums them).
- GOM (Taylor, Nieto & Johnson 2015, the gradient orientation measure): with g_I the image gradient at q_k
  and g_L the reflectivity gradient of the projected cloud at q_k,
  ``GOM = sum_k |g_I||g_L| (1 + cos 2 dtheta_k) / 2 / sum_k |g_I||g_L|`` (the authors' GOMKernel;
  (1 + cos 2 dtheta) / 2 = cos^2 dtheta ignores the sign, since a bright-to-dark edge in one modality can be
  dark-to-bright in the other). Cost: ``-GOM``. g_L is a least-squares plane fit to the reflectivity of the
  ``gom_neighbours`` nearest projected points (Taylor et al. fit the 8 nearest), its neighbours and fit frozen
  per level (like the GMM's sigma_i).
  One deviation, measured: Taylor et al. take g_I from pixel differences (Sobel), which estimates the gradient
  at a 1-px scale where g_L is an average over the neighbourhood's few pixels, off-centre where the points
  are uneven; the two disagree by an amount that depends on the pose, and on an ideal pair (test_photometric)
  the cost's minimum lay 0.13-0.46 deg from the truth (with g_L replaced by the exact image gradient: 1e-4
  deg). Here g_I is estimated by the same plane fit, over the same neighbours, from the image sampled at their
  projections (the matched estimator): where reflectivity equals the image's grey level both fits agree
  exactly at the true pose (0.004-0.05 deg on the same pairs).

Smoothness: histograms and nearest-pixel look-ups make these costs piecewise constant. Here each sample is
bilinear in the image and split linearly between its two nearest bins in each variable (Parzen windowing
with a triangular kernel), so the costs are continuous in the pose; they are still not smooth enough for
the GMM's Wolfe line search, so, as koide3 and Taylor et al. do, each level is minimised by Nelder-Mead
(scipy), in local coordinates around the level's start, and the finest level is rerun from its own result
until it stops moving (koide3's outer loop). Pandey et al. use a Barzilai-Borwein gradient ascent with
numerical gradients; we do not, as it needs the same smoothness.

Reflectivity and grey level are rank-normalised (histogram equalisation; koide3 equalises both too), and
reflectivity per ring when rings are known: an uncalibrated multi-beam LiDAR's intensity differs by laser
and falls with range, and each ring on flat ground sits at one range, so ranks within a ring keep the
surface's reflectance and drop the beam's gain.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from enum import Enum

import cv2
import numpy as np
import scipy.ndimage
from numpy.typing import NDArray

from calib.camera import CameraModel, Equirectangular
from calib.edges_image import to_grey
from calib.edges_points import rings_from_elevation
from calib.errors import CalibError, FeaturelessError
from calib.gmm import in_image, transform_points
from calib.uncertainty import tau_at, xi_of

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
_REMAP_WIDTH = 16384


class PhotoCost(Enum):
    MI = "mi"
    NID = "nid"
    GOM = "gom"


@dataclass(frozen=True)
class PhotoParams:
    """``blur_deg``: the image's Gaussian blur per level as an angle (paper 8.2.1 used 12, 6, 3, 0 px of a
    1024-wide panorama for GOM = 4.22, 2.11, 1.05, 0 deg). ``step_rot_deg``/``step_trans_m``: the initial
    simplex's size per level. ``bins``: histogram bins (0: 64 for MI, koide3's 16 for NID).
    ``max_points``: points kept over all pairs (each pair an equal share, at least ``min_points_per_pair``; a
    random subset, fixed by ``seed``, of those in view at the start): the cost of an evaluation stays about the
    same for one dense pinhole frame and twelve panoramas."""

    cost: PhotoCost = PhotoCost.NID
    blur_deg: tuple[float, ...] = (4.22, 2.11, 1.05, 0.0)
    step_rot_deg: tuple[float, ...] = (3.0, 1.5, 0.75, 0.3)
    step_trans_m: tuple[float, ...] = (0.10, 0.05, 0.025, 0.01)
    bins: int = 0
    max_points: int = 24000
    min_points_per_pair: int = 1500
    max_evals: int = 600
    restarts: int = 2
    restart_tol_deg: float = 0.005
    restart_tol_m: float = 0.0005
    per_ring: bool = True
    gom_neighbours: int = 24  # enough to span neighbouring rings: along one ring the plane fit has no across term
    rotation_only_levels: int = 1  # the first level(s) move rotation only, as rigd's GMM does
    max_move_steps: float = 4.0  # a level moves at most this many simplex steps per axis from its start
    seed: int = 0

    def __post_init__(self) -> None:
        n = len(self.blur_deg)
        if n == 0 or len(self.step_rot_deg) != n or len(self.step_trans_m) != n:
            raise CalibError("photometric levels: blur_deg, step_rot_deg and step_trans_m need one entry per level")

    @property
    def n_bins(self) -> int:
        if self.bins > 0:
            return self.bins
        return 64 if self.cost is PhotoCost.MI else 16


@dataclass(frozen=True)
class PhotoPair:
    """One pair for the photometric costs: ``grey`` (H,W) float32 in [0, 1] (equalised), ``points_lidar``
    (N,3) float64 m, ``reflectivity`` (N,) float64 in [0, 1] (rank-normalised), ``mask`` (H,W) bool, True where
    the image shows the scene (None: everywhere; points landing elsewhere are not compared), ``ring`` (N,) int64
    the ring of each point (the cloud's laser index, else its half-degree elevation bin; None: not known);
    ``place``: the assessment's jackknife leaves out whole places."""

    camera: CameraModel
    grey: F32
    points_lidar: F64
    reflectivity: F64
    mask: NDArray[np.bool_] | None = None
    ring: NDArray[np.int64] | None = None
    place: int | None = None  # the place the pair was taken at (None: a place of its own), as PairFeatures.place


@dataclass(frozen=True)
class PhotoLevel:
    """One level's outcome: blur (deg), cost evaluations, cost at its start and end, and the pose."""

    blur_deg: float
    evaluations: int
    costs: tuple[float, ...]
    tau: F64


@dataclass(frozen=True)
class PhotoResult:
    """``subset_tau``: the pose whose view chose the points the solve minimised (:func:`point_subsets`)."""

    tau: F64
    levels: tuple[PhotoLevel, ...]
    final_cost: float
    subset_tau: F64


def average_ranks(values: F64) -> F64:
    """1-based ranks of ``values`` (N,), ties sharing their mean rank (``scipy.stats.rankdata``'s default,
    without importing scipy.stats: a quarter of a second of every rigd process's start)."""
    order = np.argsort(values, kind="stable")
    ordered = values[order]
    first = np.r_[True, ordered[1:] != ordered[:-1]]
    starts = np.flatnonzero(first)
    ends = np.r_[starts[1:], len(values)]
    ranks = np.empty(len(values))
    ranks[order] = ((starts + ends + 1) / 2.0)[np.cumsum(first) - 1]
    return ranks


def rank_normalise(values: F64, groups: NDArray[np.int16] | None = None) -> F64:
    """Ranks of ``values`` (N,) mapped to [0, 1], within each group (e.g. LiDAR ring) when given; ties share
    their mean rank."""
    out = np.zeros(len(values))
    keys = np.zeros(len(values), dtype=np.int64) if groups is None else groups.astype(np.int64)
    for g in np.unique(keys):
        sel = np.flatnonzero(keys == g)
        if sel.size < 2:
            out[sel] = 0.5
            continue
        ranks = average_ranks(values[sel])
        out[sel] = (ranks - 1.0) / (sel.size - 1.0)
    return out


def photo_pair(image: NDArray[np.uint8], points_lidar: F64, intensity: NDArray[np.float32] | None,
               ring: NDArray[np.int16] | None, camera: CameraModel, params: PhotoParams, *, index: int = 0,
               mask: NDArray[np.bool_] | None = None) -> PhotoPair:
    """The arrays the photometric costs need of one pair (``mask``: see :class:`PhotoPair`); raises
    FeaturelessError when the cloud has no intensity (reflectivity) field, or one of a single value."""
    if intensity is None:
        raise FeaturelessError(f"pair {index}: the cloud has no intensity field; MI, NID and GOM compare LiDAR "
                               "reflectivity with the image")
    if len(intensity) != len(points_lidar):
        raise CalibError(f"pair {index}: {len(intensity)} intensities for {len(points_lidar)} points")
    if len(intensity) and float(np.ptp(intensity)) == 0.0:
        raise FeaturelessError(f"pair {index}: every point of the cloud has intensity {float(intensity[0]):g}; MI, "
                               "NID and GOM compare LiDAR reflectivity with the image and have nothing to compare")
    grey_u8 = np.rint(to_grey(image) * 255.0).astype(np.uint8)
    grey = (cv2.equalizeHist(grey_u8).astype(np.float32) / np.float32(255.0))
    groups = ring if params.per_ring else None
    refl = rank_normalise(np.asarray(intensity, dtype=np.float64), groups)
    points = np.asarray(points_lidar, dtype=np.float64)
    rings = rings_from_elevation(points) if ring is None else np.asarray(ring, dtype=np.int64)
    return PhotoPair(camera, grey, points, refl, mask, rings)


def labelled_histograms(a: F64, b: F64, labels: NDArray[np.int64], n: int, bins: int) -> F64:
    """(n, bins, bins): the soft joint histogram of each label's samples (``labels`` (N,) in [0, n)) of ``a``,
    ``b`` (N,) in [0, 1], in one count: each sample split linearly between its two nearest bin centres in each
    variable (triangular Parzen window), so the counts move continuously; each histogram's samples are added in
    their order, so the sums are those of each alone."""
    pa = np.clip(a, 0.0, 1.0) * (bins - 1)
    pb = np.clip(b, 0.0, 1.0) * (bins - 1)
    ia = np.minimum(np.floor(pa).astype(np.int64), bins - 2)
    ib = np.minimum(np.floor(pb).astype(np.int64), bins - 2)
    fa, fb = pa - ia, pb - ib
    base = labels * (bins * bins)
    idx = np.concatenate([base + ia * bins + ib, base + (ia + 1) * bins + ib, base + ia * bins + ib + 1,
                          base + (ia + 1) * bins + ib + 1])
    w = np.concatenate([(1 - fa) * (1 - fb), fa * (1 - fb), (1 - fa) * fb, fa * fb])
    return np.asarray(np.bincount(idx, weights=w, minlength=n * bins * bins), dtype=np.float64).reshape(n, bins, bins)


def _entropy(p: F64) -> float:
    nz = p[p > 0]
    return float(-np.sum(nz * np.log(nz)))


def entropies(joint: F64) -> tuple[float, float, float]:
    """H(X), H(Y), H(X, Y) (nats) of a joint histogram (rows X, columns Y), normalised to a distribution."""
    total = float(joint.sum())
    if total <= 0:
        raise CalibError("empty joint histogram: no point projects into an image")
    p = joint / total
    return _entropy(p.sum(axis=1)), _entropy(p.sum(axis=0)), _entropy(p)


def kde_smooth(joint: F64, n_samples: float) -> F64:
    """Pandey et al.'s kernel density estimate of a joint histogram: Gaussian smoothing with Silverman's
    bandwidth h = 1.06 sigma n^(-1/5) per variable (sigma of the variable's marginal, in bins)."""
    bins = joint.shape[0]
    centres = np.arange(bins, dtype=np.float64)
    p = joint / max(float(joint.sum()), 1e-300)
    h = []
    for marginal in (p.sum(axis=1), p.sum(axis=0)):
        mean = float(marginal @ centres)
        sd = float(np.sqrt(max(marginal @ (centres - mean) ** 2, 1e-12)))
        h.append(max(1.06 * sd * max(n_samples, 1.0) ** -0.2, 0.5))
    return np.asarray(scipy.ndimage.gaussian_filter(joint, sigma=h, mode="reflect"), dtype=np.float64)


def mutual_information(joint: F64) -> float:
    """MI = H(X) + H(Y) - H(X, Y) (Pandey 2015 eq. 4)."""
    hx, hy, hxy = entropies(joint)
    return hx + hy - hxy


def nid(joint: F64) -> float:
    """NID = (H(X, Y) - MI) / H(X, Y) in [0, 1] (koide3's CostCalculatorNID); 0 when one variable determines
    the other, 1 when they are independent."""
    hx, hy, hxy = entropies(joint)
    if hxy <= 0:
        return 0.0
    return (hxy - (hx + hy - hxy)) / hxy


@dataclass(frozen=True)
class LevelPair:
    """One pair at one level: blurred grey (H,W) float32, the kept points (M,3) m and their reflectivity (M,),
    and for GOM the frozen plane fit (:class:`GradientFit`) and the reflectivity gradients (M,2) per px."""

    camera: CameraModel
    grey: F32
    points_lidar: F64
    reflectivity: F64
    fit: GradientFit | None = None
    lidar_grad: F64 | None = None
    mask: NDArray[np.bool_] | None = None


@dataclass(frozen=True)
class GradientFit:
    """Least-squares plane fits at M projected points: ``neighbours`` (M,k) indices of each point's k nearest
    projected points, ``solve`` (M,2,k) px^-1 the fit's linear map from the k value differences to the
    gradient (d/du, d/dv): ``g = solve @ (f[neighbours] - f)``."""

    neighbours: NDArray[np.intp]
    solve: F64

    def gradients(self, values: F64) -> F64:
        """(M,2) gradient per px of ``values`` (M,) given at the points."""
        return np.asarray(np.einsum("mik,mk->mi", self.solve, values[self.neighbours] - values[:, None]),
                          dtype=np.float64)


def _filtered(image: F32, camera: CameraModel, pad: int, fn: Callable[[F32], F32]) -> F32:
    """``fn`` (a filter with reflected borders) over ``image``; a panorama is first padded by ``pad`` columns
    from its other side, so its filters wrap around u = 0 / w (OpenCV's filters have no wrapping border)."""
    if not isinstance(camera, Equirectangular):
        return fn(image)
    padded = np.pad(image, ((0, 0), (pad, pad)), mode="wrap")
    return np.ascontiguousarray(fn(padded)[:, pad:pad + image.shape[1]])


def _blur(grey: F32, camera: CameraModel, blur_deg: float) -> F32:
    sigma_px = float(np.radians(blur_deg)) * camera.pixels_per_radian
    if sigma_px < 0.3:
        return grey
    return _filtered(grey, camera, int(np.ceil(4 * sigma_px)) + 1, lambda im: np.asarray(
        cv2.GaussianBlur(im, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT), dtype=np.float32))


def sample(image: F32, camera: CameraModel, uv: F64) -> F64:
    """Bilinear samples (N,) of ``image`` at ``uv`` (N,2) px (pixel centres at integers; panoramas wrap)."""
    if len(uv) == 0:
        return np.zeros(0)
    border = cv2.BORDER_WRAP if isinstance(camera, Equirectangular) else cv2.BORDER_REPLICATE
    # cv2.remap's maps are images of fewer than 32767 columns: many samples go as rows of _REMAP_WIDTH.
    n = len(uv)
    rows = -(-n // _REMAP_WIDTH)
    maps = np.zeros((2, rows * _REMAP_WIDTH), np.float32)
    maps[:, :n] = uv.T
    mx = maps[0].reshape(rows, _REMAP_WIDTH) if rows > 1 else maps[0, :n].reshape(1, n)
    my = maps[1].reshape(rows, _REMAP_WIDTH) if rows > 1 else maps[1, :n].reshape(1, n)
    out = cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=border)
    return np.asarray(out, dtype=np.float64).reshape(-1)[:n]


def project_level(lp: LevelPair, tau: F64) -> tuple[F64, NDArray[np.bool_]]:
    uv, valid = lp.camera.project(transform_points(tau, lp.points_lidar)[0])
    inside = in_image(lp.camera, uv, valid)
    if lp.mask is not None:
        px = np.rint(uv[inside]).astype(np.int64)
        inside[inside] = lp.mask[np.clip(px[:, 1], 0, lp.mask.shape[0] - 1), np.clip(px[:, 0], 0, lp.mask.shape[1] - 1)]
    return uv, inside


def project_pairs(pairs: list[LevelPair], tau: F64) -> list[tuple[F64, NDArray[np.bool_]]]:
    """:func:`project_level` of each pair; pairs that share one camera and mask (the views of one camera) are
    projected as one array, the same numbers with a tenth of the calls."""
    first = pairs[0] if pairs else None
    if first is None or len(pairs) == 1 or any(lp.camera is not first.camera or lp.mask is not first.mask
                                               for lp in pairs):
        return [project_level(lp, tau) for lp in pairs]
    merged = replace(first, points_lidar=np.concatenate([lp.points_lidar for lp in pairs]))
    uv, inside = project_level(merged, tau)
    cuts = np.cumsum([len(lp.points_lidar) for lp in pairs])[:-1]
    return list(zip(np.split(uv, cuts), np.split(inside, cuts), strict=True))


def joint_histograms(a: list[F64], b: list[F64], bins: int) -> F64:
    """(P, bins, bins): the soft joint histogram (:func:`labelled_histograms`) of each of P pairs of samples
    ``a[i]``, ``b[i]`` (N_i,)."""
    labels = np.repeat(np.arange(len(a), dtype=np.int64), [len(x) for x in a])
    return labelled_histograms(np.concatenate(a) if a else np.zeros(0), np.concatenate(b) if b else np.zeros(0),
                               labels, len(a), bins)


def gradient_fit(uv: F64, neighbours: int) -> GradientFit | None:
    """The plane fit at each of the projected points ``uv`` (M,2) px through its ``neighbours`` nearest
    projected neighbours, ridge-regularised by 1 px^2 so points whose neighbours lie on one scan line get no
    gradient across it; None with too few points."""
    from scipy.spatial import cKDTree  # here: only NID's gradients need it (calib.edges_points, the same)

    if len(uv) <= neighbours:
        return None
    _, nb = cKDTree(uv).query(uv, k=neighbours + 1)
    nb = np.asarray(nb[:, 1:], dtype=np.intp)
    d_uv = uv[nb] - uv[:, None, :]  # (M,k,2)
    ata = np.einsum("mki,mkj->mij", d_uv, d_uv) + np.eye(2)
    return GradientFit(nb, np.asarray(np.linalg.solve(ata, np.transpose(d_uv, (0, 2, 1))), dtype=np.float64))


def gom_terms(g_image: F64, g_lidar: F64) -> tuple[F64, F64]:
    """Per sample: |g_I||g_L| (1 + cos 2 dtheta) / 2 and |g_I||g_L| (Taylor 2015's GOM numerator and
    denominator terms); (1 + cos 2 dtheta) / 2 = (g_I . g_L)^2 / (|g_I|^2 |g_L|^2)."""
    mag = np.linalg.norm(g_image, axis=1) * np.linalg.norm(g_lidar, axis=1)
    dot = np.sum(g_image * g_lidar, axis=1)
    agree = np.where(mag > 1e-12, dot**2 / np.maximum(mag, 1e-12), 0.0)
    return agree, mag


def level_cost(pairs: list[LevelPair], tau: F64, params: PhotoParams) -> float:
    """The level's cost at ``tau`` (lower is better): -MI, mean NID or -GOM over ``pairs``."""
    bins = params.n_bins
    if params.cost is PhotoCost.GOM:
        num = den = 0.0
        for lp in pairs:
            if lp.fit is None or lp.lidar_grad is None:
                continue
            uv, inside = project_level(lp, tau)
            g_img = lp.fit.gradients(sample(lp.grey, lp.camera, uv))  # the matched estimator (module docstring)
            agree, mag = gom_terms(g_img[inside], lp.lidar_grad[inside])
            num, den = num + float(agree.sum()), den + float(mag.sum())
        return -num / den if den > 0 else 0.0
    refl, grey = [], []
    for lp, (uv, inside) in zip(pairs, project_pairs(pairs, tau), strict=True):
        refl.append(lp.reflectivity[inside])
        grey.append(sample(lp.grey, lp.camera, uv[inside]))
    joints = list(joint_histograms(refl, grey, bins))
    if params.cost is PhotoCost.NID:
        return float(np.mean([nid(j) if j.sum() > 0 else 1.0 for j in joints]))
    joint = np.sum(joints, axis=0)
    if joint.sum() <= 0:
        return 0.0
    return -mutual_information(kde_smooth(joint, float(joint.sum())))


def _in_view(pair: PhotoPair, tau0: F64, params: PhotoParams, cap: int) -> NDArray[np.int64]:
    """Indices of the points that project into the image (with a 10 % margin) at ``tau0``, at most ``cap``."""
    cam = pair.camera
    uv, valid = cam.project(transform_points(tau0, pair.points_lidar)[0])
    mw, mh = 0.1 * cam.width, 0.1 * cam.height
    keep = valid & (uv[:, 0] > -mw) & (uv[:, 0] < cam.width + mw) & (uv[:, 1] > -mh) & (uv[:, 1] < cam.height + mh)
    idx = np.flatnonzero(keep)
    if idx.size > cap:
        idx = np.sort(np.random.default_rng(params.seed).choice(idx, cap, replace=False))
    return idx


def level_pairs(pairs: list[PhotoPair], tau: F64, params: PhotoParams, level: int,
                subsets: list[tuple[F64, F64]]) -> list[LevelPair]:
    """Each pair at ``level``: the blurred image (and its gradient and the frozen LiDAR gradients for GOM)."""
    out = []
    for pair, (pts, refl) in zip(pairs, subsets, strict=True):
        grey = _blur(pair.grey, pair.camera, params.blur_deg[level])
        lp = LevelPair(pair.camera, grey, pts, refl, mask=pair.mask)
        if params.cost is PhotoCost.GOM:
            uv, valid = pair.camera.project(transform_points(tau, pts)[0])
            keep = np.flatnonzero(valid)  # points behind a pinhole have no image position to fit on
            fit = gradient_fit(uv[keep], params.gom_neighbours)
            if fit is not None:
                lp = replace(lp, points_lidar=pts[keep], reflectivity=refl[keep], fit=fit,
                             lidar_grad=fit.gradients(refl[keep]))
        out.append(lp)
    return out


def _nelder_mead(f: Callable[[F64], float], tau0: F64, step: F64, max_evals: int,
                 max_move: float) -> tuple[F64, int, float]:
    """Nelder-Mead (scipy) over local coordinates xi = x * step around ``tau0``; the initial simplex spans one
    ``step`` per axis and x is bounded to +-``max_move`` (where a cost is flat, as on a hazy frame, the simplex
    would otherwise wander off: measured 12 deg from a 2 deg start). Returns the pose, the evaluations and the
    final cost."""
    import scipy.optimize  # here: with scipy.linalg, 35 MB of every calibration's memory that only NID uses

    simplex = np.vstack([np.zeros(6), np.eye(6)])
    res = scipy.optimize.minimize(lambda x: f(tau_at(tau0, x * step)), np.zeros(6), method="Nelder-Mead",
                                  bounds=[(-max_move, max_move)] * 6,
                                  options={"initial_simplex": simplex, "xatol": 0.01, "fatol": 1e-9,
                                           "maxfev": max_evals})
    return tau_at(tau0, res.x * step), int(res.nfev), float(res.fun)


def point_subsets(pairs: list[PhotoPair], tau: F64, params: PhotoParams) -> list[tuple[F64, F64]]:
    """The points each evaluation uses: per pair those in view at ``tau`` (10 % margin), an equal share of
    ``params.max_points`` (at least ``params.min_points_per_pair``), and their reflectivity."""
    return [(p.points_lidar[idx], p.reflectivity[idx]) for p, idx in zip(pairs, _subset_indices(pairs, tau, params),
                                                                          strict=True)]


def subset_rings(pairs: list[PhotoPair], tau: F64, params: PhotoParams) -> list[NDArray[np.int64]] | None:
    """The ring (M,) of each point of :func:`point_subsets`, per pair; None when a pair's rings are not known."""
    if any(p.ring is None for p in pairs):
        return None
    return [np.asarray(p.ring, dtype=np.int64)[idx] for p, idx in zip(pairs, _subset_indices(pairs, tau, params),
                                                                     strict=True)]


def _subset_indices(pairs: list[PhotoPair], tau: F64, params: PhotoParams) -> list[NDArray[np.int64]]:
    cap = max(params.max_points // max(len(pairs), 1), params.min_points_per_pair)
    return [_in_view(p, tau, params, cap) for p in pairs]


EVALS_PER_STEP = 25  # cost evaluations per progress report of optimise_photometric


def optimise_photometric(pairs: list[PhotoPair], tau0: F64, params: PhotoParams,
                         fixed_translation: bool = False, subset_tau: F64 | None = None, *,
                         on_iter: Callable[[int, int, float], None] | None = None) -> PhotoResult:
    """Coarse to fine over ``params.blur_deg`` from ``tau0``; each level one
    Nelder-Mead, the last rerun from its result up to ``params.restarts`` times until it moves less than the
    restart tolerance. ``fixed_translation`` holds t (a zero simplex step). ``subset_tau``: the pose whose
    view chooses the points (default ``tau0``; the result's ``subset_tau``: the trust assessment's restarts
    minimise the solve's own points, so their costs compare with its on the objective it minimised).
    ``on_iter(level, step, cost)`` every EVALS_PER_STEP cost evaluations, as the GMM's optimiser reports its
    iterations."""
    if not pairs:
        raise CalibError("no pairs to calibrate")
    tau = np.asarray(tau0, dtype=np.float64).copy()
    chosen_at = tau.copy() if subset_tau is None else np.asarray(subset_tau, dtype=np.float64)
    subsets = point_subsets(pairs, chosen_at, params)
    if sum(len(s[0]) for s in subsets) == 0:
        raise CalibError("no LiDAR point projects into any image under the initial guess")
    traces = []
    last = len(params.blur_deg) - 1
    for level in range(last + 1):
        lps = level_pairs(pairs, tau, params, level, subsets)
        hold_t = fixed_translation or level < params.rotation_only_levels
        step = np.array([np.radians(params.step_rot_deg[level])] * 3
                        + [0.0 if hold_t else params.step_trans_m[level]] * 3)
        step = np.where(step > 0, step, 1e-12)

        evaluations = [0]

        def f(t: F64, lps: list[LevelPair] = lps, level: int = level, seen: list[int] = evaluations) -> float:
            cost = level_cost(lps, t, params)
            seen[0] += 1
            if on_iter is not None and seen[0] % EVALS_PER_STEP == 0:
                on_iter(level, seen[0] // EVALS_PER_STEP, cost)
            return cost

        start_cost = f(tau)
        tau, evals, cost = _nelder_mead(f, tau, step, params.max_evals, params.max_move_steps)
        if level == last:
            for _ in range(params.restarts):
                new, n, cost = _nelder_mead(f, tau, 0.5 * step, params.max_evals, params.max_move_steps)
                evals += n
                xi = xi_of(tau, new)
                tau = new
                if (np.degrees(np.linalg.norm(xi[:3])) < params.restart_tol_deg
                        and np.linalg.norm(xi[3:]) < params.restart_tol_m):
                    break
        traces.append(PhotoLevel(params.blur_deg[level], evals, (start_cost, cost), tau.copy()))
    return PhotoResult(tau, tuple(traces), traces[-1].costs[-1], chosen_at)
