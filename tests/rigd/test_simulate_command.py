"""``rigd simulate``: the written dataset reads back (in a fresh process) as the simulator made it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rigd.simulate
from drivers.sim import PinholeSpec, SimConfig, simulate_pair
from rigd.cli import main
from rigd.cli.exit_codes import ERROR, USAGE
from rigd.dataset import CameraKind, open_dataset

REPO = Path(__file__).resolve().parents[2]

_LOADER = """
import sys
import numpy as np
from rigd.dataset import open_dataset
ds = open_dataset(sys.argv[1])
arrays = {}
for pair in ds.pairs():
    arrays[f"image{pair.index}"] = pair.image
    arrays[f"points{pair.index}"] = pair.cloud.points_lidar
    arrays[f"intensity{pair.index}"] = pair.cloud.intensity
    arrays[f"ring{pair.index}"] = pair.cloud.ring
arrays["truth"] = ds.ground_truth.matrix
np.savez(sys.argv[2], **arrays)
"""


def test_simulate_writes_a_dataset_that_reads_back_in_a_fresh_process(tmp_path):
    out = tmp_path / "sim"
    args = ["simulate", str(out), "--scene", "outdoor", "--pairs", "2", "--seed", "5", "--width", "256",
            "--height", "128", "--noise-m", "0.01"]
    assert main(args) == 0
    dump = tmp_path / "loaded.npz"
    subprocess.run([sys.executable, "-c", _LOADER, str(out), str(dump)], check=True, cwd=REPO)
    loaded = np.load(dump)
    for index in range(2):
        image, sweep, meta = simulate_pair("outdoor", 5, index, 256, 128, range_noise_m=0.01)
        assert loaded[f"image{index}"].tobytes() == image.tobytes()
        np.testing.assert_array_equal(loaded[f"points{index}"], sweep.points_lidar.astype(np.float32))
        np.testing.assert_array_equal(loaded[f"intensity{index}"], sweep.intensity)
        np.testing.assert_array_equal(loaded[f"ring{index}"], sweep.ring)
    np.testing.assert_allclose(loaded["truth"], SimConfig().T_camera_lidar.matrix, atol=1e-12)
    dataset = open_dataset(out)
    assert dataset.rig.camera.kind is CameraKind.EQUIRECTANGULAR
    assert (dataset.rig.camera.width, dataset.rig.camera.height) == (256, 128)
    assert dataset.rig.lidar_elevation_sigma_deg == 0.0  # the simulated beams are where the table says
    meta = dataset.load_pair(1).meta
    assert (meta["scene"], meta["seed"], meta["index"]) == ("outdoor", 5, 1)
    assert "T_world_camera" in meta and "T_world_lidar" in meta


def test_simulate_refuses_a_non_empty_directory(tmp_path, capsys):
    out = tmp_path / "taken"
    out.mkdir()
    (out / "notes.txt").write_text("someone's data")
    assert main(["simulate", str(out), "--pairs", "1", "--width", "64"]) == ERROR
    err = capsys.readouterr().err
    assert "rigd: error:" in err and "refusing to overwrite" in err and str(out) in err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_simulate_rejects_bad_arguments(tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(tmp_path / "a"), "--scene", "forest"])
    assert exc.value.code == USAGE
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(tmp_path / "b"), "--pairs", "0"])
    assert exc.value.code == USAGE
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def _without_and_with(tmp_path, scene, flag):
    """Pair 0 of seed 3 simulated without and with ``flag``."""
    common = ["--scene", scene, "--pairs", "1", "--seed", "3", "--width", "256"]
    out = []
    for name, extra in (("plain", []), ("flagged", [flag])):
        assert main(["simulate", str(tmp_path / name), *common, *extra]) == 0
        out.append(open_dataset(tmp_path / name).load_pair(0))
    return out


def test_simulate_sensor_effects_are_recorded_and_change_the_data(tmp_path):
    a, b = _without_and_with(tmp_path, "indoor", "--sensor-effects")
    assert "stitched_sensors" not in a.meta and "beam_footprint" not in a.meta
    assert b.meta["stitched_sensors"]["sphere_radius_m"] == 20.0 and b.meta["jpeg_quality"] == 85
    assert b.meta["beam_footprint"]["divergence_mrad"] == 3.0
    # Same place and scene: the clouds differ only at depth edges, the images everywhere a little.
    moved = np.linalg.norm(a.cloud.points_lidar - b.cloud.points_lidar, axis=1) > 0.05
    assert 0 < np.count_nonzero(moved) < 0.05 * len(moved)
    assert np.abs(a.image.astype(int) - b.image.astype(int)).mean() > 1.0


def test_simulate_dropouts_are_recorded_and_only_remove_returns(tmp_path):
    a, b = _without_and_with(tmp_path, "outdoor", "--dropouts")
    assert "lidar_detection" not in a.meta and b.meta["lidar_detection"]["detect_range_m"] == 60.0
    # The same draws otherwise: every return with dropouts is one without them; the far road lost some.
    kept = {tuple(p) for p in np.round(a.cloud.points_lidar, 6)}
    assert all(tuple(p) in kept for p in np.round(b.cloud.points_lidar, 6))
    lost = len(a.cloud.points_lidar) - len(b.cloud.points_lidar)
    assert 0.01 * len(a.cloud.points_lidar) < lost
    np.testing.assert_array_equal(a.image, b.image)


def test_simulate_trees_are_recorded_and_add_to_the_same_place(tmp_path):
    a, b = _without_and_with(tmp_path, "outdoor", "--trees")
    assert "trees" not in a.meta and b.meta["trees"] is True
    # The rig stands where it stood without them; the trees only add returns and shade.
    assert a.meta["T_world_camera"] == b.meta["T_world_camera"]
    assert not np.array_equal(a.image, b.image)


def test_simulate_trees_indoors_is_refused(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "d"), "--scene", "indoor", "--trees", "--pairs", "1"]) == ERROR
    assert "--trees needs --scene outdoor" in capsys.readouterr().err


def test_simulate_a_pinhole_rig_writes_a_pinhole_dataset(tmp_path, monkeypatch):
    small = PinholeSpec(np.array([[150.0, 0.0, 95.5], [0.0, 150.0, 59.5], [0.0, 0.0, 1.0]]), 192, 120)
    monkeypatch.setattr(rigd.simulate, "PINHOLE", small)
    assert main(["simulate", str(tmp_path / "p"), "--scene", "indoor", "--pairs", "1", "--camera", "pinhole"]) == 0
    dataset = open_dataset(tmp_path / "p")
    assert dataset.rig.camera.kind is CameraKind.PINHOLE and dataset.load_pair(0).image.shape[:2] == (120, 192)
    np.testing.assert_allclose(dataset.rig.camera.K, small.K)
    # The LiDAR stands level above the camera: its forward axis is the optical z, its up the optical -y.
    R = dataset.ground_truth.rotation
    assert R[2, 0] > 0.99 and R[1, 2] < -0.99
    assert dataset.ground_truth.translation_m[1] < -0.3  # 0.35 m up is optical -y


def test_simulate_a_64_ring_lidar_is_recorded(tmp_path):
    assert main(["simulate", str(tmp_path / "d"), "--scene", "indoor", "--pairs", "1", "--width", "256",
                 "--lidar", "64"]) == 0
    dataset = open_dataset(tmp_path / "d")
    pair = dataset.load_pair(0)
    assert dataset.rig.lidar_model == "64-ring" and len(pair.meta["lidar_elevations_deg"]) == 64
    assert pair.cloud.ring.max() > 16
