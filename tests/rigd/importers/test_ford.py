"""``rigd import ford``: the Ford Campus layout as a head dataset or one camera's, rings from the firing order."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calib.geometry import rotation_angle_deg
from rigd.cli import main
from rigd.cli.exit_codes import ERROR
from rigd.dataset import open_dataset
from rigd.dataset.records import HeadConfig
from rigd.dataset.reference import agreement
from rigd.errors import DatasetError
from rigd.importers.ford import PRINCIPAL_POINT_SIGMA_PX, import_ford
from rigd.importers.scan_order import rings_from_scan_order
from tests.rigd.importers.ford_tree import LASER_ELEVATIONS_DEG, laser_by_laser_cloud, write_ford_tree


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_rings_are_recovered_from_the_firing_order(seed: int) -> None:
    points, laser = laser_by_laser_cloud(seed)
    ring = rings_from_scan_order(points.astype(np.float64))
    by_elevation = np.argsort(np.argsort(LASER_ELEVATIONS_DEG))  # ring 0 is the lowest laser
    np.testing.assert_array_equal(ring, by_elevation[laser])


def test_the_head_is_imported_with_masks_rings_and_the_reference(tmp_path: Path) -> None:
    src = write_ford_tree(tmp_path / "ford")
    assert import_ford(src, tmp_path / "out") == 2
    ds = open_dataset(tmp_path / "out")
    assert isinstance(ds.rig.camera, HeadConfig) and ds.views == ("cam0", "cam1") and ds.rig.lidar_model == "HDL-64E"
    assert (tmp_path / "out/pairs/0001/images/cam1.jpg").read_bytes() == (src / "cam1/image0002.jpg").read_bytes()
    sensor = ds.rig.camera.sensors[0].camera
    assert sensor.K is not None and sensor.K[1, 1] == pytest.approx(sensor.K[0, 0] / 2)  # half the vertical focus
    assert all(m is not None and not m[:, :6].any() for m in ds.masks)
    cloud = ds.load_pair(0).cloud
    assert cloud.ring is not None and cloud.intensity is not None
    assert int(cloud.ring.max()) == len(LASER_ELEVATIONS_DEG) - 1
    assert ds.reference is not None and ds.rig.initial_guess is not None
    np.testing.assert_allclose(ds.reference.T_camera_lidar.rpy_deg[2], np.degrees(-1.5708), atol=1e-9)
    np.testing.assert_allclose(ds.reference.sigma[[2, 5]], [0.04, np.degrees(np.sqrt(3.0e-5))])
    assert rotation_angle_deg(ds.rig.initial_guess.rotation, ds.reference.T_camera_lidar.rotation) < 0.5


def test_one_camera_is_a_pinhole_dataset_whose_reference_is_the_heads(tmp_path: Path) -> None:
    src = write_ford_tree(tmp_path / "ford")
    import_ford(src, tmp_path / "head")
    import_ford(src, tmp_path / "cam1", camera="cam1", scans=[2])
    head, cam = open_dataset(tmp_path / "head"), open_dataset(tmp_path / "cam1")
    assert cam.views == ("image",) and len(cam) == 1 and cam.masks[0] is not None
    assert cam.source_camera.principal_point_sigma_px == PRINCIPAL_POINT_SIGMA_PX  # the release's K: 1 px
    assert cam.reference is not None and head.reference is not None
    # the camera's reference, read back in the head's form, is the head's reference
    np.testing.assert_allclose(agreement(cam.reference, cam.reference.T_camera_lidar).z, 0.0, atol=1e-9)
    np.testing.assert_allclose(cam.reference.source_form(cam.reference.T_camera_lidar),
                               head.reference.source_form(head.reference.T_camera_lidar), atol=1e-9)


def test_bad_sources_are_named(tmp_path: Path) -> None:
    src = write_ford_tree(tmp_path / "ford")
    with pytest.raises(DatasetError, match="no camera 'cam7'"):
        import_ford(src, tmp_path / "a", camera="cam7")
    with pytest.raises(DatasetError, match="no scan 0005"):
        import_ford(src, tmp_path / "b", scans=[1, 5])
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    with pytest.raises(DatasetError, match="not empty"):
        import_ford(src, tmp_path / "full")
    (src / "cam1" / "image0002.jpg").write_bytes(b"not a jpeg")
    with pytest.raises(DatasetError, match="image0002.jpg: not a readable"):
        import_ford(src, tmp_path / "c")
    (src / "head.yaml").write_text("cameras: {}\n")
    with pytest.raises(DatasetError, match="head.yaml: not the Ford sample's head file"):
        import_ford(src, tmp_path / "d")


def test_the_command_imports_and_reports(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write_ford_tree(tmp_path / "ford")
    assert main(["import", "ford", str(src), str(tmp_path / "out"), "--scans", "2"]) == 0
    assert "1 pairs, head" in capsys.readouterr().out
    assert main(["import", "ford", str(tmp_path / "nothing"), str(tmp_path / "out2")]) == ERROR
    assert "head.yaml: file is missing" in capsys.readouterr().err
