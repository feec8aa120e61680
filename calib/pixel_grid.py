"""The exact evaluator's sums over the edge pixels near each centre, compiled (numba).

For every centre c_i (px) with width sigma_i (px) the weighted GMM needs nine sums over the edge pixels q_j
within the soft disk's reach (4.5 sigma_i): A, dA/dc, B, dB/dc, |Omega| and d|Omega|/dc, the same columns as
:func:`calib.fields.sample_fields` (the definitions are in calib/fields.py: the truncated Gaussian of eq. 9
made continuous, the soft 3-sigma disk that counts |Omega_i| of eq. 10).

The pixels are bucketed once per image in a grid of square cells (:class:`PixelGrid`), so a centre visits
only the cells its disk overlaps, and the sums are accumulated in one compiled loop per centre. This replaced
a k-d tree query per centre followed by numpy over the (point, pixel) list (docs/performance.md): the same
sums up to rounding, without the list. A panorama wraps in u (the seam of paper 5.2, Fig. 6: a pixel counts
when it is within reach directly or across u = 0 / w, and its displacement takes the shortest of the routes
of :meth:`calib.camera.Equirectangular.displacement`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib.compiled import Kernel
from calib.fields import SOFT_REACH, SOFT_WIDTH, TRUNCATION

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

CELL_PX = 16.0  # grid cell side: about the finest levels' reach on a 1024-wide panorama (4.5 sigma ~ 20 px)


@dataclass(frozen=True)
class PixelGrid:
    """One image's edge pixels bucketed by cell: ``uv`` (M,2) float64 px and ``score`` (M,) in cell order,
    ``starts`` (rows * cols + 1,) int64 CSR offsets of each cell's pixels, cells ``cell_w`` x ``cell_h`` px
    (the image width and height divided evenly), ``wrap_u``: a panorama (u wraps at ``width``), ``v_lo`` and
    ``v_hi`` the pixels' least and greatest v (px; which centres can reach a pole)."""

    uv: F64
    score: F64
    starts: I64
    rows: int
    cols: int
    cell_w: float
    cell_h: float
    width: float
    height: float
    wrap_u: bool
    v_lo: float
    v_hi: float

    @classmethod
    def build(cls, uv: F64, score: F64, width: int, height: int, wrap_u: bool) -> PixelGrid:
        """The grid of the edge pixels ``uv`` (M,2) px with scores ``score`` (M,) of a ``width`` x ``height``
        image. Pixels a little outside the image (sub-pixel peaks at the border) go to the border cells."""
        cols = max(1, math.ceil(width / CELL_PX))
        rows = max(1, math.ceil(height / CELL_PX))
        cell_w, cell_h = width / cols, height / rows
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        u = np.mod(uv[:, 0], width) if wrap_u else uv[:, 0]
        col = np.clip(np.floor(u / cell_w).astype(np.int64), 0, cols - 1)
        row = np.clip(np.floor(uv[:, 1] / cell_h).astype(np.int64), 0, rows - 1)
        cell = row * cols + col
        order = np.argsort(cell, kind="stable")
        starts = np.searchsorted(cell[order], np.arange(rows * cols + 1)).astype(np.int64)
        v_lo, v_hi = (float(uv[:, 1].min()), float(uv[:, 1].max())) if len(uv) else (0.0, 0.0)
        return cls(np.ascontiguousarray(uv[order]), np.ascontiguousarray(np.asarray(score, np.float64)[order]),
                   starts, rows, cols, cell_w, cell_h, float(width), float(height), wrap_u, v_lo, v_hi)

    def sums(self, uv: F64, sigma: F64) -> F64:
        """(N, 9) sums at centres ``uv`` (N,2) px with widths ``sigma`` (N,) px (module docstring)."""
        out = np.zeros((len(uv), 9))
        if len(uv) and len(self.uv):
            _sums_kernel(np.ascontiguousarray(uv, dtype=np.float64), np.ascontiguousarray(sigma, dtype=np.float64),
                         self.uv, self.score, self.starts, self.rows, self.cols, self.cell_w, self.cell_h,
                         self.width, self.height, self.wrap_u, self.v_lo, self.v_hi, out)
        return out


