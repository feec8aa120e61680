"""A VLP-16's per-laser vertical offsets for clouds decoded without them (rigd.dataset.lasers), rig.yaml's
``lidar.vertical_offsets``, `rigd import pairs` finding them missing, and the LiDAR model's default elevation sigma."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from calib.assess import TrustOptions
from rigd.calibration.request import with_camera_model
from rigd.cli import main
from rigd.dataset import Cloud, open_dataset, write_pair, write_pcd, write_rig
from rigd.dataset.lasers import VerticalOffsets, lacks_vertical_offsets, ring_offsets_m, with_vertical_offsets
from rigd.dataset.records import MODEL_ELEVATION_SIGMA_DEG, RigConfig
from rigd.errors import DatasetError

CAMERA = {"model": "equirectangular", "width": 64, "height": 32}
NOMINAL_DEG = np.arange(-15.0, 16.0, 2.0)  # ring 0 the lowest beam


def cone_cloud(offsets_m: np.ndarray | None = None) -> Cloud:
    """A VLP-16 sweep as a decoder writes it: each ring on its nominal cone through the origin (+ ``offsets_m`` per
    ring along z), 8 azimuths, ranges 1.5-4 m."""
    azimuth = np.radians(np.arange(0.0, 360.0, 45.0))
    points, rings = [], []
    for ring, elevation in enumerate(np.radians(NOMINAL_DEG)):
        r = np.linspace(1.5, 4.0, len(azimuth))
        z = r * np.sin(elevation) + (0.0 if offsets_m is None else offsets_m[ring])
        points.append(np.column_stack([r * np.cos(elevation) * np.cos(azimuth),
                                       r * np.cos(elevation) * np.sin(azimuth), z]))
        rings.append(np.full(len(azimuth), ring, np.int16))
    return Cloud(np.concatenate(points), None, np.concatenate(rings))


def test_a_cloud_decoded_without_offsets_is_found_and_given_the_manuals_table() -> None:
    bare = cone_cloud()
    assert lacks_vertical_offsets(bare)
    assert ring_offsets_m()[[0, 15]] == pytest.approx([0.0112, -0.0112], abs=5e-5)  # the manual's -15 / +15 deg lasers
    given = with_vertical_offsets(bare, "c.pcd")
    np.testing.assert_allclose(given.points_lidar[:, 2] - bare.points_lidar[:, 2], ring_offsets_m()[bare.ring])
    assert not lacks_vertical_offsets(given)  # decoded with them (as rigd's decoder does): left alone
    assert not lacks_vertical_offsets(Cloud(bare.points_lidar))  # no rings: nothing to say
    with pytest.raises(DatasetError, match="c.pcd: the VLP-16's vertical offsets need each point's ring .* none"):
        with_vertical_offsets(Cloud(bare.points_lidar), "c.pcd")


def test_rig_yaml_vertical_offsets_are_applied_on_load_and_checked(tmp_path: Path) -> None:
    rig = RigConfig.from_yaml({"camera": CAMERA, "lidar": {"vertical_offsets": "manual"}}, "rig.yaml")
    assert rig.lidar_vertical_offsets is VerticalOffsets.MANUAL
    assert RigConfig.from_yaml(rig.to_yaml(), "rig.yaml") == rig
    write_rig(tmp_path, rig)
    bare = cone_cloud()
    write_pair(tmp_path, 0, np.zeros((32, 64, 3), np.uint8), bare, {})
    loaded = open_dataset(tmp_path).load_pair(0).cloud
    np.testing.assert_allclose(loaded.points_lidar[:, 2] - bare.points_lidar[:, 2], ring_offsets_m()[bare.ring],
                               atol=1e-6)  # stored as float32
    with pytest.raises(DatasetError, match="manual is the VLP-16 manual's table; the LiDAR is HDL-64E"):
        RigConfig.from_yaml({"camera": CAMERA, "lidar": {"model": "HDL-64E", "vertical_offsets": "manual"}}, "r")
    with pytest.raises(DatasetError, match="vertical_offsets must be one of as-recorded, manual, got 'yes'"):
        RigConfig.from_yaml({"camera": CAMERA, "lidar": {"vertical_offsets": "yes"}}, "r")


def test_a_vlp16_without_a_declared_elevation_sigma_gets_its_models(tmp_path: Path) -> None:
    vlp16 = RigConfig.from_yaml({"camera": CAMERA}, "rig.yaml")
    assert vlp16.lidar_elevation_sigma_deg == MODEL_ELEVATION_SIGMA_DEG["VLP-16"] > 0
    assert "elevation_offset_sigma_deg" not in vlp16.to_yaml()["lidar"]  # the default is not written down
    exact = RigConfig.from_yaml({"camera": CAMERA, "lidar": {"elevation_offset_sigma_deg": 0}}, "rig.yaml")
    assert exact.lidar_elevation_sigma_deg == 0.0  # declared exact (the simulator's beams)
    assert RigConfig.from_yaml(exact.to_yaml(), "rig.yaml").lidar_elevation_sigma_deg == 0.0
    other = RigConfig.from_yaml({"camera": CAMERA, "lidar": {"model": "HDL-64E"}}, "rig.yaml")
    assert other.lidar_elevation_sigma_deg == 0.0
    write_rig(tmp_path, vlp16)
    write_pair(tmp_path, 0, np.zeros((32, 64, 3), np.uint8), Cloud(np.array([[10.0, 0.0, 0.0]])), {})
    trust = with_camera_model(TrustOptions(), open_dataset(tmp_path))
    assert trust.elevation_sigma_deg == MODEL_ELEVATION_SIGMA_DEG["VLP-16"]  # what every assessed method weighs


def _pairs_tree(root: Path) -> Path:
    (root / "images").mkdir(parents=True)
    (root / "pcd").mkdir()
    for n in (1, 2):
        cv2.imwrite(str(root / "images" / f"pose{n}.png"), np.zeros((16, 24, 3), np.uint8))
        write_pcd(root / "pcd" / f"pose{n}.pcd", cone_cloud(), compressed=False)
    info = {"distortion_model": "plumb_bob", "width": 24, "height": 16, "D": [0.0] * 5,
            "K": [20.0, 0.0, 11.5, 0.0, 20.0, 7.5, 0.0, 0.0, 1.0]}
    (root / "camera_info.yaml").write_text(yaml.safe_dump(info))
    return root


def test_import_pairs_adds_the_offsets_clouds_lack(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = _pairs_tree(tmp_path / "src")
    common = ["import", "pairs", str(src / "images"), str(src / "pcd"), "--camera-info", str(src / "camera_info.yaml")]
    assert main([*common, str(tmp_path / "auto")]) == 0
    assert "decoded without them" in capsys.readouterr().out
    assert open_dataset(tmp_path / "auto").rig.lidar_vertical_offsets is VerticalOffsets.MANUAL
    assert main([*common, str(tmp_path / "kept"), "--vertical-offsets", "as-recorded"]) == 0
    assert open_dataset(tmp_path / "kept").rig.lidar_vertical_offsets is VerticalOffsets.AS_RECORDED
    assert main([*common, str(tmp_path / "other"), "--lidar-model", "HDL-32E"]) == 0  # not a VLP-16: left alone
    assert open_dataset(tmp_path / "other").rig.lidar_vertical_offsets is VerticalOffsets.AS_RECORDED
