"""calib.pipeline: the schedule keeps fold edges on every level when the cameras see few occlusion edges."""

import dataclasses

import numpy as np

from calib.camera import Pinhole
from calib.pipeline import CalibParams, schedule
from tests.calib.synthetic import TRUTH, make_pair


def test_occlusion_edges_are_counted_where_the_camera_sees_them():
    params = CalibParams()
    panorama = make_pair(0)  # 2400 occlusion edge points, every one in the panorama
    assert len(panorama.points) >= 2 * params.min_boundary_points
    assert schedule([panorama], params, TRUTH.tau).fold_levels == params.optim.fold_levels
    # The same cloud before a narrow pinhole (100 px at f = 2000 px: 2.9 deg) sees almost none of them.
    narrow = Pinhole(np.array([[2000.0, 0.0, 49.5], [0.0, 2000.0, 49.5], [0.0, 0.0, 1.0]]), np.zeros(5), 100, 100)
    pinhole = dataclasses.replace(panorama, camera=narrow, fields=None, pixel_grid=None)
    assert schedule([pinhole], params, TRUTH.tau).fold_levels == len(params.optim.sigmas_deg)
