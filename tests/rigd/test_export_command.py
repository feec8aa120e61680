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
from rigd.cli.exit_codes import CANT_CREATE, ERROR
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
    assert main(["export", str(tmp_path / "none.yaml"), "--format", "urdf"]) == ERROR
    assert "none.yaml" in capsys.readouterr().err
    assert main(["export", "3", "--format", "urdf", "--data-dir", str(tmp_path)]) == ERROR
    assert "no rigd store" in capsys.readouterr().err
    (tmp_path / "rigd.db").write_bytes(b"SQLite format 3\x00" + b"\x00" * 84)  # truncated after its header
    assert main(["export", "3", "--format", "urdf", "--data-dir", str(tmp_path)]) == ERROR
    assert "rigd.db: cannot open the database: the file is damaged" in capsys.readouterr().err


@pytest.mark.parametrize(("fmt", "name"), [("urdf", "extrinsics-v7-urdf.urdf"),
                                           ("ros2-launch", "extrinsics-v7-ros2-launch.launch.py"),
                                           ("json", "extrinsics-v7-json.json"), ("ros-tf", "extrinsics-v7-ros-tf.yaml"),
                                           ("opencv", "extrinsics-v7-opencv.yaml")])
def test_service_download_names_end_as_their_format(fmt: str, name: str) -> None:
    from rigd.api.exports import download_name
    from rigd.exports import ExportFormat

    assert download_name(7, ExportFormat(fmt)) == name


INJECTION = 'x"""\nimport os;os.system("id")\n"""'


@pytest.mark.parametrize("frame", [INJECTION, "cam -->", "0cam", "/camera", "cam//optical", "a" * 129])
def test_a_frame_that_is_no_ros_name_is_refused(calibration: Path, frame: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    for option in ("--parent-frame", "--child-frame"):
        assert main(["export", str(calibration), "--format", "ros2-launch", option, frame]) == ERROR
        err = capsys.readouterr().err
        assert f"rigd: error: the {option[2:].replace('-', ' ')} {frame!r} " in err and "Traceback" not in err


def test_a_bags_frame_that_is_no_ros_name_is_refused(calibration: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (calibration.parent.parent / "bag.yaml").write_text(yaml.safe_dump({"frames": {"camera": INJECTION,
                                                                                   "lidar": "vlp16"}}))
    assert main(["export", str(calibration), "--format", "urdf"]) == ERROR
    assert "bag.yaml: the camera frame" in capsys.readouterr().err


def test_a_label_cannot_leave_its_comment(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The label names the file read, whose path may hold anything: it stays inside its comment or string."""
    folder = tmp_path / 'a"""\nimport os -->\n<evil>'
    folder.mkdir()
    path = folder / "extrinsics.yaml"
    path.write_text(yaml.safe_dump({"T_camera_lidar": transform_to_yaml(T)}))
    launch = ast.parse(_export(capsys, str(path), "--format", "ros2-launch"))
    assert [type(n).__name__ for n in launch.body] == ["Expr", "ImportFrom", "ImportFrom", "FunctionDef"]
    joint = ET.fromstring(_export(capsys, str(path), "--format", "urdf"))  # one element, no other
    assert joint.tag == "joint" and [c.tag for c in joint] == ["parent", "child", "origin"]
    for fmt in ("ros-tf", "kalibr"):
        assert yaml.safe_load(_export(capsys, str(path), "--format", fmt))


def test_the_record_read_is_never_overwritten(calibration: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = calibration.read_bytes()
    for extra in ((), ("--overwrite",)):
        code = main(["export", str(calibration), "--format", "kalibr", "--out", str(calibration), *extra])
        assert code == CANT_CREATE
        assert "it is the input" in capsys.readouterr().err and calibration.read_bytes() == before
    other = calibration.parent / "kalibr.yaml"
    other.write_text("someone's file")
    assert main(["export", str(calibration), "--format", "kalibr", "--out", str(other)]) == CANT_CREATE
    assert "--overwrite" in capsys.readouterr().err and other.read_text() == "someone's file"
    assert main(["export", str(calibration), "--format", "kalibr", "--out", str(other), "--overwrite"]) == 0
    assert "cam0" in yaml.safe_load(other.read_text())
    assert sorted(p.name for p in calibration.parent.iterdir()) == ["extrinsics.yaml", "kalibr.yaml"]  # no .partial
