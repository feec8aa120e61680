"""The speed-ups of issue 12 keep the numbers: fields built lazily in row bands equal whole-image fields, the
batched per-pair cost equals the pair-by-pair one, the one-FFT L0 iteration equals the textbook one."""

import dataclasses

import cv2
import numpy as np
import pytest
import scipy.fft

from calib.edges_image import l0_smooth
from calib.field_gather import gather
from calib.fields import RUNGS_PER_OCTAVE, EdgeFields, _kernels, _sample_growing, sample_fields
from calib.gmm import Evaluator, GmmOptions, freeze, pair_terms
from tests.calib.synthetic import TRUTH, make_pair


@pytest.fixture(scope="module")
def pair():
    return make_pair(3, evaluator_fields=False)


def _fresh(pair) -> EdgeFields:
    cam = pair.camera
    return EdgeFields.build(pair.pixels.uv, pair.pixels.score, cam.width, cam.height, wrap_u=True, sigma_min=0.7,
                            sigma_max=48.0)


def _whole(pair) -> EdgeFields:
    """Every rung built over every row at once, as before the bands existed."""
    fields = _fresh(pair)
    every_row = np.broadcast_to(fields.hf[:, None], fields.rows.shape)
    fields.grow(np.zeros_like(fields.rows), every_row.copy())
    assert np.array_equal(fields.rows[fields.bw > 0], every_row[fields.bw > 0])
    return fields


def _whole_map(fields: EdgeFields, k: int) -> np.ndarray:
    """Rung k over the whole image as before issue 12: the pooled maps padded with zero rows and wrapped
    columns, filtered at once. (Hf, Wf, 9)."""
    f = int(fields.factor[k])
    kernels = _kernels(float(fields.sigmas_px[k]), f)
    r = kernels.shape[1] // 2
    out = []
    score_map, mask_map = _full_resolution_splat(fields)
    for i, m in enumerate([score_map] * 3 + [mask_map] * 6):
        pooled = _pool(m, f)
        pad = np.pad(np.pad(pooled, ((r, r), (0, 0))), ((0, 0), (r, r)), mode="wrap")
        out.append(cv2.filter2D(pad, cv2.CV_64F, kernels[i], borderType=cv2.BORDER_CONSTANT)[r:-r, r:-r])
    return np.stack(out, axis=-1)


def _full_resolution_splat(fields: EdgeFields) -> tuple[np.ndarray, np.ndarray]:
    """Score and mask maps (H,W): each edge pixel's score and unit mass split bilinearly over 4 pixels."""
    score_map, mask_map = np.zeros((fields.height, fields.width)), np.zeros((fields.height, fields.width))
    u0, v0 = np.floor(fields.uv).astype(int).T
    au, av = (fields.uv - np.floor(fields.uv)).T
    for du, dv, wgt in ((0, 0, (1 - au) * (1 - av)), (1, 0, au * (1 - av)), (0, 1, (1 - au) * av), (1, 1, au * av)):
        cols, rows = np.mod(u0 + du, fields.width), v0 + dv
        ok = (rows >= 0) & (rows < fields.height)
        np.add.at(score_map, (rows[ok], cols[ok]), (fields.score * wgt)[ok])
        np.add.at(mask_map, (rows[ok], cols[ok]), wgt[ok])
    return score_map, mask_map


