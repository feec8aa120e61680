"""The commands on a multi-camera head: simulate a head, calibrate it (overlays per sensor), check and the
photometric baseline, each through the CLI as a user runs them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from calib.camera import Mounted
from drivers.sim import ladybug_like_head
from rigd.cli import main
from rigd.dataset import open_dataset
from rigd.dataset.records import HeadConfig
from rigd.evaluate.trials import of_pairs


@pytest.fixture(scope="module")
def head_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("head") / "outdoor"
    assert main(["simulate", str(root), "--scene", "outdoor", "--pairs", "3", "--seed", "5", "--camera", "head",
                 "--width", "230"]) == 0  # 230 x 192 px: 192 px across the horizontal, as before
    return root


def test_a_simulated_head_is_five_sensors_of_a_ladybug5(head_dataset: Path) -> None:
    ds = open_dataset(head_dataset)
    assert isinstance(ds.rig.camera, HeadConfig) and ds.views == ("cam0", "cam1", "cam2", "cam3", "cam4")
    sizes = [(s.height, s.width) for s in ladybug_like_head(230)]
    assert [im.shape[:2] for im in ds.load_pair(0).images] == sizes == [(192, 230)] * 5  # a Ladybug5's aspect
    cams = ds.rig.camera.models()
    assert all(isinstance(c, Mounted) for c in cams)
    # Each sensor sees the direction at its azimuth, -72 deg * k, at its principal point, and lies on its side as a
    # Ladybug5's does: what is above that direction is towards its first columns, on the same row.
    for k, (cam, (height, width)) in enumerate(zip(cams, sizes, strict=True)):
        ahead = 20.0 * np.array([np.cos(np.radians(-72.0 * k)), np.sin(np.radians(-72.0 * k)), 0.0])
        uv, valid = cam.project(np.array([ahead, ahead + [0.0, 0.0, 2.0]]))
        assert valid.all() and np.allclose(uv[0], [(width - 1) / 2, (height - 1) / 2], atol=1e-6)
        assert uv[1, 0] < uv[0, 0] - 10 and uv[1, 1] == pytest.approx(uv[0, 1], abs=1e-6)


def test_calibrate_a_head_writes_each_sensors_overlays_and_finds_the_truth(head_dataset: Path, tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    truth = open_dataset(head_dataset).ground_truth
    assert truth is not None
    init = np.r_[truth.rpy_deg + [1.5, -1.0, 2.0], truth.translation_m + [0.03, -0.02, 0.02]]
    # --workers 1: the same numbers as the pool's (tests/rigd/calibration/test_pool.py) for half the CPU
    code = main(["calibrate", str(head_dataset), "--init", ",".join(map(str, init)), "--out", str(tmp_path / "c"),
                 "--json", "--workers", "1"])
    report = json.loads(capsys.readouterr().out)
    assert code == {"trusted": 0, "weak": 3, "failed": 4}[report["verdict"]["status"]]
    err = report["error_vs_ground_truth"]
    assert err["rotation_deg"] < 0.3 and err["translation_cm"] < 3.0
    overlays = sorted(p.name for p in (tmp_path / "c" / "overlays").iterdir())
    assert "0002_cam4_closeup.png" in overlays and "0000_cloud.png" in overlays
    assert len([n for n in overlays if n.endswith("_after.png")]) == 3 * 5
    pair = report["quality"]["pairs"][0]
    assert set(pair["edge_pixels_per_sensor"]) == {f"cam{k}" for k in range(5)}
    assert pair["edge_pixels"] == sum(pair["edge_pixels_per_sensor"].values())
    check = main(["check", str(head_dataset), "--against", str(tmp_path / "c" / "extrinsics.yaml")])
    assert check in (0, 2)  # right extrinsics: ok, or unknown from three small places; never drifted


def test_the_photometric_baseline_runs_on_a_head(head_dataset: Path, tmp_path: Path) -> None:
    assert main(["evaluate", "convergence", str(head_dataset), "--method", "nid", "--trials", "1", "--rot-deg", "0.5",
                 "--trans-m", "0.01", "--workers", "1", "--out", str(tmp_path / "n")]) == 0
    report = yaml.safe_load((tmp_path / "n" / "convergence.yaml").read_text())
    assert report["settings"]["method"] == "nid" and report["runs"][0]["verdict"] is None  # a baseline: not assessed
    assert report["summary"]["error_vs_ground_truth"]["run_median"]["rotation_deg"] < 3.0


def test_a_subset_of_pairs_takes_every_view_of_each() -> None:
    views_by_pair = [f"v{v}p{p}" for v in range(3) for p in range(4)]  # 4 pairs, 3 views, view by view
    assert of_pairs(views_by_pair, 4, [1, 3]) == ["v0p1", "v0p3", "v1p1", "v1p3", "v2p1", "v2p3"]
    assert of_pairs(["a", "b"], 2, [1]) == ["b"]  # one camera


def test_the_convergence_protocol_solves_with_every_sensor(head_dataset: Path, tmp_path: Path) -> None:
    assert main(["evaluate", "convergence", str(head_dataset), "--trials", "2", "--rot-deg", "2", "--trans-m",
                 "0.03", "--workers", "1", "--no-uncertainty", "--out", str(tmp_path / "e")]) == 0
    report = yaml.safe_load((tmp_path / "e" / "convergence.yaml").read_text())
    assert report["summary"]["error_vs_ground_truth"]["run_median"]["rotation_deg"] < 0.3
