"""Files a dataset must not be read from are refused by name (DatasetError), not read as something else or left
to a traceback: clouds without a point or with impossible values, headers claiming more than the file holds,
pair folders named two ways, a rig.yaml's ``true`` for a width, an empty transform."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigd.dataset import CameraConfig, CameraKind, Cloud, RigConfig, open_dataset, read_pcd, write_pcd, write_rig
from rigd.dataset.records import transform_from_yaml
from rigd.dataset.store import next_pair_index, read_image, write_pair
from rigd.errors import DatasetError

HEADER = ("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\n"
          "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n")


def pcd(tmp_path: Path, points: np.ndarray, ring: np.ndarray | None = None) -> Path:
    path = tmp_path / "c.pcd"
    write_pcd(path, Cloud(points, ring=ring), compressed=False)
    return path


@pytest.mark.parametrize(("points", "message"), [
    (np.zeros((0, 3)), "the cloud has no points"),
    (np.full((5, 3), np.nan), r"no point with finite x, y, z \(all 5 are NaN or infinite\)"),
    (np.array([[1.0, 2.0, 3.0], [1e30, 0.0, 0.0]]), r"1 points lie beyond 10000 m, e\.g\. \(1e\+30, 0, 0\)"),
])
def test_a_cloud_without_usable_points_is_refused(tmp_path, points, message):
    with pytest.raises(DatasetError, match=message):
        read_pcd(pcd(tmp_path, points))


def test_a_negative_ring_is_refused(tmp_path):
    path = pcd(tmp_path, np.ones((3, 3)), ring=np.array([0, 1, -1], np.int16))  # written as uint16: 65535
    with pytest.raises(DatasetError, match=r"1 points have a ring index outside 0\.\.1023, e\.g\. 65535"):
        read_pcd(path)


@pytest.mark.parametrize(("body", "message"), [
    (b"", "empty file, not a PCD cloud"),
    (HEADER.format(n=4_000_000_000, data="binary").encode() + b"\0" * 24,
     r"truncated PCD: the header says 4000000000 points \(48000000000 bytes\), the file holds 24"),
    (HEADER.format(n=4_000_000_000, data="binary_compressed").encode() + struct.pack("<II", 10, 48) + b"\0" * 10,
     "corrupt PCD: the header says 4000000000 points"),
    (HEADER.format(n=4_000_000_000, data="ascii").encode() + b"1 2 3\n", "truncated PCD: the header says"),
    (b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4\nDATA binary\n", r"not a readable PCD header \([^\n]*\)$"),
])
def test_a_pcd_that_claims_more_than_it_holds_is_refused_before_it_is_read(tmp_path, body, message):
    path = tmp_path / "c.pcd"
    path.write_bytes(body)
    with pytest.raises(DatasetError, match=message):
        read_pcd(path)


def test_an_image_header_claiming_too_many_pixels_is_refused(tmp_path):
    png = bytearray(cv2.imencode(".png", np.zeros((2, 2), np.uint8))[1].tobytes())
    png[16:24] = struct.pack(">II", 60000, 30000)  # the IHDR's width and height, then its CRC
    png[29:33] = struct.pack(">I", zlib.crc32(bytes(png[12:29])))
    (tmp_path / "image.png").write_bytes(bytes(png))
    with pytest.raises(DatasetError, match=r"image\.png: not a readable PNG/JPEG image \(.*\)"):
        read_image(tmp_path / "image.png")


def tiny(root: Path) -> Path:
    write_rig(root, RigConfig(CameraConfig(CameraKind.EQUIRECTANGULAR, 16, 8)))
    write_pair(root, 1, np.zeros((8, 16), np.uint8), Cloud(np.ones((4, 3))), {})
    return root


@pytest.mark.parametrize(("name", "message"), [("1", r"pairs/1: .* \(pairs/0001\): rename it"),
                                               ("00001", r"pairs/00001: .*\(pairs/0001\)"),
                                               ("²", r"pairs/²: a pair folder is named by its number in ASCII")])
def test_a_pair_folder_named_another_way_is_refused(tmp_path, name, message):
    root = tiny(tmp_path / "ds")
    (root / "pairs" / name).mkdir()  # beside 0001: the same pair twice, or no number at all
    for read in (open_dataset, next_pair_index):
        with pytest.raises(DatasetError, match=message):
            read(root)


def test_pairs_are_in_number_order_past_9999(tmp_path):
    root = tiny(tmp_path / "ds")
    for index in (9999, 10000):
        write_pair(root, index, np.zeros((8, 16), np.uint8), Cloud(np.ones((4, 3))), {})
    assert [p.name for p in open_dataset(root).pair_dirs] == ["0001", "9999", "10000"]
    assert next_pair_index(root) == 10001


@pytest.mark.parametrize("width", [True, 2.5, "256", 0])
def test_a_width_that_is_no_number_of_pixels_is_refused(width):
    camera = {"model": "equirectangular", "width": width, "height": 8}
    with pytest.raises(DatasetError, match=f"camera width must be a whole number of pixels, 1 .. 65535, got {width!r}"):
        RigConfig.from_yaml({"camera": camera}, "rig.yaml")


def test_a_mask_outside_the_dataset_is_refused():
    camera = {"model": "equirectangular", "width": 16, "height": 8, "mask": "../other/mask.png"}
    with pytest.raises(DatasetError, match="must be a file inside the dataset"):
        RigConfig.from_yaml({"camera": camera}, "rig.yaml")


@pytest.mark.parametrize(("data", "found"), [({}, "it is empty"), ({"rpy_deg": [0, 0, 0]}, "it has rpy_deg"),
                                             ([1, 2], "got list")])
def test_an_empty_or_partial_transform_says_what_it_needs(data, found):
    with pytest.raises(DatasetError, match=f"e.yaml: no transform: T_camera_lidar needs matrix .*{found}"):
        transform_from_yaml(data, "e.yaml")
