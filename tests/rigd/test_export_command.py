"""rigd export: every format read back with its own reader gives the transform, with the frames the bag named."""

from __future__ import annotations

import ast
import xml.etree.ElementTree as ET
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from calib.geometry import Transform
from rigd.cli import main
from rigd.dataset.records import transform_to_yaml

T = Transform.from_rpy_xyz(np.array([-0.18, 15.47, -55.14]), np.array([0.0934, 0.0597, -0.1659]))


@pytest.fixture()
def calibration(tmp_path: Path) -> Path:
    """DATASET/calibration/extrinsics.yaml, with DATASET/bag.yaml naming the frames as rigd import bag does."""
    (tmp_path / "calibration").mkdir()
    (tmp_path / "bag.yaml").write_text(yaml.safe_dump({"frames": {"camera": "cam_optical", "lidar": "vlp16"}}))
    path = tmp_path / "calibration" / "extrinsics.yaml"
    path.write_text(yaml.safe_dump({"T_camera_lidar": transform_to_yaml(T)}))
    return path


def _export(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    assert main(["export", *args]) == 0
    return capsys.readouterr().out


def test_formats_read_back(calibration: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tf = yaml.safe_load(_export(capsys, str(calibration), "--format", "ros-tf"))
    assert (tf["header"]["frame_id"], tf["child_frame_id"]) == ("cam_optical", "vlp16")
    q = tf["transform"]["rotation"]
    assert np.allclose(Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]]).as_matrix(), T.rotation, atol=1e-9)

    joint = ET.fromstring(_export(capsys, str(calibration.parent), "--format", "urdf"))
    origin = joint.find("origin")
    assert origin is not None and joint.find("parent").get("link") == "cam_optical"  # type: ignore[union-attr]
    rpy = [float(v) for v in origin.get("rpy", "").split()]
    assert np.allclose(Rotation.from_euler("xyz", rpy).as_matrix(), T.rotation, atol=1e-9)  # URDF: fixed axes
    assert np.allclose([float(v) for v in origin.get("xyz", "").split()], T.translation_m)

    launch = ast.parse(_export(capsys, str(calibration), "--format", "ros2-launch", "--child-frame", "velo"))
    args = next(ast.literal_eval(k.value) for n in ast.walk(launch) if isinstance(n, ast.Call)
                for k in n.keywords if k.arg == "arguments")
    named = dict(zip(args[::2], args[1::2], strict=True))
    assert (named["--frame-id"], named["--child-frame-id"]) == ("cam_optical", "velo")
    quat = [float(named[f"--q{c}"]) for c in "xyzw"]
    assert np.allclose(Rotation.from_quat(quat).as_matrix(), T.rotation, atol=1e-9)

    assert np.allclose(yaml.safe_load(_export(capsys, str(calibration), "--format", "kalibr"))["cam0"]["T_cam_lidar"],
                       T.matrix)
    out = calibration.parent / "cv.yaml"
    assert main(["export", str(calibration), "--format", "opencv", "--out", str(out)]) == 0
    fs = cv2.FileStorage(str(out), cv2.FILE_STORAGE_READ)
    assert np.allclose(fs.getNode("T").mat(), T.matrix)


def test_frames_default_without_a_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "extrinsics.yaml"
    path.write_text(yaml.safe_dump({"T_camera_lidar": transform_to_yaml(T)}))
    tf = yaml.safe_load(_export(capsys, str(path), "--format", "ros-tf"))
    assert (tf["header"]["frame_id"], tf["child_frame_id"]) == ("camera", "velodyne")


def test_errors_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["export", str(tmp_path / "none.yaml"), "--format", "urdf"]) == 2
    assert "none.yaml" in capsys.readouterr().err
    assert main(["export", "3", "--format", "urdf", "--data-dir", str(tmp_path)]) == 2
    assert "no rigd store" in capsys.readouterr().err


@pytest.mark.parametrize(("fmt", "name"), [("urdf", "extrinsics-v7-urdf.urdf"),
                                           ("ros2-launch", "extrinsics-v7-ros2-launch.launch.py"),
                                           ("json", "extrinsics-v7-json.json"), ("ros-tf", "extrinsics-v7-ros-tf.yaml"),
                                           ("opencv", "extrinsics-v7-opencv.yaml")])
def test_service_download_names_end_as_their_format(fmt: str, name: str) -> None:
    from rigd.api.exports import download_name
    from rigd.exports import ExportFormat

    assert download_name(7, ExportFormat(fmt)) == name
