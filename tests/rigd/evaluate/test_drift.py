"""``rigd evaluate drift``: trials counted by the error injected into the ground truth, which it needs."""

import numpy as np
import pytest
import yaml

from rigd.cli import main
from rigd.cli.exit_codes import ERROR
from rigd.dataset import write_pair
from rigd.dataset.pcd import Cloud
from rigd.simulate import write_simulated_dataset


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("ds") / "outdoor"
    write_simulated_dataset(root, "outdoor", 3, seed=5, width=512, height=256, progress=False)
    return root


def test_drift_counts_every_trial_by_injected_error(dataset, tmp_path, capsys):
    code = main(["evaluate", "drift", str(dataset), "--trials", "6", "--workers", "1", "--rot-deg", "1",
                 "--trans-cm", "5", "--out", str(tmp_path)])
    assert code == 0
    report = yaml.safe_load((tmp_path / "drift.yaml").read_text())
    assert set(report["summary"]) == {"none", "rot 1 deg", "trans 5 cm"}
    for row in report["summary"].values():
        assert row["trials"] == 2 and row["ok"] + row["drifted"] + row["unknown"] + row["error"] == 2
        assert row["ok_share"] == row["ok"] / 2 and row["drifted_share"] == row["drifted"] / 2
    assert report["false_alarm_rate"] == report["summary"]["none"]["drifted_share"]
    assert report["ok_rate_at_zero_error"] == report["summary"]["none"]["ok_share"]
    assert [t["injected"] for t in report["trials"]] == ["none", "rot 1 deg", "trans 5 cm"] * 2
    # three places: too few to measure the uncertainty across them, so every check answers unknown
    assert {t["status"] for t in report["trials"]} == {"unknown"}
    assert "false alarms" in capsys.readouterr().out


def test_drift_on_random_subsets(dataset, tmp_path):
    code = main(["evaluate", "drift", str(dataset), "--trials", "3", "--workers", "1", "--rot-deg", "1",
                 "--trans-cm", "5", "--size", "2", "--threshold", "0.5,3", "--out", str(tmp_path)])
    assert code == 0
    report = yaml.safe_load((tmp_path / "drift.yaml").read_text())
    assert report["settings"]["size"] == 2
    assert report["settings"]["threshold_rot_deg"] == 0.5 and report["settings"]["threshold_trans_cm"] == 3.0
    pairs = [tuple(t["pairs"]) for t in report["trials"]]
    assert all(len(set(p)) == 2 and set(p) <= {0, 1, 2} for p in pairs)
    assert len(set(pairs)) > 1  # the subsets differ between trials


def test_drift_refuses_a_subset_larger_than_the_dataset(dataset, tmp_path, capsys):
    assert main(["evaluate", "drift", str(dataset), "--trials", "3", "--workers", "1", "--size", "4",
                 "--out", str(tmp_path)]) == ERROR
    assert "--size" in capsys.readouterr().err


def test_drift_needs_ground_truth(tmp_path, capsys):
    root = tmp_path / "real"
    (root / "pairs").mkdir(parents=True)
    (root / "rig.yaml").write_text(yaml.safe_dump({"camera": {"model": "equirectangular", "width": 64, "height": 32}}))
    write_pair(root, 0, np.zeros((32, 64), np.uint8), Cloud(np.ones((10, 3))), {})
    assert main(["evaluate", "drift", str(root), "--trials", "2", "--workers", "1"]) == ERROR
    assert "ground_truth.yaml" in capsys.readouterr().err
