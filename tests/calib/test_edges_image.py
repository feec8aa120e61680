"""Image edges (paper 4.1) and the texture suppression that keeps silhouettes rather than texture."""

from __future__ import annotations

import numpy as np
import pytest

from calib.edges_image import ImageEdgeParams, edge_line_density, image_edge_pixels
from calib.errors import CalibError


def test_the_texture_radius_is_an_angle_with_a_floor_in_pixels() -> None:
    params = ImageEdgeParams()
    assert params.texture_radius_px(2115.0) == 11  # the pinhole sample: 37 px per degree
    assert params.texture_radius_px(1024 / (2 * np.pi)) == 3  # a 1024-wide panorama: 0.85 px, floored
    assert ImageEdgeParams(texture_radius_deg=0.0).texture_radius_px(2115.0) == 0


def _line_mask(h: int = 80, w: int = 120) -> np.ndarray:
    mask = np.zeros((h, w), bool)
    mask[:, 60] = True
    return mask


def test_an_isolated_straight_line_counts_as_one_line() -> None:
    density = edge_line_density(_line_mask(), 10, wrap_u=False)
    assert density[40, 60] == pytest.approx(1.0)
    assert density[40, 65] < 1.0  # off the line the chord is shorter
    assert density[40, 75] == pytest.approx(0.0, abs=1e-6)  # beyond the radius


def test_dense_parallel_lines_count_as_many() -> None:
    mask = np.zeros((80, 120), bool)
    mask[:, 40:80:4] = True  # 10 lines 4 px apart: a grille, i.e. texture at this scale
    assert edge_line_density(mask, 10, wrap_u=False)[40, 60] > 4.0


def test_the_panorama_wraps_across_u_zero() -> None:
    mask = np.zeros((80, 120), bool)
    mask[:, [118, 119, 0, 1, 2]] = True  # five lines straddling the seam
    wrapped = edge_line_density(mask, 10, wrap_u=True)
    flat = edge_line_density(mask, 10, wrap_u=False)
    shifted = edge_line_density(np.roll(mask, 60, axis=1), 10, wrap_u=False)
    assert wrapped[40, 0] == pytest.approx(shifted[40, 60])  # as if the lines stood mid-image
    assert flat[40, 0] < wrapped[40, 0]  # without the wrap the left border misses the lines beyond it


def _silhouette_and_texture() -> np.ndarray:
    """A bright box on a grey background (a silhouette) and a fine checkerboard patch (texture)."""
    img = np.full((200, 300), 90, np.uint8)
    img[40:160, 30:110] = 200
    yy, xx = np.mgrid[0:120, 0:100]
    img[40:160, 170:270] = np.where(((yy // 3) + (xx // 3)) % 2 == 0, 40, 220)
    return img


def test_texture_is_dropped_and_silhouettes_kept() -> None:
    img = _silhouette_and_texture()
    ppr = np.degrees(10.0 / 0.3)  # 10 px per 0.3 deg, as on a 1920-wide pinhole with a 50 deg field of view
    plain = image_edge_pixels(img, ImageEdgeParams(l0_lambda=0.0, texture_radius_deg=0.0), False, ppr)
    kept = image_edge_pixels(img, ImageEdgeParams(l0_lambda=0.0), False, ppr)

    def inside_texture(uv: np.ndarray) -> np.ndarray:
        return (uv[:, 0] > 175) & (uv[:, 0] < 265) & (uv[:, 1] > 45) & (uv[:, 1] < 155)

    def on_box(uv: np.ndarray) -> np.ndarray:
        return (uv[:, 0] < 140) & (uv[:, 1] > 30) & (uv[:, 1] < 170)

    assert inside_texture(plain.uv).sum() > 500  # without suppression the checkerboard is all edges
    assert inside_texture(kept.uv).sum() == 0
    assert on_box(kept.uv).sum() == on_box(plain.uv).sum() > 300  # the box's outline is untouched


def test_edges_near_masked_pixels_are_dropped() -> None:
    # A rectified image's black surround: its border is the strongest edge of the image and no edge of the
    # scene. With the mask, only the scene's own edge (a bright bar) remains, and the bar sets the scale.
    image = np.full((120, 160), 90, np.uint8)
    image[:, :20] = 0  # outside the rectified region
    image[40:80, 80:84] = 200  # the scene's edge
    mask = np.ones(image.shape, bool)
    mask[:, :20] = False
    params = ImageEdgeParams(l0_lambda=0.0, texture_radius_deg=0.0)
    unmasked = image_edge_pixels(image, params, False, 500.0)
    masked = image_edge_pixels(image, params, False, 500.0, mask)
    assert np.any(np.abs(unmasked.uv[:, 0] - 19.5) < 1.0)
    assert masked.uv[:, 0].min() > 20 + params.mask_margin_px - 1
    assert np.any(np.abs(masked.uv[:, 0] - 79.5) < 1.0) and masked.score.max() == 1.0


def test_a_mask_of_another_size_is_an_error() -> None:
    with pytest.raises(CalibError, match="mask is 10x10"):
        image_edge_pixels(np.zeros((20, 30), np.uint8), ImageEdgeParams(), False, 500.0, np.ones((10, 10), bool))
