"""Mutual information as the global search's score on real data (docs/method.md, "Automatic initial guess").

On real street scenes the GMM with one wide Gaussian per point (the search's edge score) tells mounts hardly
apart: every yaw about the LiDAR's up axis puts its edge points on the horizon band, where a real image's
texture is densest. Measured on the Ford Campus head (10 places, five cameras): the grid's edge cost at the
true yaw (-90 deg) was among the worst of 24 yaws at 6, 3 and 1.5 deg, and the search started 108 deg away.
The LiDAR's reflectivity against the image's grey level (Pandey et al.'s mutual information, the same
quantities as :mod:`calib.photometric`) has its best yaw at the truth there, clearly apart from the next
(MI 0.020 against 0.007 at 2 deg of blur). It needs a cloud with intensity; without one the search keeps the
edge score.

Scored here for many rotations at once: each pair's points (a fixed random subset) are projected for every
mount in one batch, their grey samples and reflectivities split into a soft joint histogram per mount (one
bincount), and the histograms of all pairs summed per mount before the MI (KDE-smoothed as Pandey's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib.camera import Equirectangular, project_rotated
from calib.gmm import in_image
from calib.photometric import PhotoPair, _blur, kde_smooth, mutual_information, sample

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]

BINS = 32
POINTS_PER_PAIR = 1500  # a fixed subset per pair: the score's cost stays the same for a head and a panorama


@dataclass(frozen=True)
class MiSearchPair:
    """One pair ready for scoring: its camera's grey image blurred by ``blur_deg``, ``points_lidar`` (N,3) m
    and their ``reflectivity`` (N,) in [0, 1], and the mask of the image (None: all of it)."""

    pair: PhotoPair
    blurred: F32
    points_lidar: F64
    reflectivity: F64


def prepare(pairs: list[PhotoPair], blur_deg: float, seed: int = 0) -> list[MiSearchPair]:
    """Each pair blurred by ``blur_deg`` with a random subset (``seed``) of its points."""
    rng = np.random.default_rng(seed)
    out = []
    for p in pairs:
        idx = np.arange(len(p.points_lidar))
        if len(idx) > POINTS_PER_PAIR:
            idx = np.sort(rng.choice(idx, POINTS_PER_PAIR, replace=False))
        out.append(MiSearchPair(p, _blur(p.grey, p.camera, blur_deg), p.points_lidar[idx], p.reflectivity[idx]))
    return out


def _joints(sp: MiSearchPair, rotations: F64, translation_m: F64) -> F64:
    """(K, BINS * BINS) soft joint histograms of reflectivity and grey level of the pair at each rotation."""
    k = len(rotations)
    cam = sp.pair.camera
    uv, valid = project_rotated(cam, rotations, translation_m, sp.points_lidar)
    inside = in_image(cam, uv, valid)
    if sp.pair.mask is not None and inside.any():
        px = np.rint(uv[inside]).astype(np.int64)
        mask = sp.pair.mask
        wrap = isinstance(cam, Equirectangular)
        cols = np.mod(px[:, 0], mask.shape[1]) if wrap else np.clip(px[:, 0], 0, mask.shape[1] - 1)
        inside[inside] = mask[np.clip(px[:, 1], 0, mask.shape[0] - 1), cols]
    sel = np.flatnonzero(inside)
    out = np.zeros((k, BINS * BINS))
    if sel.size == 0:
        return out
    grey = sample(sp.blurred, cam, uv[sel])
    refl = np.tile(sp.reflectivity, k)[sel]
    mount = sel // len(sp.points_lidar)
    pa, pb = np.clip(refl, 0.0, 1.0) * (BINS - 1), np.clip(grey, 0.0, 1.0) * (BINS - 1)
    ia, ib = np.minimum(np.floor(pa).astype(np.int64), BINS - 2), np.minimum(np.floor(pb).astype(np.int64), BINS - 2)
    fa, fb = pa - ia, pb - ib
    base = mount * BINS * BINS
    idx = np.concatenate([base + ia * BINS + ib, base + (ia + 1) * BINS + ib, base + ia * BINS + ib + 1,
                          base + (ia + 1) * BINS + ib + 1])
    w = np.concatenate([(1 - fa) * (1 - fb), fa * (1 - fb), (1 - fa) * fb, fa * fb])
    out += np.bincount(idx, weights=w, minlength=k * BINS * BINS).reshape(k, BINS * BINS)
    return out


def mi_costs(pairs: list[MiSearchPair], rotations: F64, translation_m: F64) -> F64:
    """(K,) minus the mutual information of all pairs' samples at each rotation (K,3,3) (lower is better; 0
    where no point lands in an image)."""
    joint = np.zeros((len(rotations), BINS * BINS))
    for sp in pairs:
        joint += _joints(sp, rotations, translation_m)
    out = np.zeros(len(rotations))
    for k, j in enumerate(joint):
        n = float(j.sum())
        if n > 0:
            out[k] = -mutual_information(kde_smooth(j.reshape(BINS, BINS), n))
    return out
