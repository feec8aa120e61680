"""Image edge score (paper section 4.1): L0 smoothing, Sobel magnitude, non-maximum suppression.

The score map ``E_I`` (H,W) float64 is normalised to [0, 1]; edge pixels are the pixels above a threshold
(paper: 0.15). Panoramas wrap horizontally (u = 0 and u = w are neighbours), so for them every filter
treats the left and right borders as adjacent.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import scipy.fft
from numpy.typing import NDArray

from calib.errors import CalibError

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class ImageEdgeParams:
    """``l0_lambda``: L0 smoothing weight (Xu et al. 2011; 0 disables smoothing). ``threshold``: on the
    normalised score (paper 0.15). ``normalise_percentile``: the score is divided by this percentile of the
    non-zero NMS responses (100 = the paper's max), which keeps one very strong edge (a lamp) from
    silencing the rest."""

    l0_lambda: float = 0.01
    l0_kappa: float = 2.0
    l0_beta_max: float = 1e5
    threshold: float = 0.15
    normalise_percentile: float = 100.0


@dataclass(frozen=True)
class EdgePixels:
    """Edge pixels of one image: ``uv`` (M,2) float64 px (integer centres), ``score`` (M,) in (0, 1],
    the normalised edge score E_I / max(E_I) of eq. 10."""

    uv: F64
    score: F64


def to_grey(image: NDArray[np.uint8]) -> F64:
    """(H,W) or (H,W,3) BGR uint8 -> (H,W) float64 in [0, 1]."""
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    if grey.ndim != 2:
        raise CalibError(f"image must be (H,W) or (H,W,3), got shape {image.shape}")
    return np.asarray(grey, dtype=np.float64) / 255.0


def l0_smooth(grey: F64, lam: float, kappa: float = 2.0, beta_max: float = 1e5) -> F64:
    """L0 gradient minimisation (Xu, Lu, Xu & Jia 2011) by their alternating FFT solver.

    Minimises ``|S - I|^2 + lam * #{p : grad S(p) != 0}``; boundaries are periodic, which is exact for
    a panorama's horizontal wrap.
    """
    h, w = grey.shape
    fx = np.zeros((h, w))
    fx[0, 0], fx[0, -1] = -1.0, 1.0
    fy = np.zeros((h, w))
    fy[0, 0], fy[-1, 0] = -1.0, 1.0
    otf_x, otf_y = scipy.fft.rfft2(fx), scipy.fft.rfft2(fy)
    denom_grad = np.abs(otf_x) ** 2 + np.abs(otf_y) ** 2
    f_image = scipy.fft.rfft2(grey)
    smooth = grey.copy()
    beta = 2.0 * lam
    while beta < beta_max:
        gx = np.roll(smooth, -1, axis=1) - smooth
        gy = np.roll(smooth, -1, axis=0) - smooth
        flat = gx * gx + gy * gy < lam / beta
        gx[flat] = 0.0
        gy[flat] = 0.0
        # Adjoint of the forward difference: conj(OTF) in the Fourier domain.
        numer = f_image + beta * (np.conj(otf_x) * scipy.fft.rfft2(gx) + np.conj(otf_y) * scipy.fft.rfft2(gy))
        smooth = scipy.fft.irfft2(numer / (1.0 + beta * denom_grad), s=(h, w))
        beta *= kappa
    return np.asarray(smooth, dtype=np.float64)


def _sobel(grey: F64, wrap_u: bool) -> tuple[F64, F64]:
    pad = np.pad(grey, ((1, 1), (0, 0)), mode="reflect")
    pad = np.pad(pad, ((0, 0), (1, 1)), mode="wrap" if wrap_u else "reflect")
    gx = cv2.Sobel(pad, cv2.CV_64F, 1, 0, ksize=3)[1:-1, 1:-1]
    gy = cv2.Sobel(pad, cv2.CV_64F, 0, 1, ksize=3)[1:-1, 1:-1]
    return np.asarray(gx, dtype=np.float64), np.asarray(gy, dtype=np.float64)


def non_max_suppression(magnitude: F64, gx: F64, gy: F64, wrap_u: bool) -> F64:
    """Keep pixels that are maxima across the edge (gradient direction quantised to 4 directions)."""
    angle = np.mod(np.degrees(np.arctan2(gy, gx)), 180.0)
    sector = np.rint(angle / 45.0).astype(np.int64) % 4  # 0: horizontal gradient, 1: 45, 2: vertical, 3: 135
    offsets = ((0, 1), (1, 1), (1, 0), (1, -1))
    padded = np.pad(magnitude, ((1, 1), (0, 0)), mode="edge")
    padded = np.pad(padded, ((0, 0), (1, 1)), mode="wrap" if wrap_u else "edge")
    h, w = magnitude.shape
    keep = np.zeros_like(magnitude, dtype=bool)
    for s, (dv, du) in enumerate(offsets):
        fwd = padded[1 + dv : 1 + dv + h, 1 + du : 1 + du + w]
        bwd = padded[1 - dv : 1 - dv + h, 1 - du : 1 - du + w]
        # >= on one side, > on the other: a plateau two pixels wide keeps exactly one of them.
        keep |= (sector == s) & (magnitude >= fwd) & (magnitude > bwd)
    return np.where(keep, magnitude, 0.0)


def image_edge_score(image: NDArray[np.uint8], params: ImageEdgeParams, wrap_u: bool) -> F64:
    """E_I (H,W) float64 in [0, 1] (paper 4.1): L0-smoothed Sobel magnitude after NMS, normalised."""
    grey = to_grey(image)
    if params.l0_lambda > 0:
        grey = l0_smooth(grey, params.l0_lambda, params.l0_kappa, params.l0_beta_max)
    gx, gy = _sobel(grey, wrap_u)
    nms = non_max_suppression(np.hypot(gx, gy), gx, gy, wrap_u)
    positive = nms[nms > 0]
    if positive.size == 0:
        return nms
    scale = float(np.percentile(positive, params.normalise_percentile))
    return np.minimum(nms / max(scale, 1e-12), 1.0)


def extract_edge_pixels(score: F64, threshold: float) -> EdgePixels:
    """Edge pixels with E_I above ``threshold``; pixel (row i, col j) is (u, v) = (j, i)."""
    rows, cols = np.nonzero(score > threshold)
    uv = np.stack([cols, rows], axis=1).astype(np.float64)
    return EdgePixels(uv, score[rows, cols].astype(np.float64))
