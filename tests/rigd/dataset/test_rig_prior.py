"""rig.yaml's prior, tolerance and principal-point sections: read, written back, used, refused by name."""

import numpy as np
import pytest
import yaml

from calib.assess import TrustOptions
from rigd.calibration.request import CalibrationRequest, with_camera_model
from rigd.dataset import Cloud, open_dataset, write_pair, write_rig
from rigd.dataset.records import RigConfig
from rigd.errors import DatasetError
from rigd.evaluate.trials import EvaluationSettings, open_for

CAMERA = {"model": "equirectangular", "width": 64, "height": 32}


def test_prior_and_tolerance_round_trip(tmp_path):
    data = {"camera": CAMERA, "prior": {"xyz_m": [0.1, 0.05, -0.17], "sigma_cm": 1.0, "rpy_deg": [0, 15, -55],
                                        "sigma_deg": [2, 2, 5]},
            "tolerance": {"rotation_deg": 0.3, "translation_cm": 3}}
    rig = RigConfig.from_yaml(data, "rig.yaml")
    assert np.allclose(rig.prior.xyz_m, [0.1, 0.05, -0.17]) and np.allclose(rig.prior.sigma_xyz_m, 0.01)
    assert np.allclose(np.degrees(rig.prior.sigma_rot_rad), [2, 2, 5])
    assert rig.tolerance.tolerance_rot_deg == 0.3 and rig.tolerance.tolerance_trans_cm == 3.0
    (tmp_path / "pairs").mkdir()
    write_rig(tmp_path, rig)
    again = open_dataset(tmp_path).rig
    assert np.allclose(again.prior.xyz_m, rig.prior.xyz_m) and np.allclose(again.prior.rotation, rig.prior.rotation)
    assert again.tolerance == rig.tolerance
    assert yaml.safe_load((tmp_path / "rig.yaml").read_text())["prior"]["sigma_cm"] == [1.0, 1.0, 1.0]


@pytest.mark.parametrize("prior, words", [
    ({"xyz_m": [0, 0, 0]}, "sigma_cm"),
    ({"xyz_m": [0, 0], "sigma_cm": 1}, "xyz_m"),
    ({"xyz_m": [0, 0, 0], "sigma_cm": -1}, "positive"),
    ({"rpy_deg": [0, 0, 0]}, "rotation"),
    ({"lever": [0, 0, 0]}, "unknown prior keys"),
    ({"xyz_m": [9.34, 6.24, -15.68], "sigma_cm": 1}, "more than the 5 m any rig has: it is in metres"),
    ([1, 2, 3], "mapping"),
])
def test_bad_prior_names_the_file_and_the_problem(prior, words):
    with pytest.raises(DatasetError, match=words) as info:
        RigConfig.from_yaml({"camera": CAMERA, "prior": prior}, "/etc/rigd/rig.yaml")
    assert "/etc/rigd/rig.yaml" in str(info.value)


def test_fixed_translation_needs_no_sigma():
    rig = RigConfig.from_yaml({"camera": CAMERA, "prior": {"xyz_m": [0.1, 0, 0], "fix_translation": True}}, "r")
    assert rig.prior.fix_translation and rig.prior.sigma_xyz_m is None


@pytest.mark.parametrize("tolerance", [{"rotation_deg": 0}, {"translation_cm": "x"}, {"angle": 1}])
def test_bad_tolerance_is_refused(tolerance):
    with pytest.raises(DatasetError, match="tolerance"):
        RigConfig.from_yaml({"camera": CAMERA, "tolerance": tolerance}, "r")


@pytest.mark.parametrize("tolerance, words", [
    ({"rotation_deg": 1e-300}, "rotation_deg must be within 0.001 .. 10 deg, got 1e-300"),
    ({"rotation_deg": 11}, "rotation_deg must be within 0.001 .. 10 deg, got 11"),
    ({"rotation_deg": float("nan")}, "rotation_deg must be within 0.001 .. 10 deg, got nan"),
    ({"translation_cm": 1e-300}, "translation_cm must be within 0.01 .. 100 cm, got 1e-300"),
    ({"translation_cm": float("inf")}, "translation_cm must be within 0.01 .. 100 cm, got inf"),
])
def test_tolerance_out_of_range_names_rig_yaml_and_the_range(tmp_path, tolerance, words):
    """A tolerance the sensors cannot resolve (1e-300 crashed the verdict's arithmetic) is refused on opening."""
    (tmp_path / "pairs").mkdir()
    (tmp_path / "rig.yaml").write_text(yaml.safe_dump({"camera": CAMERA, "tolerance": tolerance}))
    with pytest.raises(DatasetError, match=words) as info:
        open_dataset(tmp_path)
    assert str(tmp_path / "rig.yaml") in str(info.value)


