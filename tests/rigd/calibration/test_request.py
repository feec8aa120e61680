"""rigd.calibration.request: the sensors' uncertainties a request is judged with when rig.yaml declares none."""

import numpy as np

from rigd.calibration.request import elevation_sigma_deg
from rigd.dataset import Cloud, open_dataset, write_pair, write_rig
from rigd.dataset.records import MODEL_ELEVATION_SIGMA_DEG, RigConfig

CAMERA = {"model": "equirectangular", "width": 64, "height": 32}


def _dataset(root, spacing_deg: float, lidar: dict) -> None:
    """One pair whose cloud has rings ``spacing_deg`` apart (8 rings, 90 points each)."""
    write_rig(root, RigConfig.from_yaml({"camera": CAMERA, "lidar": lidar}, "rig.yaml"))
    elevation = np.radians(np.repeat(np.arange(8) * spacing_deg - 7.0, 90))
    azimuth = np.radians(np.tile(np.arange(90) * 4.0, 8))
    points = 10.0 * np.column_stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                                     np.sin(elevation)])
    write_pair(root, 0, np.zeros((32, 64, 3), np.uint8), Cloud(points, None, np.repeat(np.arange(8), 90)), {})


def test_a_sparse_lidar_without_a_declared_elevation_sigma_takes_the_vlp16s(tmp_path):
    """Rings 2 deg apart (a thinned 64-ring LiDAR, undeclared): the VLP-16's sigma; 0.4 deg apart: none; declared,
    as declared (a simulator's 0 included)."""
    vlp16 = MODEL_ELEVATION_SIGMA_DEG["VLP-16"]
    for name, spacing, lidar, expected in (("sparse", 2.0, {"model": "HDL-64E (thinned)"}, vlp16),
                                           ("dense", 0.4, {"model": "HDL-64E"}, 0.0),
                                           ("declared", 2.0, {"model": "sim", "elevation_offset_sigma_deg": 0.0}, 0.0),
                                           ("vlp16", 0.4, {"model": "VLP-16"}, vlp16)):
        _dataset(tmp_path / name, spacing, lidar)
        assert elevation_sigma_deg(open_dataset(tmp_path / name)) == expected, name
