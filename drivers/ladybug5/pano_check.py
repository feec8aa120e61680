"""How another panorama of the same frame (FLIR's renderer, an exported panorama) is oriented against rigd's.

rigd's panoramas follow docs/conventions.md (``u = w (pi - theta) / 2 pi``, ``v = h phi / pi``: camera 0's axis at
the centre column, left of it to the left, up at the top). FLIR documents its panorama as camera 0 in front and
camera 5 at the pole by default (``LADYBUG_FRONT_0_POLE_5``) with theta from -pi (right) to +pi (left) and phi from
0 (up) to pi (down) (ladybuggeom.h), which is the same; :func:`panorama_alignment` measures it on real images instead
of trusting it: over every turn about the vertical, mirrored or not, upside down or not, the one whose edges agree
best with rigd's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import Ladybug5Error

CHECK_WIDTH = 720  # both panoramas are compared at 720 x 360 (half a degree a column)


@dataclass(frozen=True)
class PanoramaAlignment:
    """``yaw_deg``: rigd's azimuth theta (deg, x forward, y left) at the other panorama's centre column (0: the same
    front); ``mirrored``: theta runs the other way; ``upside_down``: phi does; ``score``: the edges' normalised
    correlation at that alignment (1: identical; compare with ``runner_up``, the best of the other orientations)."""

    yaw_deg: float
    mirrored: bool
    upside_down: bool
    score: float
    runner_up: float

    @property
    def same_convention(self) -> bool:
        """Rigd's convention: no turn (under 0.25 deg, half a compared column), neither mirrored nor upside down."""
        return abs(self.yaw_deg) < 180.0 / CHECK_WIDTH and not self.mirrored and not self.upside_down


def _grey(panorama: NDArray[Any]) -> NDArray[np.float64]:
    """(360, 720) grey of a panorama (any size, grey or BGR, 8 or 16 bit)."""
    if panorama.ndim != 2 and not (panorama.ndim == 3 and panorama.shape[2] in (3, 4)):
        raise Ladybug5Error(f"not a panorama image: shape {panorama.shape}")
    grey = (panorama if panorama.ndim == 2 else cv2.cvtColor(panorama[..., :3], cv2.COLOR_BGR2GRAY)).astype(np.float32)
    scale = panorama.shape[1] / CHECK_WIDTH
    if scale > 1:  # smoothed before sampling, as an area average would, without moving it
        grey = np.asarray(cv2.GaussianBlur(grey, (0, 0), sigmaX=0.5 * scale), np.float32)
    # sampled where the convention puts the columns and rows (u = j, v = i), not at cv2.resize's pixel centres
    columns = np.arange(CHECK_WIDTH, dtype=np.float32) * scale
    rows = np.arange(CHECK_WIDTH // 2, dtype=np.float32) * scale
    map_x, map_y = np.meshgrid(columns, rows)
    return np.asarray(cv2.remap(grey, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP), np.float64)


def _gradients(grey: NDArray[np.float64]) -> NDArray[np.float64]:
    """(2, H, W) signed column and row gradients (signed: a mirror image's do not match the original's)."""
    gx = np.roll(grey, -1, axis=1) - np.roll(grey, 1, axis=1)  # the columns wrap round
    gy = np.gradient(grey, axis=0)
    return np.stack([gx, gy])


def _best_shift(reference: NDArray[np.float64], other: NDArray[np.float64]) -> tuple[float, float]:
    """The column roll s of ``reference`` (np.roll(reference, s, axis=-1)) most like ``other`` (both (2, H, W)),
    to a fraction of a column (the parabola through the peak and its neighbours), and their normalised
    correlation there."""
    spectrum = np.fft.rfft(other, axis=-1) * np.conj(np.fft.rfft(reference, axis=-1))
    correlation = np.fft.irfft(spectrum.sum(axis=(0, 1)), n=reference.shape[-1])
    norm = float(np.linalg.norm(reference) * np.linalg.norm(other)) or 1.0
    peak = int(np.argmax(correlation))
    left, centre, right = (float(correlation[(peak + k) % len(correlation)]) for k in (-1, 0, 1))
    curvature = left - 2.0 * centre + right
    offset = 0.5 * (left - right) / curvature if curvature < 0 else 0.0
    return peak + offset, centre / norm


def panorama_alignment(panorama: NDArray[Any], reference: NDArray[Any]) -> PanoramaAlignment:
    """How ``panorama`` is oriented against ``reference``, rigd's panorama of the same frame (both 2:1)."""
    for image, name in ((panorama, "panorama"), (reference, "reference")):
        if image.shape[1] != 2 * image.shape[0]:
            raise Ladybug5Error(f"the {name} is {image.shape[1]}x{image.shape[0]}, not 2:1 equirectangular")
    ref, other = _gradients(_grey(reference)), _grey(panorama)
    found = []
    for mirrored in (False, True):
        for upside_down in (False, True):
            # phi -> pi - phi is row i -> h - i, theta -> -theta column u -> w - u (row 0 is up, column w/2 ahead)
            candidate = np.roll(other[::-1], 1, axis=0) if upside_down else other
            candidate = np.roll(candidate[:, ::-1], 1, axis=1) if mirrored else candidate
            shift, score = _best_shift(ref, _gradients(np.ascontiguousarray(candidate)))
            found.append((score, shift, mirrored, upside_down))
    found.sort(reverse=True)
    score, shift, mirrored, upside_down = found[0]
    yaw = (360.0 * shift / CHECK_WIDTH + 180.0) % 360.0 - 180.0
    return PanoramaAlignment(yaw, mirrored, upside_down, score, found[1][0])
