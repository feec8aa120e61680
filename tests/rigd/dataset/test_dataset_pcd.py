"""PCD reading and writing (rigd/dataset/pcd.py) against the real LZF clouds and hand-made files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigd.dataset import Cloud, read_pcd, write_pcd
from rigd.errors import DatasetError
from tests.testdata import PINHOLE_FRAME

# Layout of the uncompressed cloud.pcd beside the original, as documented in tests/data/pinhole_sample/README.md.
CLOUD_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2")])


def read_reference(path: Path) -> np.ndarray:
    """Decode a ``DATA binary`` cloud.pcd with plain numpy (independent of pypcd4)."""
    raw = path.read_bytes()
    marker = b"DATA binary\n"
    return np.frombuffer(raw[raw.index(marker) + len(marker) :], dtype=CLOUD_DTYPE)


@pytest.fixture(scope="module")
def reference_ours_3() -> np.ndarray:
    return read_reference(PINHOLE_FRAME / "cloud.pcd")


def header_data_line(path: Path) -> str:
    for line in path.read_bytes().split(b"\n"):
        if line.startswith(b"DATA"):
            return line.decode()
    raise AssertionError(f"{path} has no DATA line")


def test_binary_compressed_matches_uncompressed_point_for_point(reference_ours_3: np.ndarray) -> None:
    compressed = PINHOLE_FRAME / "calib.pcd"
    assert header_data_line(compressed) == "DATA binary_compressed"
    cloud = read_pcd(compressed)
    reference = reference_ours_3
    assert len(cloud) == len(reference) > 80_000
    for i, axis in enumerate("xyz"):
        np.testing.assert_array_equal(cloud.points_lidar[:, i], reference[axis].astype(np.float64))
    assert cloud.intensity is not None and cloud.ring is not None
    np.testing.assert_array_equal(cloud.intensity, reference["intensity"])
    np.testing.assert_array_equal(cloud.ring, reference["ring"].astype(np.int16))
    assert cloud.ring.min() == 0 and cloud.ring.max() == 63  # a 64-ring LiDAR


def test_binary_reads_like_numpy(reference_ours_3: np.ndarray) -> None:
    cloud = read_pcd(PINHOLE_FRAME / "cloud.pcd")
    np.testing.assert_array_equal(cloud.points_lidar[:, 2], reference_ours_3["z"].astype(np.float64))
    np.testing.assert_array_equal(cloud.ring, reference_ours_3["ring"])


def cloud_from(reference: np.ndarray) -> Cloud:
    points = np.stack([reference["x"], reference["y"], reference["z"]], axis=1).astype(np.float64)
    return Cloud(points, reference["intensity"].copy(), reference["ring"].astype(np.int16))


@pytest.mark.parametrize(
    ("compressed", "data_line"), [(True, "DATA binary_compressed"), (False, "DATA binary")]
)
def test_write_read_round_trip(
    tmp_path: Path, reference_ours_3: np.ndarray, compressed: bool, data_line: str
) -> None:
    original = cloud_from(reference_ours_3[:5000])  # real data compresses, so LZF is really used
    path = tmp_path / "cloud.pcd"
    write_pcd(path, original, compressed=compressed)
    assert header_data_line(path) == data_line
    again = read_pcd(path)
    np.testing.assert_array_equal(again.points_lidar, original.points_lidar)  # float32 values survive
    np.testing.assert_array_equal(again.intensity, original.intensity)
    np.testing.assert_array_equal(again.ring, original.ring)


def test_round_trip_without_optional_fields(tmp_path: Path) -> None:
    points = np.arange(30, dtype=np.float64).reshape(10, 3) / 4.0  # exact in float32
    write_pcd(tmp_path / "c.pcd", Cloud(points))
    again = read_pcd(tmp_path / "c.pcd")
    np.testing.assert_array_equal(again.points_lidar, points)
    assert again.intensity is None and again.ring is None


def test_non_finite_points_are_dropped_with_their_fields(tmp_path: Path) -> None:
    # Organised clouds mark missing returns with NaN; those rows go, the others keep their fields.
    points = np.array([[1.0, 2.0, 3.0], [np.nan, np.nan, np.nan], [4.0, 5.0, 6.0]])
    cloud = Cloud(points, np.array([10.0, 20.0, 30.0], np.float32), np.array([0, 1, 2], np.int16))
    write_pcd(tmp_path / "c.pcd", cloud, compressed=False)
    again = read_pcd(tmp_path / "c.pcd")
    np.testing.assert_array_equal(again.points_lidar, points[[0, 2]])
    np.testing.assert_array_equal(again.intensity, [10.0, 30.0])
    np.testing.assert_array_equal(again.ring, [0, 2])


ASCII_HEADER = (
    "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\n"
    "TYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n"
)
ASCII_BODY = "1.5 -2 0.25 7\n0 0 1 8\n-3 4 5 9\n"


def test_ascii_is_accepted(tmp_path: Path) -> None:
    path = tmp_path / "a.pcd"
    path.write_text(ASCII_HEADER + ASCII_BODY)
    cloud = read_pcd(path)
    np.testing.assert_array_equal(cloud.points_lidar, [[1.5, -2.0, 0.25], [0.0, 0.0, 1.0], [-3.0, 4.0, 5.0]])
    np.testing.assert_array_equal(cloud.intensity, [7.0, 8.0, 9.0])
    assert cloud.ring is None


def compressed_bytes() -> bytes:
    return (PINHOLE_FRAME / "calib.pcd").read_bytes()


def body_start(raw: bytes, marker: bytes) -> int:
    return raw.index(marker) + len(marker)


def broken_files() -> dict[str, bytes]:
    lzf = compressed_bytes()
    binary = (PINHOLE_FRAME / "cloud.pcd").read_bytes()
    lzf_body = body_start(lzf, b"DATA binary_compressed\n")
    return {
        "empty": b"",
        "garbage": bytes(range(256)) * 8,
        "text": b"this is not a point cloud\n",
        "header cut": lzf[:120],
        "compressed cut in half": lzf[: len(lzf) // 2],
        "compressed header only": lzf[:lzf_body],
        "compressed size words only": lzf[: lzf_body + 8],
        "binary cut by whole points": binary[: len(binary) - 10 * CLOUD_DTYPE.itemsize],
        "binary cut mid point": binary[: len(binary) - 7],
        "ascii missing a row": (ASCII_HEADER + ASCII_BODY.split("\n", 1)[1]).encode(),
        "no xyz": ASCII_HEADER.replace("x y z", "a b c").encode() + ASCII_BODY.encode(),
    }


@pytest.mark.parametrize("name", list(broken_files()))
def test_broken_pcd_gives_dataset_error_naming_the_file(tmp_path: Path, name: str) -> None:
    path = tmp_path / f"{name.replace(' ', '_')}.pcd"
    path.write_bytes(broken_files()[name])
    with pytest.raises(DatasetError, match=path.name):
        read_pcd(path)


def test_missing_pcd(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="nowhere.pcd.*missing"):
        read_pcd(tmp_path / "nowhere.pcd")
