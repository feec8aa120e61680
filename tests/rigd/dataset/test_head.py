"""A multi-camera head dataset (rig.yaml ``model: head``, pairs/NNNN/images/NAME.*, masks) and reference.yaml."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from calib.camera import Fisheye, Mounted
from calib.geometry import Transform
from rigd.dataset import Cloud, RigConfig, open_dataset, write_pair, write_rig
from rigd.dataset.records import CameraConfig, CameraKind, HeadConfig, SensorConfig
from rigd.dataset.reference import Reference, agreement, reference_from_yaml
from rigd.dataset.store import write_yaml
from rigd.errors import DatasetError

K = np.array([[40.0, 0.0, 31.5], [0.0, 20.0, 11.5], [0.0, 0.0, 1.0]])  # fy = fx / 2, as the Ford images


def _sensor(name: str, yaw_deg: float, mask: str | None = None) -> SensorConfig:
    pose = Transform.from_rpy_xyz(np.array([-90.0, 0.0, yaw_deg - 90.0]), np.array([0.04, 0.0, 0.0]))
    return SensorConfig(name, CameraConfig(CameraKind.PINHOLE, 64, 24, K, np.zeros(0), mask), pose)


HEAD = HeadConfig((_sensor("front", 0.0, "masks/front.png"), _sensor("left", 90.0)))
GUESS = Transform.from_rpy_xyz(np.array([0.0, 0.0, -90.0]), np.array([0.3, 0.0, -0.4]))


def _head_dataset(root: Path, pairs: int = 2) -> Path:
    write_rig(root, RigConfig(HEAD, "HDL-64E", GUESS))
    (root / "masks").mkdir()
    mask = np.full((24, 64), 255, np.uint8)
    mask[:, :10] = 0  # the rig's body on the left of the front sensor
    cv2.imwrite(str(root / "masks" / "front.png"), mask)
    rng = np.random.default_rng(0)
    for i in range(pairs):
        images = {"front": rng.integers(0, 255, (24, 64, 3), dtype=np.uint8),
                  "left": rng.integers(0, 255, (24, 64), dtype=np.uint8)}
        write_pair(root, i, images, Cloud(rng.normal(size=(30, 3)) * 5), {"source": "test"})
    return root


def test_a_head_rig_file_round_trips() -> None:
    back = RigConfig.from_yaml(yaml.safe_load(yaml.safe_dump(RigConfig(HEAD, "HDL-64E", GUESS).to_yaml())), "rig.yaml")
    assert isinstance(back.camera, HeadConfig)
    assert back.camera.view_names == ("front", "left") and back.camera.masks == ("masks/front.png", None)
    np.testing.assert_allclose(back.camera.sensors[1].T_head_camera.matrix, HEAD.sensors[1].T_head_camera.matrix,
                               atol=1e-12)
    models = back.camera.models()
    assert all(isinstance(m, Mounted) for m in models) and models[0].name == "front"
    # the sensor looks along the head's x axis: a point 10 m ahead lands on its principal point
    uv, valid = models[0].project(np.array([[10.04, 0.0, 0.0]]))
    assert valid[0] and np.allclose(uv[0], K[:2, 2], atol=1e-6)


@pytest.mark.parametrize(("camera", "message"), [
    ({"model": "head"}, "non-empty list camera.sensors"),
    ({"model": "head", "sensors": [{"name": "a b"}]}, "sensor name 'a b'"),
    ({"model": "head", "sensors": [{"name": "a", "model": "equirectangular", "width": 8, "height": 4,
                                    "T_head_camera": {"rpy_deg": [0, 0, 0], "xyz_m": [0, 0, 0]}}]},
     "pinhole or fisheye cameras"),
    ({"model": "head", "sensors": [{"name": "a", "model": "pinhole", "width": 64, "height": 24, "K": K.tolist()}]},
     "needs T_head_camera"),
])
def test_a_bad_head_section_names_what_is_wrong(camera: dict, message: str) -> None:
    with pytest.raises(DatasetError, match=message):
        RigConfig.from_yaml({"camera": camera}, "rig.yaml")


def test_sensor_names_are_unique() -> None:
    twice = RigConfig(HeadConfig((_sensor("a", 0.0), _sensor("a", 90.0)))).to_yaml()
    with pytest.raises(DatasetError, match="unique"):
        RigConfig.from_yaml(twice, "rig.yaml")


def test_a_head_dataset_loads_one_image_per_sensor_and_the_masks(tmp_path: Path) -> None:
    ds = open_dataset(_head_dataset(tmp_path / "ds"))
    assert ds.views == ("front", "left") and len(ds) == 2
    pair = ds.load_pair(1)
    assert [im.shape[:2] for im in pair.images] == [(24, 64), (24, 64)]
    written = sorted(p.name for p in (tmp_path / "ds" / "pairs" / "0001" / "images").iterdir())
    assert written == ["front.png", "left.png"]
    front, left = ds.masks
    assert left is None and front is not None and not front[:, :10].any() and front[:, 10:].all()


def test_a_copied_jpeg_keeps_its_bytes(tmp_path: Path) -> None:
    src = tmp_path / "photo.jpg"
    cv2.imwrite(str(src), np.full((24, 64, 3), 120, np.uint8))
    root = _head_dataset(tmp_path / "ds", pairs=0)
    write_pair(root, 0, {"front": src, "left": np.zeros((24, 64), np.uint8)}, Cloud(np.ones((3, 3))), {})
    assert (root / "pairs" / "0000" / "images" / "front.jpg").read_bytes() == src.read_bytes()
    assert open_dataset(root).load_pair(0).images[0].shape == (24, 64, 3)


def test_a_missing_or_wrong_sized_file_is_named(tmp_path: Path) -> None:
    root = _head_dataset(tmp_path / "ds")
    (root / "pairs" / "0001" / "images" / "left.png").unlink()
    with pytest.raises(DatasetError, match=r"0001/images/left.png: image file is missing"):
        open_dataset(root).load_pair(1)
    cv2.imwrite(str(root / "masks" / "front.png"), np.full((10, 10), 255, np.uint8))
    with pytest.raises(DatasetError, match=r"front.png: mask is 10x10, its sensor 64x24"):
        open_dataset(root)
    (root / "masks" / "front.png").unlink()
    with pytest.raises(DatasetError, match="front.png: image file is missing"):
        open_dataset(root)


def test_agreement_is_measured_in_the_references_own_form_and_sigmas(tmp_path: Path) -> None:
    T_head_cam = HEAD.sensors[1].T_head_camera
    ref_head = Transform.from_rpy_xyz(np.array([0.1, -0.2, -90.0]), np.array([0.3, 0.0, -0.43]))
    sigma = np.array([0.03, 0.03, 0.025, 0.2, 0.2, 0.2])
    # the reference of one sensor's pinhole dataset: the camera's pose, with the head's sigmas
    ref = Reference(T_head_cam.inverse().compose(ref_head), sigma, T_head_cam, "test")
    write_yaml(tmp_path / "reference.yaml", ref.to_yaml())
    ref = reference_from_yaml(yaml.safe_load((tmp_path / "reference.yaml").read_text()), "reference.yaml")
    moved_head = Transform.from_rpy_xyz(np.array([0.1, -0.2, -89.7]), np.array([0.3, 0.0, -0.38]))  # +0.3 deg, +5 cm
    a = agreement(ref, T_head_cam.inverse().compose(moved_head))
    np.testing.assert_allclose(a.z, [0.0, 0.0, 2.0, 0.0, 0.0, 1.5], atol=1e-6)
    assert a.within() and not a.within(z_max=1.9)
    assert a.rotation_deg == pytest.approx(0.3, abs=1e-6) and a.translation_cm == pytest.approx(5.0, abs=1e-6)


def test_the_references_sigmas_in_local_coordinates() -> None:
    # A reference that is the identity in its own frame: local and published axes are the same ones.
    ref = Reference(Transform.identity(), np.array([0.03, 0.02, 0.01, 0.2, 0.3, 0.4]), Transform.identity(), "t")
    np.testing.assert_allclose(ref.local_sigma(), [0.2, 0.3, 0.4, 3.0, 2.0, 1.0], rtol=1e-4)
    # Seen from a camera turned 90 deg about z, the x and y sigmas swap: translation is in the camera frame.
    turned = Transform.from_rpy_xyz(np.array([0.0, 0.0, 90.0]), np.zeros(3))
    ref = Reference(turned.inverse(), np.array([0.03, 0.02, 0.01, 0.2, 0.2, 0.2]), turned, "t")
    np.testing.assert_allclose(ref.local_sigma()[3:], [2.0, 3.0, 1.0], rtol=1e-4)
    assert Reference(Transform.identity(), None, Transform.identity(), "kitti").local_sigma() is None


def test_a_head_may_have_fisheye_sensors() -> None:
    data = RigConfig(HEAD, "HDL-64E", GUESS).to_yaml()
    data["camera"]["sensors"][1].update(model="fisheye", D=[0.01, -0.002, 0.0, 0.0])
    camera = RigConfig.from_yaml(data, "rig.yaml").camera
    assert isinstance(camera, HeadConfig)
    fisheye = camera.models()[1]
    assert isinstance(fisheye, Mounted) and isinstance(fisheye.sensor, Fisheye)
    data["camera"]["sensors"][1]["D"] = [0.01]
    with pytest.raises(DatasetError, match="fisheye needs K"):
        RigConfig.from_yaml(data, "rig.yaml")


def test_the_dataset_hash_covers_a_heads_images_and_its_masks(tmp_path: Path) -> None:
    from rigd.store.datasets import content_hash

    root = _head_dataset(tmp_path / "head")
    hashes = [content_hash(open_dataset(root))]
    cv2.imwrite(str(root / "pairs" / "0001" / "images" / "left.png"), np.zeros((24, 64), np.uint8))
    hashes.append(content_hash(open_dataset(root)))
    cv2.imwrite(str(root / "masks" / "front.png"), np.full((24, 64), 255, np.uint8))
    hashes.append(content_hash(open_dataset(root)))
    assert len(set(hashes)) == 3  # a version's hash names the data it was made from