def test_tolerance_bounds_are_accepted():
    for rot, trans in ((0.001, 0.01), (10.0, 100.0)):
        rig = RigConfig.from_yaml({"camera": CAMERA, "tolerance": {"rotation_deg": rot, "translation_cm": trans}}, "r")
        assert (rig.tolerance.tolerance_rot_deg, rig.tolerance.tolerance_trans_cm) == (rot, trans)


def test_a_declared_principal_point_sigma_is_read_written_back_and_bounded(tmp_path):
    camera = {"model": "pinhole", "width": 640, "height": 480, "K": [[500.0, 0, 320], [0, 250.0, 240], [0, 0, 1]],
              "D": [], "principal_point_sigma_px": 1.5}
    rig = RigConfig.from_yaml({"camera": camera}, "rig.yaml")
    assert rig.camera.intrinsics_sigma_rad() == pytest.approx((1.5 / 250.0, 1.5 / 500.0))  # about x: rows, y: columns
    (tmp_path / "pairs").mkdir()
    write_rig(tmp_path, rig)
    assert open_dataset(tmp_path).rig.camera.principal_point_sigma_px == 1.5
    assert RigConfig.from_yaml({"camera": {**camera, "principal_point_sigma_px": None}}, "rig.yaml") \
        .camera.intrinsics_sigma_rad() == (0.0, 0.0)
    with pytest.raises(DatasetError, match="principal_point_sigma_px must be 0 .. 100 px"):
        RigConfig.from_yaml({"camera": {**camera, "principal_point_sigma_px": -1}}, "rig.yaml")


def test_the_calibration_and_its_evaluation_judge_a_single_camera_with_its_principal_point(tmp_path):
    """rigd calibrate and rigd evaluate both carry rig.yaml's principal-point sigma into the verdict's options; a
    panorama (no K) stays K-exact."""
    camera = {"model": "pinhole", "width": 640, "height": 480, "K": [[500.0, 0, 320], [0, 250.0, 240], [0, 0, 1]],
              "D": [], "principal_point_sigma_px": 2.0}
    for name, cam, expected in (("pin", camera, (2.0 / 250.0, 2.0 / 500.0)), ("pano", CAMERA, (0.0, 0.0))):
        root = tmp_path / name
        write_rig(root, RigConfig.from_yaml({"camera": cam}, "rig.yaml"))
        size = (cam["height"], cam["width"], 3)
        write_pair(root, 0, np.zeros(size, np.uint8), Cloud(np.array([[10.0, 0.0, 0.0]])), {})
        trust = with_camera_model(TrustOptions(), open_dataset(root))
        assert trust.intrinsics_sigma_rad == pytest.approx(expected)
        assert open_for(EvaluationSettings(CalibrationRequest(dataset=root)))[1].solve.trust == trust


def test_a_declared_lidar_elevation_offset_raises_every_loaded_point_and_is_bounded(tmp_path):
    lidar = {"model": "VLP-16", "elevation_offset_deg": 0.3, "elevation_offset_sigma_deg": 0.05}
    write_rig(tmp_path, RigConfig.from_yaml({"camera": CAMERA, "lidar": lidar}, "rig.yaml"))
    points = np.array([[10.0, 0.0, 0.0], [0.0, 5.0, -1.0]])
    write_pair(tmp_path, 0, np.zeros((32, 64, 3), np.uint8), Cloud(points), {})
    dataset = open_dataset(tmp_path)
    assert dataset.rig.lidar_elevation_offset_deg == 0.3 and dataset.rig.lidar_elevation_sigma_deg == 0.05
    assert with_camera_model(TrustOptions(), dataset).elevation_sigma_deg == 0.05  # the verdict's, as calibrate runs
    evaluated = open_for(EvaluationSettings(CalibrationRequest(dataset=tmp_path)))[1].solve.trust
    assert evaluated is not None and evaluated.elevation_sigma_deg == 0.05  # and evaluate
    loaded = dataset.load_pair(0).cloud.points_lidar
    elevation = np.degrees(np.arctan2(loaded[:, 2], np.hypot(loaded[:, 0], loaded[:, 1])))
    assert elevation == pytest.approx(np.degrees(np.arctan2([0.0, -1.0], [10.0, 5.0])) + 0.3)
    assert "elevation_offset_deg" not in RigConfig.from_yaml({"camera": CAMERA}, "rig.yaml").to_yaml()["lidar"]
    with pytest.raises(DatasetError, match=r"elevation_offset_deg must be within \+-2 deg, got 5"):
        RigConfig.from_yaml({"camera": CAMERA, "lidar": {"elevation_offset_deg": 5}}, "rig.yaml")
