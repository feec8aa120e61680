"""``rigd import pairs``: folders of images and PCD clouds with a ROS camera_info, on a tiny tree the tests write
in the layout of the ACFR cam_lidar_calibration data (images/poseN.png, pcd/poseN_full.pcd and poseN_target.pcd,
camera_info.yaml, a CSV of calibrations)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from calib.geometry import Transform
from rigd.cli import main
from rigd.cli.exit_codes import ERROR
from rigd.dataset import CameraKind, open_dataset
from rigd.errors import DatasetError
from rigd.importers.pairs import PairsOptions, PairsSource, import_pairs, match_pairs

SIZE = (24, 16)  # w, h
K = [20.0, 0.0, 11.5, 0.0, 20.5, 7.5, 0.0, 0.0, 1.0]
FISHEYE_INFO = {"distortion_model": "fisheye", "width": SIZE[0], "height": SIZE[1],
                "D": [-0.05, -0.08, 0.09, -0.05], "K": K}
# camera-in-LiDAR rows as the ACFR tool writes them: roll, pitch, yaw (rad), x, y, z (m); the last an outlier
ROWS = np.array([[-1.69, -0.02, -1.49, 0.06, 0.00, -0.19], [-1.70, -0.03, -1.50, 0.07, 0.01, -0.20],
                 [-1.68, -0.02, -1.48, 0.06, -0.01, -0.18], [-1.69, -0.01, -1.49, 0.05, 0.00, -0.19],
                 [-1.69, -0.02, -1.49, 0.06, 0.00, -0.19], [-1.20, 0.30, -1.10, 0.40, 0.30, 0.20]])


def _write_cloud(path: Path, seed: int, top_first: bool = False) -> None:
    """An ASCII PCD (x y z intensity ring) of 4 rings, 10 points each, ring 0 the lowest."""
    rng = np.random.default_rng(seed)
    rows = []
    for ring, elevation in enumerate((-3.0, -1.0, 1.0, 3.0)):
        azimuth = np.radians(np.linspace(0, 350, 10))
        r = rng.uniform(2.0, 9.0, 10)
        e = np.radians(elevation)
        rows += [(x, y, z, i, 3 - ring if top_first else ring) for x, y, z, i in
                 zip(r * np.cos(e) * np.cos(azimuth), r * np.cos(e) * np.sin(azimuth), r * np.sin(e) + 0.0 * r,
                     rng.integers(0, 200, 10), strict=True)]
    body = "\n".join(f"{x:.5f} {y:.5f} {z:.5f} {i} {g}" for x, y, z, i, g in rows)
    path.write_text("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity ring\nSIZE 4 4 4 4 2\nTYPE F F F F U\n"
                    f"COUNT 1 1 1 1 1\nWIDTH {len(rows)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(rows)}\n"
                    f"DATA ascii\n{body}\n")


def write_tree(root: Path, numbers: tuple[int, ...] = (1, 3, 10)) -> Path:
    (root / "images").mkdir(parents=True)
    (root / "pcd").mkdir()
    (root / "cfg").mkdir()
    for n in numbers:
        cv2.imwrite(str(root / "images" / f"pose{n}.png"), np.full((SIZE[1], SIZE[0], 3), 10 * n, np.uint8))
        _write_cloud(root / "pcd" / f"pose{n}_full.pcd", n)
        _write_cloud(root / "pcd" / f"pose{n}_target.pcd", 100 + n)
    (root / "cfg" / "camera_info.yaml").write_text(yaml.safe_dump(FISHEYE_INFO))
    np.savetxt(root / "calib.csv", ROWS, delimiter=",", header="roll,pitch,yaw,x,y,z", comments="")
    return root


def _import(src: Path, out: Path, *extra: str) -> int:
    return main(["import", "pairs", str(src / "images"), str(src / "pcd"), str(out), "--camera-info",
                 str(src / "cfg" / "camera_info.yaml"), "--cloud-glob", "*_full.pcd", *extra])


def test_acfr_layout_imports_with_its_reference_as_its_authors_define_it(tmp_path: Path) -> None:
    src = write_tree(tmp_path / "src")
    mask = np.full((SIZE[1], SIZE[0]), 255, np.uint8)
    mask[-3:] = 0  # the rig's own body
    cv2.imwrite(str(src / "mask.png"), mask)
    assert _import(src, tmp_path / "out", "--only", "10,1", "--reference", str(src / "calib.csv"),
                   "--reference-convention", "camera-in-lidar:rpy-rad-xyz", "--init", "1,-80,-60,0.01,-0.2,-0.1",
                   "--mask", str(src / "mask.png")) == 0
    ds = open_dataset(tmp_path / "out")
    camera = ds.rig.camera
    assert ds.rig.initial_guess is not None and ds.masks[0] is not None and not ds.masks[0][-1].any()
    np.testing.assert_allclose(ds.rig.initial_guess.translation_m, [0.01, -0.2, -0.1])
    assert camera.kind is CameraKind.FISHEYE and camera.K is not None and camera.D is not None
    np.testing.assert_allclose(camera.K.ravel(), K)
    np.testing.assert_allclose(camera.D, FISHEYE_INFO["D"])
    pairs = list(ds.pairs())
    assert [p.meta["key"] for p in pairs] == [10, 1] and pairs[0].meta["cloud"] == "pose10_full.pcd"
    assert int(pairs[1].image[0, 0, 0]) == 10 and pairs[0].cloud.ring is not None and len(pairs[0].cloud) == 40
    # the reference: the mean of the five rows within 2 std (the outlier dropped), p_camera = R^T (p_lidar - t)
    mean = ROWS[:5].mean(axis=0)
    R = Rotation.from_euler("xyz", mean[:3]).as_matrix()  # extrinsic x, y, z: Rz(yaw) Ry(pitch) Rx(roll)
    p_lidar = np.array([[3.0, 1.0, -0.5], [6.0, -2.0, 1.0]])
    assert ds.reference is not None and ds.reference.sigma is not None
    np.testing.assert_allclose(ds.reference.T_camera_lidar.apply(p_lidar), (p_lidar - mean[3:]) @ R, atol=1e-12)
    assert "5 of 6 rows" in ds.reference.source
    # its sigma: the kept rows' spread, per axis of the LiDAR in the reference's LiDAR frame
    rows = [Transform(Rotation.from_euler("xyz", row[:3]).as_matrix(), row[3:]).inverse() for row in ROWS[:5]]
    np.testing.assert_allclose(np.std([ds.reference.source_form(T) for T in rows], axis=0), ds.reference.sigma,
                               rtol=1e-9)
    np.testing.assert_allclose(ds.reference.source_form(ds.reference.T_camera_lidar), np.zeros(6), atol=1e-9)


LAYOUTS = {"rpy-rad-xyz": lambda r, t, q, m: [*r, *t], "rpy-deg-xyz": lambda r, t, q, m: [*np.degrees(r), *t],
           "xyz-rpy-rad": lambda r, t, q, m: [*t, *r], "xyz-rpy-deg": lambda r, t, q, m: [*t, *np.degrees(r)],
           "xyz-quat-xyzw": lambda r, t, q, m: [*t, *q], "matrix": lambda r, t, q, m: m}


@pytest.mark.parametrize("frame", ["camera-in-lidar", "lidar-in-camera"])
def test_every_convention_names_one_pose(tmp_path: Path, frame: str) -> None:
    from rigd.importers.reference_file import parse_convention, read_reference

    rpy, t = np.array([-1.7, 0.05, -1.4]), np.array([0.06, 0.01, -0.2])
    rotation = Rotation.from_euler("xyz", rpy)
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = rotation.as_matrix(), t
    expected = matrix if frame == "lidar-in-camera" else np.linalg.inv(matrix)
    for layout, row in LAYOUTS.items():
        path = tmp_path / f"{layout}.txt"
        values = np.asarray(row(rpy, t, rotation.as_quat(), matrix))
        np.savetxt(path, values.reshape(4, 4) if layout == "matrix" else values[None], delimiter=" ")
        reference = read_reference(path, parse_convention(f"{frame}:{layout}"))
        np.testing.assert_allclose(reference.T_camera_lidar.matrix, expected, atol=1e-12, err_msg=layout)
        assert reference.sigma is None


def test_references_written_otherwise_are_refused_by_name(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rigd.importers.reference_file import parse_convention, read_reference

    src = write_tree(tmp_path / "src", (1,))
    with pytest.raises(DatasetError, match="header names the columns roll, pitch, yaw, x, y, z; .* xyz-rpy-rad"):
        read_reference(src / "calib.csv", parse_convention("lidar-in-camera:xyz-rpy-rad"))
    with pytest.raises(DatasetError, match="'camera-in-lidar:ypr' is not one of .*lidar-in-camera:matrix"):
        parse_convention("camera-in-lidar:ypr")
    (src / "two.txt").write_text("1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n1 0 0 0\n")
    with pytest.raises(DatasetError, match="two.txt: a matrix reference is one 4x4"):
        read_reference(src / "two.txt", parse_convention("lidar-in-camera:matrix"))
    (src / "short.txt").write_text("0.1 0.2 0.3 1 2\n")
    with pytest.raises(DatasetError, match="short.txt: the rpy-deg-xyz layout needs rows of 6 numbers; data row 1"):
        read_reference(src / "short.txt", parse_convention("lidar-in-camera:rpy-deg-xyz"))
    assert _import(src, tmp_path / "out", "--reference", str(src / "calib.csv")) == ERROR
    assert "--reference and --reference-convention go together" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_files_without_a_partner_or_sharing_a_number_are_named(tmp_path: Path) -> None:
    src = write_tree(tmp_path / "src", (1, 2, 3))
    info = PairsOptions(src / "cfg" / "camera_info.yaml")
    both = PairsSource(src / "images", src / "pcd")
    with pytest.raises(DatasetError, match=r"pose1_full.pcd and .*pose1_target.pcd: two clouds numbered 1"):
        import_pairs(both, tmp_path / "a", info)
    (src / "images" / "pose2.png").unlink()
    (src / "pcd" / "pose7_full.pcd").write_text("")
    full = PairsSource(src / "images", src / "pcd", cloud_glob="*_full.pcd")
    with pytest.raises(DatasetError, match=r"2 files without a partner \(by the numbers in names\): pose2_full.pcd, "
                       "pose7_full.pcd"):
        import_pairs(full, tmp_path / "b", info)
    with pytest.raises(DatasetError, match="no image and cloud numbered 2"):
        import_pairs(full, tmp_path / "c", info, only=[1, 2])
    ordered = PairsSource(src / "images", src / "pcd", cloud_glob="*_full.pcd", by_order=True)
    with pytest.raises(DatasetError, match="in sorted order: the folders hold different counts"):
        match_pairs(ordered)
    assert [(k, i.name) for k, i, _ in match_pairs(ordered, only=[1])] == [(1, "pose3.png")]
    assert not any(p.exists() for p in (tmp_path / "a", tmp_path / "b", tmp_path / "c"))


def test_bad_files_are_named_before_a_pair_is_written(tmp_path: Path) -> None:
    src = write_tree(tmp_path / "src", (1, 2))
    source = PairsSource(src / "images", src / "pcd", cloud_glob="*_full.pcd")
    info = PairsOptions(src / "cfg" / "camera_info.yaml")
    cv2.imwrite(str(src / "images" / "pose2.png"), np.zeros((8, 8), np.uint8))
    with pytest.raises(DatasetError, match=r"pose2.png: image is 8x8, camera_info.yaml says 24x16"):
        import_pairs(source, tmp_path / "a", info)
    assert not (tmp_path / "a").exists()
    cv2.imwrite(str(src / "images" / "pose2.png"), np.zeros((SIZE[1], SIZE[0]), np.uint8))
    text = (src / "pcd" / "pose2_full.pcd").read_text()
    (src / "pcd" / "pose2_full.pcd").write_text(text[: len(text) // 2])
    with pytest.raises(DatasetError, match="pose2_full.pcd"):
        import_pairs(source, tmp_path / "b", info)
    _write_cloud(src / "pcd" / "pose2_full.pcd", 2, top_first=True)
    with pytest.raises(DatasetError, match="pose2_full.pcd: its rings are numbered from the top beam down"):
        import_pairs(source, tmp_path / "c", info)


@pytest.mark.parametrize(("info", "message"), [
    ({"image_width": 24, "image_height": 16, "distortion_model": "plumb_bob", "camera_matrix": {"data": K},
      "distortion_coefficients": {"data": [0.1, -0.2, 0.001, 0.002, 0.03]}}, None),
    ({**FISHEYE_INFO, "distortion_model": "rational_polynomial", "D": [0.1, -0.2, 0, 0, 0.03, 0.5, 0, 0]},
     "distortion model rational_polynomial with k4..k6 \\[0.5, 0.0, 0.0\\] is not supported"),
    ({**FISHEYE_INFO, "distortion_model": "kannala_brandt"}, "distortion model 'kannala_brandt' is not supported"),
    ({**FISHEYE_INFO, "D": [0.1, 0.2]}, "needs 4 distortion terms, got 2"),
    ({"distortion_model": "plumb_bob", "K": K, "D": []}, "camera_info has no width / image_width"),
])
def test_camera_info_models(tmp_path: Path, info: dict[str, object], message: str | None) -> None:
    from rigd.importers.camera_info import read_camera_info

    path = tmp_path / "camera_info.yaml"
    path.write_text(yaml.safe_dump(info))
    if message is not None:
        with pytest.raises(DatasetError, match=f"camera_info.yaml: .*{message}"):
            read_camera_info(path)
        return
    camera = read_camera_info(path)
    assert camera.kind is CameraKind.PINHOLE and camera.D is not None
    np.testing.assert_allclose(camera.D, [0.1, -0.2, 0.001, 0.002, 0.03])
