"""Dataset directories (rigd/dataset/store.py, records.py): layout, atomic pairs, clear errors."""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from calib.camera import Equirectangular, Pinhole
from calib.geometry import Transform
from rigd.dataset import (
    CameraConfig,
    CameraKind,
    Cloud,
    RigConfig,
    open_dataset,
    store,
    write_ground_truth,
    write_pair,
    write_rig,
)
from rigd.dataset.store import next_pair_index
from rigd.errors import DatasetError, DatasetLockedError
from rigd.locks import DatasetLock, reading
from tests.testdata import PINHOLE_FRAME

PANO_RIG = RigConfig(
    CameraConfig(CameraKind.EQUIRECTANGULAR, 64, 32),
    "VLP-16",
    Transform.from_rpy_xyz(np.array([1.0, -2.0, 90.0]), np.array([0.1, 0.0, -0.2])),
)


def small_pair(seed: int) -> tuple[np.ndarray, Cloud, dict]:
    rng = np.random.default_rng(seed)
    image = rng.integers(0, 256, size=(32, 64, 3), dtype=np.uint8)
    # Quarter-metre steps are exact in float32, so the cloud survives the PCD round trip bit for bit.
    points = rng.integers(-40, 40, size=(50, 3)) / 4.0
    intensity, ring = rng.integers(0, 255, 50).astype(np.float32), rng.integers(0, 16, 50).astype(np.int16)
    cloud = Cloud(points, intensity, ring)
    return image, cloud, {"capture_time_s": 1700000000.5 + seed, "stationary": True}


@pytest.fixture
def dataset_root(tmp_path: Path) -> Path:
    root = tmp_path / "ds"
    write_rig(root, PANO_RIG)
    for i in range(2):
        write_pair(root, i, *small_pair(i))
    return root


def test_pairs_round_trip(dataset_root: Path) -> None:
    dataset = open_dataset(dataset_root)
    assert len(dataset) == 2
    assert [p.name for p in dataset.pair_dirs] == ["0000", "0001"]
    for i, pair in enumerate(dataset.pairs()):
        image, cloud, meta = small_pair(i)
        assert pair.index == i
        np.testing.assert_array_equal(pair.image, image)  # PNG is lossless
        np.testing.assert_array_equal(pair.cloud.points_lidar, cloud.points_lidar)
        np.testing.assert_array_equal(pair.cloud.intensity, cloud.intensity)
        np.testing.assert_array_equal(pair.cloud.ring, cloud.ring)
        assert pair.meta == meta
    assert sorted(p.name for p in (dataset_root / "pairs" / "0000").iterdir()) == [
        "cloud.pcd",
        "image.png",
        "meta.yaml",
    ]


def test_rig_round_trip(dataset_root: Path) -> None:
    rig = open_dataset(dataset_root).rig
    assert rig.camera.kind is CameraKind.EQUIRECTANGULAR
    assert (rig.camera.width, rig.camera.height) == (64, 32)
    assert isinstance(rig.camera.model(), Equirectangular)
    assert rig.lidar_model == "VLP-16"
    assert rig.initial_guess is not None and PANO_RIG.initial_guess is not None
    np.testing.assert_allclose(rig.initial_guess.matrix, PANO_RIG.initial_guess.matrix, atol=1e-12)


def test_ground_truth_round_trip(dataset_root: Path) -> None:
    assert open_dataset(dataset_root).ground_truth is None
    truth = Transform.from_rpy_xyz(np.array([-90.0, 0.5, -90.0]), np.array([0.0, -0.08, -0.1]))
    write_ground_truth(dataset_root, truth)
    data = yaml.safe_load((dataset_root / "ground_truth.yaml").read_text())["T_camera_lidar"]
    assert set(data) == {"matrix", "quaternion_xyzw", "rpy_deg", "xyz_m"}
    loaded = open_dataset(dataset_root).ground_truth
    assert loaded is not None
    np.testing.assert_allclose(loaded.matrix, truth.matrix, atol=1e-12)


# --- atomic writes and resumption --------------------------------------------------------------------


def test_leftover_tmp_is_not_a_pair(dataset_root: Path) -> None:
    # An interrupted writer leaves pairs/.0002.tmp with whatever it got to write.
    leftover = dataset_root / "pairs" / ".0002.tmp"
    shutil.copytree(dataset_root / "pairs" / "0001", leftover)
    assert len(open_dataset(dataset_root)) == 2
    assert next_pair_index(dataset_root) == 2
    # Resuming writes pair 2 over the leftover, which then is gone.
    write_pair(dataset_root, 2, *small_pair(2))
    assert not leftover.exists()
    dataset = open_dataset(dataset_root)
    assert len(dataset) == 3
    assert dataset.load_pair(2).meta == small_pair(2)[2]


