"""rigd check: exit 0 / 1 / 2 for ok / drifted / unknown, the extrinsics from a file, the store or rig.yaml."""

import json

import numpy as np
import pytest
import yaml

from calib.geometry import Transform
from rigd.cli import main
from rigd.dataset import open_dataset
from rigd.dataset.records import transform_to_yaml
from rigd.simulate import write_simulated_dataset
from rigd.store import Database, NewVersion, VersionStore


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("ds") / "outdoor"
    write_simulated_dataset(root, "outdoor", 3, seed=5, width=512, height=256, progress=False)
    return root


def _file(path, transform):
    path.write_text(yaml.safe_dump({"T_camera_lidar": transform_to_yaml(transform)}))
    return path


def test_a_drifted_calibration_exits_1_and_the_truth_does_not(dataset, tmp_path, capsys):
    truth = open_dataset(dataset).ground_truth
    moved = Transform.from_rpy_xyz(truth.rpy_deg + [0.0, 0.0, 1.5], truth.translation_m + [0.0, 0.06, 0.0])
    code = main(["check", str(dataset), "--against", str(_file(tmp_path / "moved.yaml", moved)), "--json",
                 "--threshold", "0.5,3"])
    report = json.loads(capsys.readouterr().out)
    assert code == 1 and report["status"] == "drifted" and report["reasons"]
    assert "yaw" in report["axes"] or "y" in report["axes"]
    code = main(["check", str(dataset), "--against", str(_file(tmp_path / "truth.yaml", truth)), "--json",
                 "--threshold", "0.5,3"])
    report = json.loads(capsys.readouterr().out)
    # Never "drifted" at zero error: 3 small pairs may let an axis wander (then "unknown"), not call it drift.
    assert code == {"ok": 0, "unknown": 2}[report["status"]]
    wandered = np.abs(report["change"]["rpy_deg"] + report["change"]["xyz_cm"]) > [0.5] * 3 + [3.0] * 3
    assert not wandered.any() or report["status"] == "unknown"


def test_version_from_the_store_and_missing_sources(dataset, tmp_path, capsys):
    truth = open_dataset(dataset).ground_truth
    db = Database(tmp_path / "data" / "rigd.db")
    VersionStore(db).add(NewVersion(truth, quality={}, method="manual", parameters={}, code_version="t"),
                         lambda change: False)
    db.close()
    code = main(["check", str(dataset), "--version", "1", "--data-dir", str(tmp_path / "data"), "--json"])
    assert code in (0, 2) and json.loads(capsys.readouterr().out)["checked"]["xyz_m"] == pytest.approx(
        truth.translation_m.tolist())
    assert main(["check", str(dataset), "--version", "9", "--data-dir", str(tmp_path / "data")]) == 2
    assert "9" in capsys.readouterr().err
    assert main(["check", str(dataset), "--version", "1", "--data-dir", str(tmp_path / "nothing")]) == 2
    assert "no rigd store" in capsys.readouterr().err
    assert main(["check", str(dataset)]) == 2  # simulated datasets carry no initial_guess
    assert "--against" in capsys.readouterr().err
