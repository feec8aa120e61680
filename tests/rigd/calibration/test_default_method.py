"""The default method (rigd.calibration.request.resolve): NID with its assessment on a single pinhole camera when NID
can run (a start, clouds with intensity, no Gaussian prior), the GMM everywhere else, each choice with its reason;
rigd calibrate without --method reports the method it chose and why."""

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from calib.geometry import Transform
from calib.methods import Method, SolveRequest
from rigd.calibration.features import features_for
from rigd.calibration.request import CalibrationRequest, Decision, Options, PriorIn, Start, TransformIn, resolve
from rigd.cli import main
from rigd.cli.exit_codes import ERROR, Calibrate
from rigd.dataset import Dataset, open_dataset
from rigd.dataset.pcd import Cloud, read_pcd, write_pcd
from rigd.evaluate.trials import EvaluationSettings, open_for
from rigd.simulate import write_simulated_dataset
from tests.testdata import PINHOLE_FRAME


def _pinhole_dataset(root: Path, with_intensity: bool = True, flat: bool = False, every: int = 1) -> Path:
    """The real pinhole frame ours_3 as a one-pair dataset (its cloud with or without intensity, or with an
    intensity field of zeros: ``flat``; every ``every``-th point of it)."""
    calibration = yaml.safe_load((PINHOLE_FRAME / "calibration.yaml").read_text())
    (root / "pairs" / "0000").mkdir(parents=True)
    (root / "rig.yaml").write_text(yaml.safe_dump({"camera": calibration["camera"], "lidar": {"model": "64-ring"}}))
    (root / "ground_truth.yaml").write_text(yaml.safe_dump({"T_camera_lidar": calibration["T_camera_lidar"]}))
    shutil.copy(PINHOLE_FRAME / "image.jpg", root / "pairs" / "0000" / "image.jpg")
    cloud = read_pcd(PINHOLE_FRAME / "calib.pcd")
    assert cloud.intensity is not None
    if flat:
        cloud = Cloud(cloud.points_lidar, np.zeros(len(cloud), np.float32), cloud.ring)
    if every > 1:
        cloud = Cloud(cloud.points_lidar[::every], None if cloud.intensity is None else cloud.intensity[::every],
                      None if cloud.ring is None else cloud.ring[::every])
    write_pcd(root / "pairs" / "0000" / "cloud.pcd", cloud if with_intensity else Cloud(cloud.points_lidar))
    return root


@pytest.fixture(scope="module")
def pinhole(tmp_path_factory):
    # every 4th point: the method chosen and reported does not need the whole cloud, and NID's solves a quarter
    return _pinhole_dataset(tmp_path_factory.mktemp("pin") / "ours_3", every=4)


def _chosen(dataset: Dataset, start: Transform | None, **options: object) -> Decision:
    request = CalibrationRequest(dataset=dataset.root, start=Start.GIVEN if start else Start.SEARCH,
                                 initial=TransformIn.of(start) if start else None, options=Options(**options))
    return resolve(request, dataset).method_why


def test_a_pinhole_camera_with_a_start_is_solved_by_assessed_nid(pinhole, tmp_path):
    dataset = open_dataset(pinhole)
    start = dataset.ground_truth
    assert _chosen(dataset, start).choice == Method.NID_ASSESSED.value
    assert _chosen(dataset, start, fix_translation=True).choice == Method.NID_ASSESSED.value  # held, not weighed
    searched = _chosen(dataset, None)  # no start: the global search scores the GMM's edges
    assert searched.choice == Method.GMM.value and "searches for its start" in searched.why
    drawing = PriorIn(xyz_m=start.translation_m.tolist(), sigma_cm=1.0)
    weighed = _chosen(dataset, start, prior=drawing)  # a Gaussian prior weighs the GMM's likelihood
    assert weighed.choice == Method.GMM.value and "prior" in weighed.why
    no_intensity = open_dataset(_pinhole_dataset(tmp_path / "bare", with_intensity=False))
    assert "no intensity" in _chosen(no_intensity, start).why
    zeros = open_dataset(_pinhole_dataset(tmp_path / "zeros", flat=True))  # NID has nothing to align
    assert _chosen(zeros, start).choice == Method.GMM.value
    asked = _chosen(dataset, start, method=Method.GMM)
    assert asked == Decision(Method.GMM.value, "asked for")


def test_nid_assessed_reads_the_edges_for_its_second_opinion(pinhole):
    dataset = open_dataset(pinhole)
    solve = SolveRequest(method=Method.NID_ASSESSED, initial=dataset.ground_truth)
    features = features_for(dataset, solve)
    assert features.photo is not None and features.gmm is not None and len(features.gmm) == 1
    assert features.search_photo is None  # a start is given: no global search


def test_a_panorama_keeps_the_gmm(tmp_path):
    root = write_simulated_dataset(tmp_path / "pano", "indoor", 1, seed=5, width=256, height=128, progress=False)
    dataset = open_dataset(root)
    assert dataset.ground_truth is not None
    assert _chosen(dataset, dataset.ground_truth).choice == Method.GMM.value
    assert open_for(EvaluationSettings(CalibrationRequest(dataset=root)))[1].solve.method is Method.GMM


def test_the_evaluation_protocols_run_what_calibrate_picks(pinhole):
    assert open_for(EvaluationSettings(CalibrationRequest(dataset=pinhole)))[1].solve.method is Method.NID_ASSESSED
    asked = CalibrationRequest(dataset=pinhole, options=Options(method=Method.GMM))
    assert open_for(EvaluationSettings(asked))[1].solve.method is Method.GMM


def test_calibrate_without_a_method_reports_the_one_it_chose(pinhole, tmp_path, capsys):
    truth = open_dataset(pinhole).ground_truth
    start = Transform.from_rpy_xyz(truth.rpy_deg + [0.5, -0.5, 0.5], truth.translation_m + [0.02, -0.02, 0.02])
    init = ",".join(f"{v:.6f}" for v in [*start.rpy_deg, *start.translation_m])
    out = tmp_path / "out"
    code = main(["calibrate", str(pinhole), "--init", init, "--no-visuals", "--max-width", "480", "--out", str(out)])
    assert code in (Calibrate.TRUSTED, Calibrate.WEAK, Calibrate.FAILED), capsys.readouterr().err  # any verdict
    report = yaml.safe_load((out / "extrinsics.yaml").read_text())
    assert report["method"]["name"] == "nid-assessed" and "default on one pinhole camera" in report["method"]["why"]
    assert report["verdict"]["status"] != "not_assessed"
    assert "cross_check" in report["uncertainty"]  # null here: the edges run beyond the restarts' reach
    assert "method: nid-assessed (the default on one pinhole camera" in capsys.readouterr().out


def test_an_elevation_fit_on_one_pinhole_camera_is_refused_by_name(pinhole, tmp_path, capsys):
    code = main(["calibrate", str(pinhole), "--fit-elevation-offset", "--no-visuals", "--out", str(tmp_path / "o")])
    assert code == ERROR
    assert "one pinhole camera cannot tell it from a tilt: declare it in rig.yaml" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # refused before any work
