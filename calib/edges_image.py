"""Image edge score (paper section 4.1): L0 smoothing, Sobel magnitude, non-maximum suppression.

The score map ``E_I`` (H,W) float64 is normalised to [0, 1]; edge pixels are the pixels above a threshold
(paper: 0.15). Panoramas wrap horizontally (u = 0 and u = w are neighbours), so for them every filter
treats the left and right borders as adjacent.

Texture (foliage, fence bars, grass, a traffic light's face) is then dropped: a LiDAR occlusion edge is an
object's silhouette, a long contour with few others beside it, while texture packs many short edges into a
small area. An edge pixel is kept when the edge pixels within a radius r of it amount to at most
``texture_max_lines`` straight lines through that disk (a line through its centre holds 2r + 1 pixels). The
radius is an angle (``texture_radius_deg``, at least ``texture_min_radius_px``): about the finest Gaussian's
reach on a pinhole camera, so edges closer together than the cost can tell apart count as texture.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import scipy.fft
from numpy.typing import NDArray

from calib.errors import CalibError
from calib.l0_kernel import flattened_adjoint, spectral_update
from calib.nms_kernel import non_max

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]


@dataclass(frozen=True)
class ImageEdgeParams:
    """``l0_lambda``: L0 smoothing weight (Xu et al. 2011; 0 disables smoothing). ``threshold``: on the
    normalised score (paper 0.15). ``normalise_percentile``: the score is divided by this percentile of the
    non-zero NMS responses (100 = the paper's max), which keeps one very strong edge (a lamp) from
    silencing the rest. ``clahe_clip``: contrast-limited adaptive histogram equalisation before smoothing
    (0 disables), so an edge's score follows local contrast rather than global exposure or haze.
    ``texture_radius_deg``, ``texture_min_radius_px``, ``texture_max_lines``: texture suppression (module
    docstring; radius 0 disables, the paper has none). ``mask_margin_px``: with a mask of the pixels that show
    the scene, edge pixels closer than this to a masked pixel are dropped (the mask's own border, the rig's
    body and a rectified image's black surround are edges of the image, not of the scene)."""

    clahe_clip: float = 0.0
    l0_lambda: float = 0.01
    l0_kappa: float = 2.0
    l0_beta_max: float = 1e5
    threshold: float = 0.15
    normalise_percentile: float = 100.0
    texture_radius_deg: float = 0.3
    texture_min_radius_px: int = 3
    texture_max_lines: float = 2.0
    mask_margin_px: int = 4

    def texture_radius_px(self, pixels_per_radian: float) -> int:
        """The texture disk's radius in pixels for a camera with ``pixels_per_radian`` (0: no suppression)."""
        if self.texture_radius_deg <= 0:
            return 0
        return max(self.texture_min_radius_px, round(float(np.radians(self.texture_radius_deg)) * pixels_per_radian))


@dataclass(frozen=True)
class EdgePixels:
    """Edge pixels of one image: ``uv`` (M,2) float64 px (sub-pixel), ``score`` (M,) in (0, 1],
    the normalised edge score E_I / max(E_I) of eq. 10."""

    uv: F64
    score: F64


def to_grey(image: NDArray[np.uint8], clahe_clip: float = 0.0) -> F64:
    """(H,W) or (H,W,3) BGR uint8 -> (H,W) float64 in [0, 1], optionally CLAHE-equalised."""
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    if grey.ndim != 2:
        raise CalibError(f"image must be (H,W) or (H,W,3), got shape {image.shape}")
    if clahe_clip > 0:
        grey = cv2.createCLAHE(clipLimit=clahe_clip, tileGridSize=(8, 8)).apply(np.ascontiguousarray(grey))
    return np.asarray(grey, dtype=np.float64) / 255.0


def l0_smooth(grey: F64, lam: float, kappa: float = 2.0, beta_max: float = 1e5) -> F64:
    """L0 gradient minimisation (Xu, Lu, Xu & Jia 2011) by their alternating FFT solver.

    Minimises ``|S - I|^2 + lam * #{p : grad S(p) != 0}``; boundaries are periodic, which is exact for
    a panorama's horizontal wrap. Solved in float32: 2.4x faster than float64 on a 2048x1024 panorama, and
    the result differs from float64's by 2e-6 of the grey range on average (at most 1e-3 where a gradient
    sits on the flattening threshold), below one grey level (1/255).
    """
    h, w = grey.shape
    fx = np.zeros((h, w), np.float32)
    fx[0, 0], fx[0, -1] = -1.0, 1.0
    fy = np.zeros((h, w), np.float32)
    fy[0, 0], fy[-1, 0] = -1.0, 1.0
    denom_grad = np.abs(scipy.fft.rfft2(fx)) ** 2 + np.abs(scipy.fft.rfft2(fy)) ** 2
    smooth = np.ascontiguousarray(grey, dtype=np.float32)
    f_image = scipy.fft.rfft2(smooth)
    gx, gy, adjoint = (np.empty((h, w), np.float32) for _ in range(3))
    beta = 2.0 * lam
    while beta < beta_max:
        # Forward differences flattened where their energy is below lam / beta, then their adjoint in space
        # (conj(OTF) in the Fourier domain), so one forward FFT per iteration instead of two.
        flattened_adjoint(smooth, np.float32(lam / beta), gx, gy, adjoint)
        f_adjoint = scipy.fft.rfft2(adjoint)
        f_adjoint[0, 0] = 0.0  # a difference's adjoint sums to 0; in float32, beta (up to 1e5) x rounding does not
        spectral_update(f_image, f_adjoint, np.float32(beta), denom_grad)
        # f_adjoint is not needed again: the inverse may work in it (30 % faster, the same values).
        smooth = np.ascontiguousarray(scipy.fft.irfft2(f_adjoint, s=(h, w), overwrite_x=True))
        beta *= kappa
    return np.asarray(smooth, dtype=np.float64)


def _sobel(grey: F64, wrap_u: bool) -> tuple[F64, F64]:
    pad = np.pad(grey, ((1, 1), (0, 0)), mode="reflect")
    pad = np.pad(pad, ((0, 0), (1, 1)), mode="wrap" if wrap_u else "reflect")
    gx = cv2.Sobel(pad, cv2.CV_64F, 1, 0, ksize=3)[1:-1, 1:-1]
    gy = cv2.Sobel(pad, cv2.CV_64F, 0, 1, ksize=3)[1:-1, 1:-1]
    return np.asarray(gx, dtype=np.float64), np.asarray(gy, dtype=np.float64)


_SECTOR_STEPS = ((1, 0), (1, 1), (0, 1), (-1, 1))  # (du, dv) across the edge for gradient sectors 0..3


def _gradient_sector(gx: F64, gy: F64) -> NDArray[np.int64]:
    """Gradient direction quantised to 4 sectors: 0 along u, 1 diagonal, 2 along v, 3 anti-diagonal."""
    angle = np.mod(np.degrees(np.arctan2(gy, gx)), 180.0)
    return np.asarray(np.rint(angle / 45.0).astype(np.int64) % 4)


def non_max_suppression(magnitude: F64, gx: F64, gy: F64, wrap_u: bool) -> F64:
    """Keep pixels that are maxima across the edge (gradient direction quantised to 4 directions, the
    sectors of :func:`_gradient_sector`); ``>=`` on one side and ``>`` on the other, so a plateau two pixels
    wide keeps exactly one of them. Compiled: :mod:`calib.nms_kernel`."""
    out = np.empty_like(magnitude, dtype=np.float64)
    non_max(np.ascontiguousarray(magnitude, dtype=np.float64), np.ascontiguousarray(gx, dtype=np.float64),
            np.ascontiguousarray(gy, dtype=np.float64), wrap_u, out)
    return out


def subpixel_offsets(magnitude: F64, gx: F64, gy: F64, rows: NDArray[np.intp], cols: NDArray[np.intp],
                     wrap_u: bool) -> F64:
    """(K,2) offset in px from each pixel (``rows``, ``cols``) to the peak of a parabola through the gradient
    magnitude across the edge. NMS alone keeps one pixel of a step edge that falls between two pixels, always the
    one with the lower index on ties: a systematic half-pixel shift (0.18 deg at 1024 px) that the calibration
    would inherit. Computed at the given pixels only (the edge pixels: a few percent of the image)."""
    h, w = magnitude.shape
    sector = _gradient_sector(gx[rows, cols], gy[rows, cols])
    steps = np.array(_SECTOR_STEPS)[sector]  # (K,2) (du, dv) across the edge
    cols_f, cols_b = cols + steps[:, 0], cols - steps[:, 0]
    if wrap_u:
        cols_f, cols_b = np.mod(cols_f, w), np.mod(cols_b, w)
    else:
        cols_f, cols_b = np.clip(cols_f, 0, w - 1), np.clip(cols_b, 0, w - 1)
    fwd = magnitude[np.clip(rows + steps[:, 1], 0, h - 1), cols_f]
    bwd = magnitude[np.clip(rows - steps[:, 1], 0, h - 1), cols_b]
    centre = magnitude[rows, cols]
    curvature = bwd - 2.0 * centre + fwd
    peaked = curvature < -1e-12
    t = np.clip(np.where(peaked, 0.5 * (bwd - fwd) / np.where(peaked, curvature, -1.0), 0.0), -0.5, 0.5)
    return np.asarray(t[:, None] * steps, dtype=np.float64)


def _smoothed(grey: F64, params: ImageEdgeParams, wrap_u: bool) -> F64:
    """L0 smoothing of ``grey`` (H,W). A panorama's columns wrap, so its FFT boundaries are exact as they are
    (and its sizes are powers of two). Any other image is padded by mirroring to sizes the FFT factors well and
    cropped back: a width of 1616 = 16 x 101 (the Ford images) made each transform twice as slow as 1620's."""
    if wrap_u:
        return l0_smooth(grey, params.l0_lambda, params.l0_kappa, params.l0_beta_max)
    h, w = grey.shape
    fast_h, fast_w = scipy.fft.next_fast_len(h, real=True), scipy.fft.next_fast_len(w, real=True)
    padded = np.pad(grey, ((0, fast_h - h), (0, fast_w - w)), mode="symmetric")
    return l0_smooth(padded, params.l0_lambda, params.l0_kappa, params.l0_beta_max)[:h, :w]


def _edge_maps(image: NDArray[np.uint8], params: ImageEdgeParams, wrap_u: bool) -> tuple[F64, F64, F64, F64]:
    grey = to_grey(image, params.clahe_clip)
    if params.l0_lambda > 0:
        grey = _smoothed(grey, params, wrap_u)
    gx, gy = _sobel(grey, wrap_u)
    magnitude = np.hypot(gx, gy)
    return magnitude, gx, gy, non_max_suppression(magnitude, gx, gy, wrap_u)


def _normalise(nms: F64, percentile: float) -> F64:
    positive = nms[nms > 0]
    if positive.size == 0:
        return nms
    scale = float(np.percentile(positive, percentile))
    return np.asarray(np.minimum(nms / max(scale, 1e-12), 1.0), dtype=np.float64)


def edge_line_density(mask: NDArray[np.bool_], radius_px: int, wrap_u: bool) -> F64:
    """(H,W) float64: the edge pixels of ``mask`` within ``radius_px`` of each pixel, in straight lines through
    the disk (2 radius + 1 pixels each): about 1 on an isolated contour, several in texture."""
    r = int(radius_px)
    yy, xx = np.mgrid[-r : r + 1, -r : r + 1]
    disk = (xx * xx + yy * yy <= r * r).astype(np.float32)
    padded = np.pad(mask.astype(np.float32), ((r, r), (0, 0)))
    padded = np.pad(padded, ((0, 0), (r, r)), mode="wrap" if wrap_u else "constant")
    counts = cv2.filter2D(padded, cv2.CV_32F, disk, borderType=cv2.BORDER_CONSTANT)[r:-r, r:-r]
    return np.asarray(counts, dtype=np.float64) / (2 * r + 1)


def scene_pixels(mask: NDArray[np.bool_], margin_px: int) -> NDArray[np.bool_]:
    """(H,W) bool: the pixels of ``mask`` (True where the image shows the scene) at least ``margin_px`` from any
    pixel outside it (and from the image border)."""
    if margin_px <= 0:
        return np.asarray(mask, dtype=bool)
    kernel = np.ones((2 * margin_px + 1, 2 * margin_px + 1), np.uint8)
    eroded = cv2.erode(np.asarray(mask, dtype=np.uint8), kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return np.asarray(eroded > 0)


def image_edge_pixels(image: NDArray[np.uint8], params: ImageEdgeParams, wrap_u: bool,
                      pixels_per_radian: float, mask: NDArray[np.bool_] | None = None) -> EdgePixels:
    """Edge pixels above the threshold and not in texture, each moved to its sub-pixel peak across the edge.
    ``mask`` (H,W) bool, True where the image shows the scene: edge pixels near masked pixels are dropped."""
    magnitude, gx, gy, nms = _edge_maps(image, params, wrap_u)
    if mask is not None:
        if mask.shape != image.shape[:2]:
            raise CalibError(f"mask is {mask.shape[1]}x{mask.shape[0]}, the image {image.shape[1]}x{image.shape[0]}")
        nms = np.where(scene_pixels(mask, params.mask_margin_px), nms, 0.0)
    score = _normalise(nms, params.normalise_percentile)
    edges = score > params.threshold
    radius = params.texture_radius_px(pixels_per_radian)
    if radius > 0:
        edges &= edge_line_density(edges, radius, wrap_u) <= params.texture_max_lines
    rows, cols = np.nonzero(edges)
    offsets = subpixel_offsets(magnitude, gx, gy, rows, cols, wrap_u)
    uv = np.stack([cols, rows], axis=1).astype(np.float64) + offsets
    if wrap_u:
        uv[:, 0] = np.mod(uv[:, 0], image.shape[1])
    return EdgePixels(uv, score[rows, cols].astype(np.float64))