def _pool(image: np.ndarray, f: int) -> np.ndarray:
    """Sums over f x f cells (the last row and column of cells padded with zeros)."""
    h, w = image.shape
    padded = np.zeros((-(-h // f) * f, -(-w // f) * f))
    padded[:h, :w] = image
    return padded.reshape(padded.shape[0] // f, f, padded.shape[1] // f, f).sum(axis=(1, 3))


def test_pooled_splat_equals_the_full_resolution_splat_pooled(pair):
    fields = _fresh(pair)
    full = _full_resolution_splat(fields)
    for f in (1, 2, 4, 8, 16):
        got = fields._splat(f)
        for g, expected in zip(got, full, strict=True):
            assert g.shape == (-(-expected.shape[0] // f), -(-expected.shape[1] // f))
            np.testing.assert_allclose(g, _pool(expected, f), rtol=1e-12, atol=1e-12)


def test_blocks_hold_the_whole_image_maps(pair):
    fields = _fresh(pair)
    fields.sample(*_centres(pair, (100.0, 140.0), 400, 9))
    fields.sample(*_centres(pair, (30.0, 60.0), 100, 10))  # grows some blocks upwards
    checked = 0
    for k in np.flatnonzero(fields.rows.sum(axis=1)):
        whole = _whole_map(fields, int(k))
        for b in np.flatnonzero(fields.rows[k]):
            r0, c0 = int(fields.row0[k, b]), b * int(fields.cb[k])
            expected = whole[r0:r0 + int(fields.rows[k, b]), c0:c0 + int(fields.bw[k, b])]
            got = fields._block(int(k), int(b))
            assert np.abs(got - expected).max() <= 1e-6 * np.abs(whole).max() + 1e-12, (k, b)
            checked += 1
    assert checked > 20


def _centres(pair, rows: tuple[float, float], n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres near edge pixels within image rows ``rows``, with widths over the whole ladder."""
    rng = np.random.default_rng(seed)
    uv = pair.pixels.uv[rng.integers(0, len(pair.pixels.uv), n)] + rng.normal(0.0, 4.0, (n, 2))
    uv[:, 1] = rng.uniform(*rows, n)
    sigma = np.exp(rng.uniform(np.log(0.7), np.log(48.0), n))
    return uv, sigma


def test_band_built_on_demand_equals_whole_image_maps(pair):
    whole, lazy = _whole(pair), _fresh(pair)
    for rows, seed in (((100.0, 140.0), 0), ((10.0, 30.0), 1), ((200.0, 255.0), 2), ((100.0, 140.0), 3)):
        uv, sigma = _centres(pair, rows, 400, seed)
        expected, got = whole.sample(uv, sigma), lazy.sample(uv, sigma)
        scale = np.abs(expected).max(axis=0)
        # cv2.filter2D switches to a DFT for wide kernels, so a band and the whole map can differ in rounding.
        assert np.all(np.abs(got - expected) <= 1e-9 * scale), np.abs(got - expected).max(axis=0) / scale
        if seed == 0:  # one band of rows: the rest of the image was not filtered
            assert 0 < lazy.nbytes < 0.5 * whole.nbytes


def test_samples_do_not_change_when_the_band_grows(pair):
    fields = _fresh(pair)
    uv, sigma = _centres(pair, (120.0, 130.0), 300, 4)
    before = fields.sample(uv, sigma)
    fields.sample(*_centres(pair, (0.0, 255.0), 300, 5))  # grows every band it touches to the whole image
    np.testing.assert_allclose(fields.sample(uv, sigma), before, rtol=0, atol=1e-9 * np.abs(before).max())


def test_several_images_sampled_at_once_equal_each_alone(pair):
    other = make_pair(4, evaluator_fields=False)
    fa, fb = _fresh(pair), _fresh(other)
    uv_a, s_a = _centres(pair, (90.0, 160.0), 200, 6)
    uv_b, s_b = _centres(other, (90.0, 160.0), 150, 7)
    both = sample_fields([fa, fb], [200, 150], np.concatenate([uv_a, uv_b]), np.concatenate([s_a, s_b]))
    np.testing.assert_array_equal(both[:200], _fresh(pair).sample(uv_a, s_a))
    np.testing.assert_array_equal(both[200:], _fresh(other).sample(uv_b, s_b))


@pytest.mark.parametrize("evaluator", [Evaluator.EXACT, Evaluator.FIELD])
def test_pairs_batched_equal_pair_by_pair(evaluator):
    feats = [make_pair(5), make_pair(6)]
    opts = dataclasses.replace(GmmOptions(), evaluator=evaluator)
    tau = TRUTH.tau + np.array([0.01, -0.02, 0.015, 0.03, -0.02, 0.01])
    sigma_in = [12.0, 9.0]  # different per pair: each point must get its own pair's kernel height
    frozen = [freeze(f, tau, s, opts) for f, s in zip(feats, sigma_in, strict=True)]
    batched = pair_terms(feats, frozen, tau, sigma_in, opts)
    for f, z, s, got in zip(feats, frozen, sigma_in, batched, strict=True):
        alone = pair_terms([f], [z], tau, [s], opts)[0]
        assert got.index.size > 100
        np.testing.assert_array_equal(got.index, alone.index)
        np.testing.assert_allclose(got.value, alone.value, rtol=1e-12, atol=0)
        np.testing.assert_allclose(got.d_pcam, alone.d_pcam, rtol=1e-12, atol=1e-15)


def _l0_textbook(grey, lam, kappa=2.0, beta_max=1e5):
    """Xu et al.'s solver as printed: both gradient images through the FFT and the conjugate OTFs."""
    h, w = grey.shape
    fx, fy = np.zeros((h, w)), np.zeros((h, w))
    fx[0, 0], fx[0, -1] = -1.0, 1.0
    fy[0, 0], fy[-1, 0] = -1.0, 1.0
    otf_x, otf_y = scipy.fft.rfft2(fx), scipy.fft.rfft2(fy)
    denom = np.abs(otf_x) ** 2 + np.abs(otf_y) ** 2
    f_image, smooth, beta = scipy.fft.rfft2(grey), grey.copy(), 2.0 * lam
    while beta < beta_max:
        gx = np.roll(smooth, -1, axis=1) - smooth
        gy = np.roll(smooth, -1, axis=0) - smooth
        flat = gx * gx + gy * gy < lam / beta
        gx[flat], gy[flat] = 0.0, 0.0
        numer = f_image + beta * (np.conj(otf_x) * scipy.fft.rfft2(gx) + np.conj(otf_y) * scipy.fft.rfft2(gy))
        smooth = scipy.fft.irfft2(numer / (1.0 + beta * denom), s=(h, w))
        beta *= kappa
    return smooth


def test_l0_smoothing_equals_the_textbook_solver():
    rng = np.random.default_rng(8)
    grey = np.zeros((48, 64))
    grey[10:30, 20:50] = 0.8
    grey[35:, :15] = 0.4
    grey += rng.normal(0.0, 0.02, grey.shape)
    got, expected = l0_smooth(grey, 0.01), _l0_textbook(grey, 0.01)
    assert np.abs(got - expected).max() < 1e-5  # float32 solver against float64: far below a grey level (1/255)
    assert np.abs(np.diff(got, axis=1)).max() > 0.3  # it is a real edge-keeping smoothing, not a copy


def test_samples_do_not_depend_on_what_was_sampled_before(pair):
    # Ladders asked for the same centres after different histories give bit-identical samples, so a
    # calibration's result cannot depend on the trials that ran before it in the same process.
    uv, sigma = _centres(pair, (100.0, 200.0), 300, 6)
    fresh, used = _fresh(pair), _fresh(pair)
    used.sample(*_centres(pair, (0.0, 120.0), 300, 7))
    assert np.array_equal(used.sample(uv, sigma), fresh.sample(uv, sigma))


def test_compiled_gather_equals_the_numpy_path_bit_for_bit(pair):
    """calib.field_gather samples built bands with the numpy path's arithmetic in its order: the same bits."""
    fields = _fresh(pair)
    uv, sigma = _centres(pair, (20.0, 230.0), 500, 11)
    uv[:20, 0] = np.linspace(-3.0, 3.0, 20)  # across the seam
    grown = fields.sample(uv, sigma)  # the numpy path: it grows the bands first
    pos = np.clip(np.log2(sigma / fields.sigmas_px[0]) * RUNGS_PER_OCTAVE, 0.0, fields.rows.shape[0] - 1.000001)
    out = np.zeros((len(uv), 9))
    assert gather(uv, pos, fields.factor, fields.hf, fields.wf, fields.cb, fields.bw, fields.row0, fields.rows,
                  fields.offset, fields.flat, fields.wrap_u, out)
    np.testing.assert_array_equal(out, grown)
    np.testing.assert_array_equal(_sample_growing([fields], [len(uv)], uv, pos), grown)


def test_compiled_gather_asks_for_growth_on_an_unbuilt_row(pair):
    fields = _fresh(pair)
    fields.sample(*_centres(pair, (120.0, 130.0), 50, 12))
    uv = np.array([[100.0, 10.0]])  # a row no sample has reached
    out = np.zeros((1, 9))
    pos = np.zeros(1)
    assert not gather(uv, pos, fields.factor, fields.hf, fields.wf, fields.cb, fields.bw, fields.row0,
                      fields.rows, fields.offset, fields.flat, fields.wrap_u, out)
    fields.sample(uv, np.full(1, fields.sigmas_px[0]))  # grows that row's blocks, then samples
    assert gather(uv, pos, fields.factor, fields.hf, fields.wf, fields.cb, fields.bw, fields.row0,
                  fields.rows, fields.offset, fields.flat, fields.wrap_u, out)