def test_existing_pair_is_not_overwritten(dataset_root: Path) -> None:
    before = (dataset_root / "pairs" / "0001" / "cloud.pcd").read_bytes()
    with pytest.raises(DatasetError, match="0001.*already exists"):
        write_pair(dataset_root, 1, *small_pair(7))
    assert (dataset_root / "pairs" / "0001" / "cloud.pcd").read_bytes() == before
    assert not (dataset_root / "pairs" / ".0001.tmp").exists()


def test_disk_full_is_a_dataset_error_and_leaves_no_pair(
    dataset_root: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_space(path: Path, cloud: Cloud, compressed: bool = True) -> None:
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(store, "write_pcd", no_space)
    with pytest.raises(DatasetError, match=r"\.0002\.tmp.*pair 0002.*No space left"):
        write_pair(dataset_root, 2, *small_pair(2))
    assert len(open_dataset(dataset_root)) == 2
    monkeypatch.undo()
    write_pair(dataset_root, 2, *small_pair(2))  # space freed: the same index is written
    assert len(open_dataset(dataset_root)) == 3


def test_next_pair_index_on_a_new_dataset(tmp_path: Path) -> None:
    assert next_pair_index(tmp_path / "new") == 0


# --- broken files --------------------------------------------------------------------------------------


def test_corrupt_png_names_the_file(dataset_root: Path) -> None:
    image = dataset_root / "pairs" / "0001" / "image.png"
    image.write_bytes(image.read_bytes()[:200])  # truncated PNG
    dataset = open_dataset(dataset_root)
    with pytest.raises(DatasetError, match=r"0001/image\.png"):
        dataset.load_pair(1)
    image.write_bytes(b"\x89PNG\r\n\x1a\n" + b"garbage" * 20)
    with pytest.raises(DatasetError, match=r"0001/image\.png"):
        dataset.load_pair(1)


def test_missing_and_broken_cloud_name_the_file(dataset_root: Path) -> None:
    cloud = dataset_root / "pairs" / "0000" / "cloud.pcd"
    cloud.write_bytes(cloud.read_bytes()[:-40])
    with pytest.raises(DatasetError, match=r"0000/cloud\.pcd"):
        open_dataset(dataset_root).load_pair(0)
    cloud.unlink()
    with pytest.raises(DatasetError, match=r"0000/cloud\.pcd.*missing"):
        open_dataset(dataset_root).load_pair(0)


def test_image_size_must_match_rig(dataset_root: Path) -> None:
    cv2.imwrite(str(dataset_root / "pairs" / "0000" / "image.png"), np.zeros((10, 20), np.uint8))
    with pytest.raises(DatasetError, match=r"image\.png.*20x10.*64x32"):
        open_dataset(dataset_root).load_pair(0)


def test_meta_must_be_a_mapping(dataset_root: Path) -> None:
    (dataset_root / "pairs" / "0000" / "meta.yaml").write_text("- just\n- a list\n")
    with pytest.raises(DatasetError, match=r"meta\.yaml"):
        open_dataset(dataset_root).load_pair(0)


PANO_CAMERA = "camera: {model: equirectangular, width: 64, height: 32}\n"
PINHOLE_K = "K: [[50, 0, 32], [0, 50, 16], [0, 0, 1]]"
SCALED = "[[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"
BAD_RIGS = {
    "not yaml": "camera: [unclosed\n",
    "a list": "- camera\n",
    "empty": "",
    "no camera": "lidar: {model: VLP-16}\n",
    "unknown model": "camera: {model: fisheye, width: 64, height: 32}\n",
    "no size": "camera: {model: equirectangular}\n",
    "negative size": "camera: {model: equirectangular, width: -64, height: 32}\n",
    "text size": "camera: {model: equirectangular, width: wide, height: 32}\n",
    "pinhole without K": "camera: {model: pinhole, width: 64, height: 32}\n",
    "K not 3x3": "camera: {model: pinhole, width: 64, height: 32, K: [[1, 0], [0, 1]], D: []}\n",
    "D of 3": "camera: {model: pinhole, width: 64, height: 32, " + PINHOLE_K + ", D: [0, 0, 0]}\n",
    "lidar not a mapping": PANO_CAMERA + "lidar: VLP-16\n",
    "guess without xyz": PANO_CAMERA + "initial_guess: {rpy_deg: [0, 0, 0]}\n",
    "guess not a rotation": PANO_CAMERA + "initial_guess: {matrix: " + SCALED + "}\n",
}


@pytest.mark.parametrize("name", list(BAD_RIGS))
def test_bad_rig_yaml_names_the_file(dataset_root: Path, name: str) -> None:
    (dataset_root / "rig.yaml").write_text(BAD_RIGS[name])
    with pytest.raises(DatasetError, match=r"ds/rig\.yaml"):
        open_dataset(dataset_root)


POSE = "T_head_camera: {rpy_deg: [0, 0, 0], xyz_m: [0, 0, 0]}"
BAD_INTRINSICS = {  # rig.yaml text, the message it must give
    "pinhole fx < 0": (
        "camera: {model: pinhole, width: 64, height: 32, K: [[-500, 0, 32], [0, 50, 16], [0, 0, 1]]}",
        r"ds/rig\.yaml: pinhole K: fx must be > 0, got -500$",
    ),
    "pinhole K zero": (
        "camera: {model: pinhole, width: 64, height: 32, K: [[0, 0, 0], [0, 0, 0], [0, 0, 0]]}",
        r"ds/rig\.yaml: pinhole K: fx must be > 0, got 0$",
    ),
    "fisheye fy NaN": (
        "camera: {model: fisheye, width: 64, height: 32, K: [[50, 0, 32], [0, .nan, 16], [0, 0, 1]], D: [0, 0, 0, 0]}",
        r"ds/rig\.yaml: fisheye K: fy must be finite, got nan$",
    ),
    "head sensor": (
        "camera: {model: head, sensors: [{name: cam0, model: pinhole, width: 64, height: 32, "
        "K: [[50, 0, 32], [0, 50, 16], [0, 0, 2]], " + POSE + "}]}",
        r"ds/rig\.yaml: sensor cam0: pinhole K: the last row must be \[0, 0, 1\]",
    ),
}


@pytest.mark.parametrize("name", list(BAD_INTRINSICS))
def test_bad_intrinsics_in_rig_yaml_name_the_file_and_the_value(dataset_root: Path, name: str) -> None:
    """calib's GeometryError on a bad K reaches the user as a DatasetError naming rig.yaml (not a traceback)."""
    text, message = BAD_INTRINSICS[name]
    (dataset_root / "rig.yaml").write_text(text + "\n")
    with pytest.raises(DatasetError, match=message):
        open_dataset(dataset_root)


def test_missing_rig_and_missing_dataset(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="nothing.*does not exist"):
        open_dataset(tmp_path / "nothing")
    with pytest.raises(DatasetError, match=r"rig\.yaml.*missing"):
        open_dataset(tmp_path)


def test_bad_ground_truth_names_the_file(dataset_root: Path) -> None:
    (dataset_root / "ground_truth.yaml").write_text("- not\n- a mapping\n")
    with pytest.raises(DatasetError, match=r"ground_truth\.yaml"):
        open_dataset(dataset_root)
    (dataset_root / "ground_truth.yaml").write_text("T_camera_lidar: {xyz_m: [0, 0, 0]}\n")
    with pytest.raises(DatasetError, match=r"ground_truth\.yaml"):
        open_dataset(dataset_root)


# --- the real pinhole sample in the dataset layout ------------------------------------------------------


def test_pinhole_sample_as_a_dataset(tmp_path: Path) -> None:
    """ours_3 converted by hand: rig.yaml from calibration.yaml's camera block, the JPEG, the LZF cloud."""
    source = PINHOLE_FRAME
    calibration = yaml.safe_load((source / "calibration.yaml").read_text())
    root = tmp_path / "ours_3"
    (root / "pairs" / "0000").mkdir(parents=True)
    rig = {"camera": calibration["camera"], "lidar": {"model": "64-ring"}}
    (root / "rig.yaml").write_text(yaml.safe_dump(rig))
    (root / "ground_truth.yaml").write_text(yaml.safe_dump({"T_camera_lidar": calibration["T_camera_lidar"]}))
    shutil.copy(source / "image.jpg", root / "pairs" / "0000" / "image.jpg")
    shutil.copy(source / "calib.pcd", root / "pairs" / "0000" / "cloud.pcd")

    dataset = open_dataset(root)
    assert len(dataset) == 1
    camera = dataset.rig.camera
    assert camera.kind is CameraKind.PINHOLE and (camera.width, camera.height) == (1920, 1200)
    np.testing.assert_array_equal(camera.K, calibration["camera"]["K"])
    np.testing.assert_array_equal(camera.D, calibration["camera"]["D"])
    assert isinstance(camera.model(), Pinhole)
    assert dataset.rig.lidar_model == "64-ring"
    pair = dataset.load_pair(0)
    assert pair.image.shape == (1200, 1920, 3) and pair.image.dtype == np.uint8
    assert len(pair.cloud) == 85546  # POINTS in the header of the original calib.pcd
    assert pair.meta == {}
    truth = dataset.ground_truth
    assert truth is not None
    np.testing.assert_allclose(truth.matrix, calibration["T_camera_lidar"]["matrix"], atol=1e-12)
    # The sample's README: about 10.5-12.7 thousand points of each cloud fall inside the image.
    uv, valid = camera.model().project(truth.apply(pair.cloud.points_lidar))
    inside = valid & (uv[:, 0] >= 0) & (uv[:, 0] < 1920) & (uv[:, 1] >= 0) & (uv[:, 1] < 1200)
    assert 10_000 < inside.sum() < 13_000


# --- one writer per dataset, and disk errors ------------------------------------------------------------

HOLD_LOCK = """
import sys, time
from pathlib import Path
from rigd.locks import DatasetLock
lock = DatasetLock.acquire(Path(sys.argv[1]))
(Path(sys.argv[1]) / "pairs" / ".0002.tmp").mkdir()  # its pair 0002, half written
print("locked", flush=True)
time.sleep(60)
"""


def test_a_dataset_another_process_writes_is_left_alone(dataset_root: Path) -> None:
    other = subprocess.Popen([sys.executable, "-c", HOLD_LOCK, str(dataset_root)], stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout is not None and other.stdout.readline() == "locked\n"
        with pytest.raises(DatasetLockedError, match=rf"dataset {dataset_root} is being written by another process "
                                                     rf"\(pid {other.pid}: "):
            write_pair(dataset_root, 2, *small_pair(2))
        assert (dataset_root / "pairs" / ".0002.tmp").is_dir()  # the other writer's work is not deleted
        assert not (dataset_root / "pairs" / "0002").exists()
        with pytest.raises(DatasetLockedError):
            DatasetLock.acquire(dataset_root)
    finally:
        other.kill()
        other.wait(10)
    # Its process gone, the kernel dropped its lock: the leftover is cleared and the pair written.
    write_pair(dataset_root, 2, *small_pair(2))
    assert not (dataset_root / "pairs" / ".0002.tmp").exists() and len(open_dataset(dataset_root)) == 3
    with DatasetLock.acquire(dataset_root):  # held by this process: its writes go through
        write_pair(dataset_root, 3, *small_pair(3))
    assert len(open_dataset(dataset_root)) == 4


def test_a_dataset_being_calibrated_takes_no_capture_and_one_being_captured_no_calibration(
        dataset_root: Path) -> None:
    with reading(dataset_root), reading(dataset_root):  # calibrations and checks share it
        with pytest.raises(DatasetLockedError, match=rf"dataset {dataset_root} is being calibrated or checked"):
            DatasetLock.acquire(dataset_root)
        with pytest.raises(DatasetLockedError):
            write_pair(dataset_root, 2, *small_pair(2))
    with DatasetLock.acquire(dataset_root), pytest.raises(DatasetLockedError, match="calibrate or check it when"):
        with reading(dataset_root):
            pass
    with reading(dataset_root):  # both released
        assert len(open_dataset(dataset_root)) == 2


def test_a_full_disk_is_a_dataset_error_and_leaves_no_temporary_file(tmp_path: Path) -> None:
    root = tmp_path / "ds"
    root.mkdir()
    tmp = root / ".rig.yaml.tmp"
    tmp.symlink_to("/dev/full")  # writes there fail with ENOSPC, as on a full disk
    with pytest.raises(DatasetError, match=r"rig\.yaml: cannot write \(No space left on device\)") as caught:
        write_rig(root, PANO_RIG)
    assert isinstance(caught.value.__cause__, OSError) and caught.value.__cause__.errno == errno.ENOSPC
    assert not os.path.lexists(tmp) and not (root / "rig.yaml").exists()
    (tmp_path / "file").write_text("not a folder")
    with pytest.raises(DatasetError, match=r"file/ds: cannot create the dataset folder \(Not a directory\)"):
        write_rig(tmp_path / "file" / "ds", PANO_RIG)
