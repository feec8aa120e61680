"""``rigd evaluate convergence|precision``: files and keys written, seeds honoured, results independent of the
number of workers."""

import shutil

import numpy as np
import pytest
import yaml

from calib.assess import TrustOptions
from calib.evaluate import random_starts, random_subsets, run_stats
from calib.geometry import Transform
from calib.methods import Method, SolveRequest, solve
from rigd.calibration.features import dataset_photo_pairs
from rigd.cli import main
from rigd.cli.exit_codes import ERROR
from rigd.dataset import open_dataset, write_pair
from rigd.dataset.pcd import Cloud
from rigd.dataset.thin import ThinOptions, thin_dataset
from rigd.dataset.working import WORKING_WIDTH_PX
from rigd.evaluate.protocols import std_not_failed
from rigd.evaluate.trials import Run

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SUMMARY_KEYS = {"runs", "finished", "converged", "converged_percent", "outlier_rule", "median", "mean", "std",
                "std_converged", "solution", "calibration_time_s"}


def _convergence(dataset, out, workers, capsys):
    # Two levels of the ladder: what is checked is the report, the starts and the workers' independence
    code = main(["evaluate", "convergence", str(dataset), "--trials", "2", "--seed", "4", "--workers", str(workers),
                 "--out", str(out), "--sigmas-deg", "3.5,1.8"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return yaml.safe_load((out / "convergence.yaml").read_text()), captured.out


def test_convergence_report_plot_and_worker_independence(small_dataset, tmp_path, capsys):
    one, printed = _convergence(small_dataset, tmp_path / "w1", 1, capsys)
    two, _ = _convergence(small_dataset, tmp_path / "w2", 2, capsys)
    assert "converged:" in printed and "convergence.yaml" in printed
    assert one["protocol"] == "convergence" and one["settings"]["trials"] == 2 and one["settings"]["seed"] == 4
    assert one["reference"]["source"] == "ground_truth"
    assert SUMMARY_KEYS | {"error_vs_ground_truth"} <= set(one["summary"])
    # With two runs the median is their midpoint: whether either converged depends on the optimiser, not on us.
    assert set(one["summary"]["error_vs_ground_truth"]) == {"solution", "run_median"}
    assert len(one["runs"]) == 2 and all(r["result"] is not None for r in one["runs"])
    assert (tmp_path / "w1" / "convergence.png").read_bytes().startswith(PNG_MAGIC)
    # The starts are calib.evaluate's draws around the ground truth for the seed (a panorama: roll, pitch, yaw).
    assert one["settings"]["start_axes"] == "rpy"
    truth = open_dataset(small_dataset).ground_truth
    expected = random_starts(truth, 2, 5.0, 0.1, seed=4)
    for run, start in zip(one["runs"], expected, strict=True):
        assert np.allclose(run["start"]["rpy_deg"], start.rpy_deg) and np.allclose(run["start"]["xyz_m"],
                                                                                    start.translation_m)
    # A calibration is deterministic: splitting the runs over processes must not change any of them.
    assert [r["index"] for r in two["runs"]] == [0, 1]
    for a, b in zip(one["runs"], two["runs"], strict=True):
        assert np.allclose(a["result"]["rpy_deg"], b["result"]["rpy_deg"], atol=1e-9)
        assert np.allclose(a["result"]["xyz_m"], b["result"]["xyz_m"], atol=1e-12)
    assert one["summary"]["converged"] == two["summary"]["converged"]


def test_precision_report_uses_the_seeded_subsets(small_dataset, tmp_path, capsys):
    out = tmp_path / "prec"
    # one worker: each extracts the features (a process and ~1 s more); the workers' independence is the
    # convergence test's
    code = main(["evaluate", "precision", str(small_dataset), "--subsets", "3", "--size", "1", "--seed", "2",
                 "--workers", "1", "--out", str(out), "--sigmas-deg", "3.5,1.8"])
    assert code == 0, capsys.readouterr().err
    report = yaml.safe_load((out / "precision.yaml").read_text())
    assert report["protocol"] == "precision" and report["settings"]["start"] == "ground_truth"
    assert report["settings"]["sigmas_deg"] == [3.5, 1.8]
    assert [tuple(r["pairs"]) for r in report["runs"]] == list(random_subsets(2, 1, 3, seed=2))
    assert SUMMARY_KEYS | {"error_vs_ground_truth"} <= set(report["summary"])
    assert report["summary"]["runs"] == 3
    assert (out / "precision.png").read_bytes().startswith(PNG_MAGIC)


def test_without_ground_truth_the_reference_is_a_first_calibration(small_dataset, tmp_path, capsys):
    root = tmp_path / "no_truth"
    shutil.copytree(small_dataset, root)
    (root / "ground_truth.yaml").unlink()
    assert main(["evaluate", "convergence", str(root), "--trials", "1", "--workers", "1"]) == ERROR
    assert "--init" in capsys.readouterr().err
    truth = open_dataset(small_dataset).ground_truth
    init = ",".join(str(v) for v in np.r_[truth.rpy_deg + 0.5, truth.translation_m + 0.01])
    assert main(["evaluate", "convergence", str(root), "--trials", "1", "--workers", "1", "--init", init]) == 0
    report = yaml.safe_load((root / "evaluation" / "convergence.yaml").read_text())
    assert report["reference"]["source"] == "calibration"
    assert "error_vs_ground_truth" not in report["summary"]


def test_featureless_dataset_reports_the_worker_error(small_dataset, tmp_path, capsys):
    root = tmp_path / "blank"
    (root / "pairs").mkdir(parents=True)
    (root / "rig.yaml").write_text((small_dataset / "rig.yaml").read_text())
    (root / "ground_truth.yaml").write_text((small_dataset / "ground_truth.yaml").read_text())
    pts = np.random.default_rng(0).normal(size=(500, 3)) + [5.0, 0.0, 0.0]
    write_pair(root, 0, np.full((256, 512), 128, np.uint8), Cloud(pts), {})
    assert main(["evaluate", "convergence", str(root), "--trials", "2", "--workers", "1"]) == ERROR
    assert "featureless" in capsys.readouterr().err


def test_bad_settings_are_refused(small_dataset, capsys):
    assert main(["evaluate", "precision", str(small_dataset), "--size", "3"]) == ERROR
    assert "subset size" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["evaluate", "convergence", str(small_dataset), "--workers", "0"])


def test_the_runs_use_the_rig_file_prior_as_calibrate_does(small_dataset, tmp_path, capsys):
    root = tmp_path / "with_prior"
    shutil.copytree(small_dataset, root)
    truth = open_dataset(small_dataset).ground_truth
    lever_arm = truth.translation_m + [0.05, -0.04, 0.03]  # a drawing 7 cm off, held to 1 mm
    rig = yaml.safe_load((root / "rig.yaml").read_text())
    rig["prior"] = {"xyz_m": [float(v) for v in lever_arm], "sigma_cm": 0.1}
    (root / "rig.yaml").write_text(yaml.safe_dump(rig))
    report, printed = _convergence(root, tmp_path / "out", 1, capsys)
    assert report["settings"]["prior"]["xyz_m"] == pytest.approx(list(lever_arm))
    assert "with rig.yaml's prior" in printed
    for run in report["runs"]:
        assert np.linalg.norm(np.array(run["result"]["xyz_m"]) - lever_arm) < 0.005


def test_a_method_is_evaluated_as_calibrate_runs_it(small_dataset, tmp_path, capsys):
    sparse = tmp_path / "sparse"  # every fifth ring, a point per 0.6 deg: NID's solves on a tenth of the points
    thin_dataset(small_dataset, sparse, ThinOptions(ring_spacing_deg=10.0, azimuth_step_deg=0.6))
    out = tmp_path / "nid"
    code = main(["evaluate", "convergence", str(sparse), "--trials", "1", "--seed", "2", "--workers", "1",
                 "--rot-deg", "1", "--trans-m", "0.02", "--out", str(out), "--method", "nid-assessed"])
    assert code == 0, capsys.readouterr().err
    report = yaml.safe_load((out / "convergence.yaml").read_text())
    assert report["settings"]["method"] == "nid-assessed" and "sigmas_deg" not in report["settings"]
    assert "uncertainty_check" in report["summary"]  # the method is assessed: its sigmas are checked
    dataset = open_dataset(sparse, WORKING_WIDTH_PX)
    (start,) = random_starts(dataset.ground_truth, 1, 1.0, 0.02, seed=2)
    photo = dataset_photo_pairs(dataset, Method.NID_ASSESSED.spec.photo, None)
    direct = solve(SolveRequest(method=Method.NID_ASSESSED, initial=start, trust=TrustOptions()), photo=photo)
    (run,) = report["runs"]
    assert direct.assessment is not None and run["verdict"] == direct.assessment.verdict.status.value
    assert np.allclose(run["result"]["rpy_deg"], direct.T_camera_lidar.rpy_deg, atol=1e-9)
    assert np.allclose(run["result"]["xyz_m"], direct.T_camera_lidar.translation_m, atol=1e-12)


def test_the_spread_of_the_results_a_user_is_given_leaves_out_failed_runs():
    """Five-place subsets of a real head: the runs rigd fails (not to be used) carry most of the spread, so the
    report also gives the std of the trusted and weak ones; without verdicts (a baseline) there is none."""
    ref = Transform.from_rpy_xyz(np.zeros(3), np.zeros(3))
    z_cm = [0.0, 1.0, 2.0, 30.0, -30.0]
    verdicts = ["weak", "trusted", "weak", "failed", "failed"]
    runs = [Run(i, (i,), ref, Transform.from_rpy_xyz(np.zeros(3), np.array([0.0, 0.0, z / 100])), None, 0.0, 1, 1.0,
                verdict=v) for i, (z, v) in enumerate(zip(z_cm, verdicts, strict=True))]
    stats = run_stats(ref, [r.result for r in runs])
    usable = std_not_failed(stats, runs)
    assert usable is not None and usable.z_m == pytest.approx(0.01)  # std of 0, 1, 2 cm
    assert stats.std is not None and stats.std.z_m > 0.2  # the failed runs' 30 cm
    baseline = [Run(r.index, r.pairs, r.start, r.result, None, 0.0, 1, 1.0, verdict="not_assessed") for r in runs]
    assert std_not_failed(stats, baseline) is None


def test_an_earlier_runs_report_is_not_written_over_unless_told(small_dataset, tmp_path, capsys):
    """Refused at once, before any run (exit 73), and the earlier report kept; compare likewise."""
    from rigd.cli.exit_codes import CANT_CREATE

    out = tmp_path / "eval"
    out.mkdir()
    (out / "convergence.yaml").write_text("an earlier run's report\n")
    assert main(["evaluate", "convergence", str(small_dataset), "--trials", "1", "--out", str(out)]) == CANT_CREATE
    assert "convergence.yaml: exists already" in capsys.readouterr().err
    assert (out / "convergence.yaml").read_text() == "an earlier run's report\n"
    (out / "compare.md").write_text("an earlier table\n")
    assert main(["evaluate", "compare", str(small_dataset), "--methods", "gmm", "--out", str(out)]) == CANT_CREATE
