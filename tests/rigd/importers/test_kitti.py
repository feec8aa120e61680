"""``rigd import kitti``: a KITTI raw drive's camera as a pinhole dataset, checked against KITTI's own projection
``P_rect_0X R_rect_00 T_cam0_velo`` on a tiny drive the test writes."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from calib.camera import Pinhole
from calib.geometry import rpy_deg_to_matrix
from rigd.cli import main
from rigd.cli.exit_codes import ERROR
from rigd.dataset import open_dataset
from rigd.errors import DatasetError
from rigd.importers.kitti import import_kitti
from tests.rigd.importers.ford_tree import laser_by_laser_cloud

R_RECT = rpy_deg_to_matrix(np.array([0.4, -0.3, 0.2]))
P2 = np.array([[721.5, 0.0, 609.6, 44.86], [0.0, 721.5, 172.9, 0.2164], [0.0, 0.0, 1.0, 0.002746]])
R_VELO = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]) @ rpy_deg_to_matrix(np.array([0.5, 0.3, -0.2]))
T_VELO = np.array([-0.0041, -0.0763, -0.2718])
SIZE = (48, 16)  # w, h: a tiny stand-in for 1242 x 375


def _line(key: str, values: np.ndarray) -> str:
    return f"{key}: " + " ".join(f"{v:.12e}" for v in np.ravel(values)) + "\n"


def write_drive(root: Path, frames: int = 2) -> Path:
    date = root / "2011_09_26"
    drive = date / "2011_09_26_drive_0001_sync"
    (drive / "image_02" / "data").mkdir(parents=True)
    (drive / "velodyne_points" / "data").mkdir(parents=True)
    (date / "calib_cam_to_cam.txt").write_text("calib_time: 09-Jan-2012 13:57:47\n" + _line("R_rect_00", R_RECT)
                                               + _line("P_rect_02", P2) + _line("S_rect_02", np.array(SIZE, float)))
    (date / "calib_velo_to_cam.txt").write_text("calib_time: 15-Mar-2012 11:37:16\n" + _line("R", R_VELO)
                                                + _line("T", T_VELO))
    for f in range(frames):
        cv2.imwrite(str(drive / "image_02" / "data" / f"{f:010d}.png"), np.full((SIZE[1], SIZE[0], 3), 90, np.uint8))
        points, _ = laser_by_laser_cloud(f)
        data = np.column_stack([points, np.full(len(points), 0.5, np.float32)]).astype("<f4")
        data.tofile(drive / "velodyne_points" / "data" / f"{f:010d}.bin")
    return drive


def test_the_rectified_camera_sees_the_lidar_as_kitti_projects_it(tmp_path: Path) -> None:
    drive = write_drive(tmp_path)
    assert import_kitti(drive, tmp_path / "out", camera=2) == 2
    ds = open_dataset(tmp_path / "out")
    assert ds.rig.camera.width == SIZE[0] and ds.rig.camera.height == SIZE[1] and ds.reference is not None
    points = np.array([[10.0, 1.0, -0.5], [25.0, -3.0, 1.0], [6.0, 0.2, 0.3]])
    homogeneous = np.column_stack([points, np.ones(3)])
    T_cam0 = np.eye(4)
    T_cam0[:3, :3], T_cam0[:3, 3] = R_VELO, T_VELO
    rect = np.eye(4)
    rect[:3, :3] = R_RECT
    kitti = (P2 @ rect @ T_cam0 @ homogeneous.T).T
    expected = kitti[:, :2] / kitti[:, 2:]
    camera = ds.rig.camera.model()
    assert isinstance(camera, Pinhole)
    uv, valid = camera.project(ds.reference.T_camera_lidar.apply(points))
    assert valid.all()
    np.testing.assert_allclose(uv, expected, atol=1e-9)
    cloud = ds.load_pair(1).cloud
    assert cloud.ring is not None and cloud.intensity is not None and np.allclose(cloud.intensity, 127.5)


def test_bad_drives_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    drive = write_drive(tmp_path)
    with pytest.raises(DatasetError, match="calib_cam_to_cam.txt: needs P_rect_01 with 12 numbers"):
        import_kitti(drive, tmp_path / "a", camera=1)
    with pytest.raises(DatasetError, match="no frame 7"):
        import_kitti(drive, tmp_path / "b", frames=[0, 7])
    (drive / "velodyne_points" / "data" / "0000000001.bin").write_bytes(b"\0" * 10)
    with pytest.raises(DatasetError, match=r"0000000001.bin: 8 bytes is not a whole number"):
        import_kitti(drive, tmp_path / "c")
    (drive.parent / "calib_velo_to_cam.txt").write_text("R: 1 0 0\n")
    assert main(["import", "kitti", str(drive), str(tmp_path / "d")]) == ERROR
    assert "calib_velo_to_cam.txt: needs R with 9 numbers" in capsys.readouterr().err
