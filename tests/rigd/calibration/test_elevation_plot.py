"""rigd.calibration.elevation_plot: the fitted elevation offset's profile as a picture."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from calib.elevation import ElevationFit
from rigd.calibration.elevation_plot import plot_elevation_profile

BAND_BGR = [243, 234, 221]  # the sigma band: tab:blue at 15 % over white


@pytest.mark.parametrize("offset_deg, side", [(0.3, "right"), (-0.3, "left")])
def test_the_sigma_band_is_drawn_where_the_offset_lies(tmp_path, offset_deg, side):
    grid = (-0.5, -0.25, 0.0, 0.25, 0.5)
    costs = tuple(10.0 * (g - offset_deg) ** 2 - 5.0 for g in grid)
    plot_elevation_profile(tmp_path / "p.png", ElevationFit(offset_deg, 0.05, np.zeros(6), grid, costs, False))
    image = cv2.imread(str(tmp_path / "p.png"))
    assert image is not None and image.shape[:2] == (506, 770)  # 7 x 4.6 in at 110 dpi
    band = np.flatnonzero((np.all(np.abs(image.astype(int) - BAND_BGR) < 6, axis=2)).sum(axis=0) > 100)
    assert band.size > 0
    middle = image.shape[1] / 2
    assert (band.min() > middle) if side == "right" else (band.max() < middle)