def _route_py(du: float, dv_direct: float, vp: float, vc: float, width: float, height: float,
              poles: bool) -> tuple[float, float]:
    """The displacement (du, dv) px from a centre to a pixel, given ``du`` already the shorter way round a
    panorama: direct, or for a panorama centre near a pole (``poles``) the shorter of that and over either
    pole (calib.camera.Equirectangular)."""
    if not poles:
        return du, dv_direct
    du_pole = du - width / 2.0
    du_pole = du_pole - width * np.round(du_pole / width)
    best_u, best_v = du, dv_direct
    best = du * du + dv_direct * dv_direct
    for dv in (-(vp + vc), 2.0 * height - vp - vc):  # over the north pole, over the south pole
        d2 = du_pole * du_pole + dv * dv
        if d2 < best:
            best, best_u, best_v = d2, du_pole, dv
    return best_u, best_v


def _accumulate_py(out: F64, i: int, du: float, dv: float, e: float, s: float) -> None:
    """Add one pixel at displacement (du, dv) with score ``e`` to centre i's nine sums (width ``s``)."""
    d2 = du * du + dv * dv
    s2 = s * s
    if d2 <= 9.0 * s2:
        g_full = math.exp(-0.5 * d2 / s2)
        g = g_full - TRUNCATION
        gu, gv = g_full * du / s2, g_full * dv / s2  # d G / d centre
        out[i, 0] += e * g
        out[i, 1] += e * gu
        out[i, 2] += e * gv
        out[i, 3] += g
        out[i, 4] += gu
        out[i, 5] += gv
    d = math.sqrt(d2)
    if d <= SOFT_REACH * s:
        z = min(max((d - 3.0 * s) / (SOFT_WIDTH * s), -50.0), 50.0)
        soft = 1.0 / (1.0 + math.exp(z))
        dsoft = -soft * (1.0 - soft) / (SOFT_WIDTH * s)
        scale = -dsoft / max(d, 1e-12)  # d soft / d centre = -soft'(d) delta / d
        out[i, 6] += soft
        out[i, 7] += scale * du
        out[i, 8] += scale * dv


def _sums_py(centres: F64, sigma: F64, q: F64, score: F64, starts: I64, rows: int, cols: int, cell_w: float,
             cell_h: float, width: float, height: float, wrap_u: bool, v_lo: float, v_hi: float, out: F64) -> None:
    """:meth:`PixelGrid.sums` written into ``out`` (N, 9); compiled as ``_sums_kernel``."""
    half = width / 2.0
    for i in range(centres.shape[0]):
        cu, cv, s = centres[i, 0], centres[i, 1], sigma[i]
        reach = SOFT_REACH * s
        reach2 = reach * reach
        # A route over a pole beats a direct one within reach only if it is itself within reach.
        poles = wrap_u and (cv + v_lo < reach or 2.0 * height - v_hi - cv < reach)
        r_lo = max(int(math.floor((cv - reach) / cell_h)), 0)
        r_hi = min(int(math.floor((cv + reach) / cell_h)), rows - 1)
        c_lo = int(math.floor((cu - reach) / cell_w))
        c_hi = int(math.floor((cu + reach) / cell_w))
        if wrap_u:
            c_hi = min(c_hi, c_lo + cols - 1)  # a disk wider than the panorama visits each column once
        else:
            c_lo, c_hi = max(c_lo, 0), min(c_hi, cols - 1)
        for r in range(r_lo, r_hi + 1):
            for c in range(c_lo, c_hi + 1):
                cell = r * cols + (c % cols if wrap_u else c)
                for j in range(starts[cell], starts[cell + 1]):
                    du = q[j, 0] - cu
                    if wrap_u:  # the shorter way round the seam
                        if du > half:
                            du -= width
                        elif du < -half:
                            du += width
                    dv = q[j, 1] - cv
                    if du * du + dv * dv > reach2:  # the k-d tree's ball: within reach, across the seam
                        continue
                    du, dv = _route(du, dv, q[j, 1], cv, width, height, poles)
                    _accumulate(out, i, du, dv, score[j], s)


_route, _accumulate = _route_py, _accumulate_py  # compiled in place with the kernel (calib.compiled)
_sums_kernel = Kernel(_sums_py, helpers=("_route", "_accumulate"), nogil=True)
