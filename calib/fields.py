"""Gaussian-filtered edge maps: the GMM's sums over edge pixels as images, sampled at projected points.

For a centre c and a width sigma, the weighted GMM needs (eq. 8-10, with |Omega_i| and sigma_i frozen)
  A(c) = sum_j e_j g(q_j - c),  B(c) = sum_j g(q_j - c),  g(y) = exp(-|y|^2 / 2 sigma^2) for |y| <= 3 sigma,
their gradients with respect to c, and |Omega(c)| = #{j : |q_j - c| <= 3 sigma}. Each is a correlation of the
edge-score map (or the edge mask) with a fixed kernel, so it is computed once per image for a ladder of
sigmas (3 per octave) and sampled bilinearly; a sigma between two rungs interpolates in log sigma. Rungs
with sigma >= 4 px are computed on maps sum-pooled by f = 2^floor(log2(sigma / 2)), so the cost of a rung is
bounded whatever its width (the image pyramid the issue asks for). Differences from the exact sum: the
kernel's support is the 6-sigma square rather than the 3-sigma disk (the corners hold < 1.2 % of the
kernel's value at the disk's edge), pooled pixels sit at their cell's centre (at most f/2 <= sigma/4 away),
and the bilinear/log-sigma interpolation. ``tests/calib/test_fields.py`` and ``docs/method.md`` measure it.

The maps are built lazily (docs/performance.md): a rung only when a sample needs it, and in each block of
``COLUMN_BLOCK`` image columns only for the rows that samples reach (projected LiDAR points cover a band of
the panorama a few tens of degrees high, tilted with the rig), grown as the samples move. A band is filtered
with the same zero rows outside the image as the whole map, so a sample's value does not depend on how the
band grew (chunks of fixed windows, each correlated by FFT: ``tests/calib/test_fields.py`` pins the bands
against whole-image maps).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.fft
from numpy.typing import NDArray

from calib.errors import CalibError
from calib.field_gather import gather

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
I64 = NDArray[np.int64]
Mask = NDArray[np.bool_]

RUNGS_PER_OCTAVE = 3
BAND_BLOCK = 16  # bands grow by whole blocks of this many image rows, so they are extended rarely
ROW_CHUNK = 32  # pooled rows computed together (fixed windows: history-independent values; 32: docs/performance.md)
COLUMN_BLOCK = 128  # image columns that share one row band (a tilted LiDAR band moves ~60 rows across one)
POOL_FROM_PX = 4.0  # rungs this wide are built on pooled maps; narrower ones at full resolution


TRUNCATION = float(np.exp(-4.5))  # G at 3 sigma: subtracted so the truncated kernel is continuous
SOFT_WIDTH = 0.2  # width (in sigma) of the logistic edge of the soft 3-sigma disk that counts |Omega|
SOFT_REACH = 4.5  # the soft disk is cut at 4.5 sigma, where it is 6e-4


def gaussian_kernel(d2: F64, sigma: F64 | float) -> F64:
    """exp(-d^2 / 2 sigma^2) - exp(-4.5) inside 3 sigma, 0 outside: eq. 9's truncated Gaussian, made
    continuous at the truncation so the cost does not jump when a pixel crosses 3 sigma."""
    return np.where(d2 <= 9.0 * sigma * sigma, np.exp(-0.5 * d2 / (sigma * sigma)) - TRUNCATION, 0.0)


def soft_disk(d: F64, sigma: F64 | float) -> tuple[F64, F64]:
    """A soft count of pixels within 3 sigma and its derivative with respect to d."""
    z = np.clip((d - 3.0 * sigma) / (SOFT_WIDTH * sigma), -50.0, 50.0)
    value = np.where(d <= SOFT_REACH * sigma, 1.0 / (1.0 + np.exp(z)), 0.0)
    return value, -value * (1.0 - value) / (SOFT_WIDTH * sigma)


def _window(image: F64, r0: int, r1: int, c0: int, c1: int, wrap_u: bool) -> F64:
    """``image[r0:r1, c0:c1]`` with zeros outside the image, except across the u seam of a panorama."""
    h, w = image.shape
    out = np.zeros((r1 - r0, c1 - c0))
    a, b = max(r0, 0), min(r1, h)
    if b > a:
        cols = np.arange(c0, c1)
        inside = np.ones(len(cols), bool) if wrap_u else (cols >= 0) & (cols < w)
        out[a - r0:b - r0, inside] = image[a:b][:, np.mod(cols[inside], w)]
    return out


def _factor(sigma: float, width: int, wrap_u: bool) -> int:
    f = int(2 ** max(0, int(np.floor(np.log2(sigma / 2.0))))) if sigma >= POOL_FROM_PX else 1
    return 1 if wrap_u and width % f else f


def _kernels(sigma: float, f: int) -> F64:
    """(9, K, K) correlation kernels of one rung on maps pooled by ``f``: G, dG/dc (u, v) for the score and
    the mask, then the soft disk and its derivatives for the mask."""
    s = sigma / f
    radius = int(np.ceil(SOFT_REACH * s))
    y = np.arange(-radius, radius + 1, dtype=np.float64)
    yy, xx = np.meshgrid(y, y, indexing="ij")  # (row offset = v, column offset = u) in pooled pixels
    d2 = (xx * xx + yy * yy) * f * f  # in original pixels
    g = gaussian_kernel(d2, sigma)
    c, dc_dd = soft_disk(np.sqrt(d2), sigma)
    d = np.maximum(np.sqrt(d2), 1e-12)
    # Derivatives with respect to the centre c of k(q - c), with q - c = (xx, yy) * f:
    # d/dc exp(-|q-c|^2/2s^2) = exp(.) (q - c) / s^2 ; d/dc soft(|q-c|) = -soft'(d) (q - c) / d.
    g_full = np.where(d2 <= 9.0 * sigma * sigma, np.exp(-0.5 * d2 / sigma**2), 0.0)
    gu, gv = g_full * xx * f / sigma**2, g_full * yy * f / sigma**2
    cu, cv = -dc_dd * xx * f / d, -dc_dd * yy * f / d
    return np.stack([g, gu, gv, g, gu, gv, c, cu, cv])


_CHANNEL_MAP = [0, 0, 0, 1, 1, 1, 1, 1, 1]  # the window (score 0, mask 1) each of the nine kernels reads


class _Spectra:
    """One rung's nine kernels, flipped and transformed for each window shape they meet (a growth meets one
    or two: chunks of ROW_CHUNK rows, a shorter last one; a narrower last column block)."""

    def __init__(self, kernels: F64) -> None:
        self.flipped = np.ascontiguousarray(kernels[:, ::-1, ::-1])
        self.radius = kernels.shape[1] // 2
        self._by_shape: dict[tuple[int, int], tuple[NDArray[np.complex128], tuple[int, int]]] = {}

    def spectra(self, window: tuple[int, ...]) -> tuple[NDArray[np.complex128], tuple[int, int]]:
        """(9, H', W'//2+1) spectra for a window (H, W), and the transform shape (H', W') >= (H, W)."""
        key = (int(window[0]), int(window[1]))
        if key not in self._by_shape:
            shape = (scipy.fft.next_fast_len(key[0], real=True), scipy.fft.next_fast_len(key[1], real=True))
            padded = np.zeros((9, *shape), np.float32)
            size = self.flipped.shape[1]
            padded[:, :size, :size] = self.flipped
            self._by_shape[key] = (scipy.fft.rfft2(padded), shape)
        return self._by_shape[key]


@dataclass
class EdgeFields:
    """The rungs of one image's edge pixels, for sigmas ``sigmas_px`` (3 per octave), built on demand.

    Holds the edge pixels (``uv`` (M,2) px, ``score`` (M,)) and the built bands, all in one buffer ``flat``
    (cells, 9) float32 with channels A, dA/dc (u, v), B, dB/dc (u, v), soft |Omega|, d|Omega|/dc (u, v).
    Rung k is pooled by ``factor[k]`` to (``hf[k]``, ``wf[k]``) and cut into column blocks of ``cb[k]``
    pooled columns (``COLUMN_BLOCK`` image columns); block (k, b) holds pooled rows
    ``row0[k, b] : row0[k, b] + rows[k, b]`` at ``offset[k, b]``, ``bw[k, b]`` cells wide. One buffer lets a
    sample gather every point's rungs and corners at once. The cache only grows; sampling the same place
    always returns the same values."""

    uv: F64
    score: F64
    width: int
    height: int
    wrap_u: bool
    sigmas_px: F64
    factor: I64 = field(init=False)
    hf: I64 = field(init=False)
    wf: I64 = field(init=False)
    cb: I64 = field(init=False)
    bw: I64 = field(init=False)
    row0: I64 = field(init=False)
    rows: I64 = field(init=False)
    offset: I64 = field(init=False)
    flat: F32 = field(init=False)
    band_lo: I64 = field(init=False)  # per column block: image rows asked for so far, rounded to BAND_BLOCK
    band_hi: I64 = field(init=False)

    def __post_init__(self) -> None:
        self.factor = np.array([_factor(float(s), self.width, self.wrap_u) for s in self.sigmas_px], np.int64)
        self.hf, self.wf = -(-self.height // self.factor), -(-self.width // self.factor)
        self.cb = np.maximum(COLUMN_BLOCK // self.factor, 1)
        n_blocks = int((-(-self.wf // self.cb)).max())
        starts = np.arange(n_blocks)[None, :] * self.cb[:, None]
        self.bw = np.clip(self.wf[:, None] - starts, 0, self.cb[:, None])
        shape = (len(self.sigmas_px), n_blocks)
        self.row0, self.rows, self.offset = (np.zeros(shape, np.int64) for _ in range(3))
        self.flat = np.zeros((0, 9), np.float32)
        self.band_lo, self.band_hi = np.full(n_blocks, self.height), np.zeros(n_blocks, np.int64)

    def __reduce__(self) -> tuple[type[EdgeFields], tuple[F64, F64, int, int, bool, F64]]:
        """Pickled without the built bands: a copy sent to another process rebuilds what it samples, to the
        same values (the cache only saves time), instead of carrying up to hundreds of MB along."""
        return EdgeFields, (self.uv, self.score, self.width, self.height, self.wrap_u, self.sigmas_px)

    @classmethod
    def build(
        cls, uv: F64, score: F64, width: int, height: int, *, wrap_u: bool, sigma_min: float, sigma_max: float
    ) -> EdgeFields:
        """``uv`` (M,2) px edge positions (sub-pixel), ``score`` (M,) normalised edge scores."""
        n = int(np.ceil(np.log2(sigma_max / sigma_min) * RUNGS_PER_OCTAVE)) + 1
        sigmas = sigma_min * 2.0 ** (np.arange(n) / RUNGS_PER_OCTAVE)
        return cls(np.asarray(uv, np.float64), np.asarray(score, np.float64), width, height, wrap_u, sigmas)

    def rung_position(self, sigma: F64) -> F64:
        """Where widths ``sigma`` (N,) px fall on the ladder (N,): rung floor(pos) and the next, mixed by the
        fraction (clipped to the ladder's ends)."""
        n_rungs = len(self.sigmas_px)
        return np.asarray(np.clip(np.log2(sigma / self.sigmas_px[0]) * RUNGS_PER_OCTAVE, 0.0, n_rungs - 1.000001),
                          dtype=np.float64)

    def reads_pooled(self, sigma: F64) -> Mask:
        """(N,) whether a centre of width ``sigma`` px samples only rungs at least ``POOL_FROM_PX`` wide (those
        built on pooled maps; narrower rungs are full resolution)."""
        wide = np.flatnonzero(self.sigmas_px >= POOL_FROM_PX)
        if not len(wide):
            return np.zeros(len(sigma), dtype=bool)
        return np.asarray(np.floor(self.rung_position(sigma)) >= wide[0], dtype=bool)

    @property
    def nbytes(self) -> int:
        """Memory held by the built maps."""
        return int(self.flat.nbytes)

    def _splat(self, f: int) -> tuple[F64, F64]:
        """Score and mask maps sum-pooled by ``f`` (ceil(H/f), ceil(W/f)): sub-pixel edge positions splatted
        bilinearly onto pixels, which keeps each pixel's mass and centroid, each pixel summed into its cell.
        Straight from the edge pixels: a full-resolution map pooled on every growth cost more than the
        bands it fed (Ford head, 5 x 1616x616 images a place)."""
        hp, wp = -(-self.height // f), -(-self.width // f)
        score_map, mask_map = np.zeros(hp * wp), np.zeros(hp * wp)
        uv, width, height = self.uv, self.width, self.height
        u0, v0 = np.floor(uv[:, 0]).astype(np.int64), np.floor(uv[:, 1]).astype(np.int64)
        au, av = uv[:, 0] - u0, uv[:, 1] - v0
        for du, dv, wgt in ((0, 0, (1 - au) * (1 - av)), (1, 0, au * (1 - av)), (0, 1, (1 - au) * av), (1, 1, au * av)):
            cols, rows = u0 + du, v0 + dv
            if self.wrap_u:
                cols = np.mod(cols, width)
            ok = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
            cell = rows[ok] // f * wp + cols[ok] // f
            score_map += np.bincount(cell, (self.score * wgt)[ok], minlength=hp * wp)
            mask_map += np.bincount(cell, wgt[ok], minlength=hp * wp)
        return score_map.reshape(hp, wp), mask_map.reshape(hp, wp)

    def _block(self, k: int, b: int) -> F32:
        """The built rows of block (k, b), (rows, bw, 9)."""
        a, r, w = int(self.offset[k, b]), int(self.rows[k, b]), int(self.bw[k, b])
        return self.flat[a: a + r * w].reshape(r, w, 9)

    def _maps(self, lo: int, hi: int, c0: int, c1: int, pooled: tuple[F64, F64], kernels: _Spectra) -> F32:
        """Pooled rows ``lo:hi`` and columns ``c0:c1`` of one rung, (hi - lo, c1 - c0, 9) float32: the 2-D
        correlation of the pooled maps with the rung's ``kernels``, zero outside the image except across the u
        seam of a panorama, from only the window of the maps the kernels reach. By FFT: the window's two
        transforms times the nine kernels' (made once per window shape), one inverse for all nine; the
        cyclic wrap of an unpadded transform only reaches the kernel margin, which is cut off."""
        r = kernels.radius
        windows = np.stack([_window(m, lo - r, hi + r, c0 - r, c1 + r, self.wrap_u) for m in pooled]).astype(np.float32)
        spectra, shape = kernels.spectra(windows.shape[1:])
        product = scipy.fft.rfft2(windows, s=shape)[_CHANNEL_MAP] * spectra
        # The product is a temporary: the inverse may work in it (faster, the same values).
        maps: F64 = scipy.fft.irfft2(product, s=shape, overwrite_x=True)
        maps = maps[:, 2 * r: windows.shape[1], 2 * r: windows.shape[2]]
        return np.moveaxis(maps, 0, -1).astype(np.float32)

    def grow(self, need_lo: I64, need_hi: I64) -> None:
        """Extend the blocks so block (k, b) covers pooled rows ``need_lo[k, b] : need_hi[k, b]`` (nothing
        where lo >= hi).

        A block built or extended covers at least the image rows any rung was asked for in its column block
        so far (rounded out to ``BAND_BLOCK``): the samples of all rungs come from the same projected points,
        so the next rung asked for finds its band ready instead of growing it again."""
        end = self.row0 + self.rows
        short = (need_hi > need_lo) & (self.bw > 0) & ((self.rows == 0) | (need_lo < self.row0) | (need_hi > end))
        if not short.any():
            return
        f = self.factor[:, None]
        lo_px = np.where(short, need_lo * f, self.height).min(axis=0)
        hi_px = np.where(short, need_hi * f, 0).max(axis=0)
        self.band_lo = np.minimum(self.band_lo, lo_px) // BAND_BLOCK * BAND_BLOCK
        self.band_hi = np.minimum(-(-np.maximum(self.band_hi, hi_px) // BAND_BLOCK) * BAND_BLOCK, self.height)
        # New extent of each short block: what it has, what is asked, and its column block's band.
        new_lo = np.minimum(need_lo, self.band_lo[None, :] // f)
        new_hi = np.maximum(need_hi, np.minimum(-(-self.band_hi[None, :] // f), self.hf[:, None]))
        new_lo = np.where(self.rows > 0, np.minimum(new_lo, self.row0), new_lo)
        new_hi = np.where(self.rows > 0, np.maximum(new_hi, end), new_hi)
        # Whole chunks of ROW_CHUNK pooled rows only, each always computed from the same window: a cell's
        # value then does not depend on which rows were asked for first (an FFT's result depends on the
        # window it is given at rounding level, which a long solve can amplify into a different answer).
        new_lo = new_lo // ROW_CHUNK * ROW_CHUNK
        new_hi = np.minimum(-(-new_hi // ROW_CHUNK) * ROW_CHUNK, self.hf[:, None])
        chunks = self._compute(self._chunk_jobs(short, new_lo, new_hi, end))
        blocks = []
        for k, b in np.ndindex(*self.rows.shape):
            block = self._block(k, b)
            if short[k, b]:  # only the missing rows were computed: a built cell keeps its value
                parts = chunks[k, b]  # an unbuilt block has row0 = rows = 0: all its chunks go below
                block = np.concatenate([m for a, m in parts if a < self.row0[k, b]] + [block]
                                       + [m for a, m in parts if a >= end[k, b]])
                self.row0[k, b], self.rows[k, b] = new_lo[k, b], new_hi[k, b] - new_lo[k, b]
            blocks.append(block.reshape(-1, 9))
        sizes = np.array([len(b) for b in blocks], np.int64)
        self.offset = (np.cumsum(sizes) - sizes).reshape(self.rows.shape)
        self.flat = np.concatenate(blocks)

    def _chunk_jobs(self, short: Mask, new_lo: I64, new_hi: I64, end: I64) -> list[tuple[int, int, int, int]]:
        """(rung, block, first pooled row, end row) of each ROW_CHUNK the short blocks miss, above and below
        the rows they hold."""
        jobs = []
        for k, b in zip(*np.nonzero(short), strict=True):
            lo, hi = int(new_lo[k, b]), int(new_hi[k, b])
            have_lo, have_hi = (int(self.row0[k, b]), int(end[k, b])) if self.rows[k, b] else (lo, lo)
            jobs += [(int(k), int(b), a, min(a + ROW_CHUNK, have_lo)) for a in range(lo, have_lo, ROW_CHUNK)]
            jobs += [(int(k), int(b), a, min(a + ROW_CHUNK, hi)) for a in range(have_hi, hi, ROW_CHUNK)]
        return jobs

    def _compute(self, jobs: list[tuple[int, int, int, int]]) -> dict[tuple[int, int], list[tuple[int, F32]]]:
        """The chunks of ``jobs``, per block in row order. The edge maps are splatted once per pooling factor,
        and each rung's kernels and their spectra made once, for all of them (a chunk's window of the pooled
        map holds the same sums as the pooled window of the map: windows start on whole pooling cells)."""
        rungs = sorted({k for k, _, _, _ in jobs})
        pooled = {int(f): self._splat(int(f)) for f in set(self.factor[rungs])}
        kernels = {k: _Spectra(_kernels(float(self.sigmas_px[k]), int(self.factor[k]))) for k in rungs}
        out: dict[tuple[int, int], list[tuple[int, F32]]] = {}
        for k, b, a, z in jobs:
            c0 = b * int(self.cb[k])
            maps = self._maps(a, z, c0, c0 + int(self.bw[k, b]), pooled[int(self.factor[k])], kernels[k])
            out.setdefault((k, b), []).append((a, maps))
        return out

    def sample(self, uv: F64, sigma: F64) -> F64:
        """(N, 9): A, dA/dc, B, dB/dc, |Omega|, d|Omega|/dc at centres ``uv`` (N,2) px with widths ``sigma``
        (N,) px (:func:`sample_fields` of this image alone)."""
        return sample_fields([self], [len(uv)], uv, sigma)


def _corners(ladder: EdgeFields, kk: I64, uv: F64) -> tuple[F64, I64, I64, Mask]:
    """The 4 bilinear corners of each centre on each of its rungs ``kk`` (N,2), as (4, N, 2) arrays: weights
    (zero outside the image), pooled columns (clipped, wrapped if panorama) and rows, and whether the corner
    is inside."""
    f, hf, wf = ladder.factor[kk], ladder.hf[kk], ladder.wf[kk]
    x = (uv[:, 0, None] - (f - 1) / 2.0) / f
    y = (uv[:, 1, None] - (f - 1) / 2.0) / f
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    ax, ay = x - x0, y - y0
    xi = x0 + _CORNER_DX  # corners (0, 0), (1, 0), (0, 1), (1, 1)
    yi = y0 + _CORNER_DY
    if ladder.wrap_u:
        xi = np.mod(xi, wf)
    ok = (xi >= 0) & (xi < wf) & (yi >= 0) & (yi < hf)
    wx, wy = np.stack([1 - ax, ax, 1 - ax, ax]), np.stack([1 - ay, 1 - ay, ay, ay])
    return np.where(ok, wx * wy, 0.0), np.minimum(np.maximum(xi, 0), wf - 1), yi, ok


_CORNER_DX = np.array([0, 1, 0, 1])[:, None, None]
_CORNER_DY = np.array([0, 0, 1, 1])[:, None, None]


def sample_fields(fields: list[EdgeFields], sizes: list[int], uv: F64, sigma: F64) -> F64:
    """(N, 9) samples of several images' fields at once: the first ``sizes[0]`` centres ``uv`` (N,2) px with
    widths ``sigma`` (N,) px on ``fields[0]``, the next ``sizes[1]`` on ``fields[1]``, ... Bilinear in space
    (zero outside the image, wrapping u if panorama), linear in log sigma between the two nearest rungs.
    The images must share one ladder (size, sigmas, wrap): one camera and one set of options.

    Compiled (:mod:`calib.field_gather`) while every corner falls on built rows; else the bands grow first."""
    ladder = fields[0]
    if any(f.width != ladder.width or f.height != ladder.height or f.wrap_u != ladder.wrap_u
           or not np.array_equal(f.sigmas_px, ladder.sigmas_px) for f in fields):
        raise CalibError("sample_fields needs images with one ladder of rungs (same camera and options)")
    pos = ladder.rung_position(sigma)
    uv = np.ascontiguousarray(uv, dtype=np.float64)
    out = np.zeros((len(uv), 9))
    for f, end, n in zip(fields, np.cumsum(sizes), sizes, strict=True):
        part = slice(int(end) - n, int(end))
        if n and not gather(uv[part], pos[part], ladder.factor, ladder.hf, ladder.wf, ladder.cb, ladder.bw,
                            f.row0, f.rows, f.offset, f.flat, f.wrap_u, out[part]):
            return _sample_growing(fields, sizes, uv, pos)
    return out


def _sample_growing(fields: list[EdgeFields], sizes: list[int], uv: F64, pos: F64) -> F64:
    """:func:`sample_fields` at rung positions ``pos`` (N,), growing the bands its corners need first (numpy:
    the same arithmetic as :mod:`calib.field_gather`)."""
    ladder = fields[0]
    n_rungs, n_blocks = ladder.rows.shape
    k0 = np.floor(pos).astype(np.int64)
    t = pos - k0
    kk = np.stack([k0, np.minimum(k0 + 1, n_rungs - 1)], axis=1)  # (N, 2): the rungs below and above
    weights, x_all, y_all, ok_all = _corners(ladder, kk, uv)  # (4, N, 2)
    owner = np.repeat(np.arange(len(fields)), sizes)
    block = x_all // ladder.cb[kk]
    key = (owner[:, None] * n_rungs + kk) * n_blocks + block  # (4, N, 2): image, rung, column block
    row0, rows = _built_rows(fields, key)
    if np.any(ok_all & ((rows == 0) | (y_all < row0) | (y_all >= row0 + rows))):
        _grow(fields, key, y_all, ok_all)
        row0, rows = _built_rows(fields, key)
    offset = np.concatenate([f.offset.ravel() for f in fields])[key]
    bw = ladder.bw.ravel()[kk * n_blocks + block]
    row_in_block = np.minimum(np.maximum(y_all - row0, 0), np.maximum(rows - 1, 0))  # np.clip, faster on ints
    cells = offset + row_in_block * bw + x_all - block * ladder.cb[kk]
    vals = np.zeros((4, len(uv), 2, 9), np.float32)
    ends = np.cumsum(sizes)
    for f, end, n in zip(fields, ends, sizes, strict=True):
        if n and len(f.flat):
            np.take(f.flat, cells[:, end - n:end], axis=0, out=vals[:, end - n:end], mode="clip")
    both = np.zeros((len(uv), 2, 9))  # bilinear on the rung below and the one above
    for c in range(4):
        both += weights[c][:, :, None] * vals[c]
    return np.asarray((1.0 - t[:, None]) * both[:, 0] + t[:, None] * both[:, 1], dtype=np.float64)


def _built_rows(fields: list[EdgeFields], key: I64) -> tuple[I64, I64]:
    """First built pooled row and number of built rows of the block each corner ``key`` falls in."""
    return (np.concatenate([f.row0.ravel() for f in fields])[key],
            np.concatenate([f.rows.ravel() for f in fields])[key])


def _grow(fields: list[EdgeFields], key: I64, y_all: I64, ok_all: Mask) -> None:
    """Build the rows the inside corners (pooled rows ``y_all``, blocks ``key``) need and no block has."""
    n_rungs, n_blocks = fields[0].rows.shape
    need_lo = np.full(len(fields) * n_rungs * n_blocks, np.iinfo(np.int64).max)
    need_hi = np.full(len(fields) * n_rungs * n_blocks, -1)
    np.minimum.at(need_lo, key[ok_all], y_all[ok_all])
    np.maximum.at(need_hi, key[ok_all], y_all[ok_all] + 1)
    shape = (len(fields), n_rungs, n_blocks)
    lo_p, hi_p = need_lo.reshape(shape), need_hi.reshape(shape)
    built0, built = np.stack([f.row0 for f in fields]), np.stack([f.rows for f in fields])
    short = (hi_p > lo_p) & ((built == 0) | (lo_p < built0) | (hi_p > built0 + built))
    for p in np.flatnonzero(short.any(axis=(1, 2))):
        fields[p].grow(lo_p[p], hi_p[p])
