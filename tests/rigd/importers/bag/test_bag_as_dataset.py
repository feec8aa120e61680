"""rigd calibrate / rigd check given a bag as DATASET (rigd/cli/bag_input.py): imported into a temporary dataset
(removed after, or kept with --keep-dataset), clear errors for a bag without its topics and for topics given with a
dataset folder. The calibration itself is replaced by a stand-in that records what it was given (a real one takes
too long here; tests/rigd/calibration covers it); the check runs for real on the bag's two places."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml

import rigd.cli.calibrate as calibrate_cli
from rigd.cli import main
from rigd.cli.bag_input import DatasetInput, is_bag
from rigd.cli.exit_codes import ERROR
from rigd.dataset import open_dataset
from rigd.errors import RigdError
from tests.rigd.importers.bag.bags import BagFormat, Recording, bag_file, stops, write_bag


@pytest.fixture(scope="module")
def recording() -> Recording:
    return stops(yaws_deg=[0.0, 90.0], still_sweeps=45, move_sweeps=8)  # 2.25 s stops: the default 2 s hold


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory, recording: Recording) -> Path:
    return write_bag(tmp_path_factory.mktemp("bag") / "run", BagFormat.MCAP, recording)


def _topics(recording: Recording) -> list[str]:
    return ["--image-topic", recording.image_topic, "--cloud-topic", recording.cloud_topic, "--camera-info-topic",
            recording.info_topic]


class _Stop(RigdError):
    """Raised by the stand-in calibration once it has seen its request."""


def _stand_in(seen: dict[str, Any]) -> Any:
    def run_calibration(request: Any, *_: Any) -> Any:
        dataset = open_dataset(request.dataset)
        seen.update(dataset=request.dataset, out=request.out_dir, pairs=len(dataset), kind=dataset.rig.camera.kind)
        raise _Stop("stand-in calibration")
    return run_calibration


def test_is_bag(tmp_path: Path, bag: Path) -> None:
    assert is_bag(bag) and is_bag(bag_file(bag, BagFormat.MCAP)) and is_bag(tmp_path / "run.bag")
    assert not is_bag(tmp_path) and not is_bag(tmp_path / "dataset")


def test_calibrate_imports_into_a_temporary_dataset(tmp_path: Path, bag: Path, recording: Recording,
                                                    monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    seen: dict[str, Any] = {}
    monkeypatch.setattr(calibrate_cli, "run_calibration", _stand_in(seen))
    code = main(["calibrate", str(bag), *_topics(recording)])
    err = capsys.readouterr().err
    assert code == ERROR and "stand-in calibration" in err
    assert seen["pairs"] == 2 and seen["kind"].value == "pinhole"  # the bag's two stops, CameraInfo's camera
    assert "kept as pair 0001" in err  # the import's report goes to stderr (stdout may be --json)
    assert not seen["dataset"].exists()  # the temporary dataset is gone
    # beside the bag, not inside the vanished dataset: written to a temporary name there, then put in place
    assert seen["out"].parent == bag.parent and seen["out"].name.startswith(".run_calibration.")


def test_bag_needs_its_topics(tmp_path: Path, bag: Path, recording: Recording,
                              capsys: pytest.CaptureFixture[str]) -> None:
    for command in ("calibrate", "check"):
        assert main([command, str(bag), "--cloud-topic", recording.cloud_topic]) == ERROR
        err = capsys.readouterr().err
        assert err.startswith("rigd: error: ") and "--image-topic" in err and "--cloud-topic" not in err.split("(")[0]
        assert recording.image_topic in err  # the bag's topics, to choose from


def test_topics_refused_for_a_dataset_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "dataset"
    folder.mkdir()
    for command in ("calibrate", "check"):
        assert main([command, str(folder), "--image-topic", "/camera", "--keep-dataset", str(tmp_path / "k")]) == ERROR
        err = capsys.readouterr().err
        assert "a dataset folder, not a bag" in err and "--image-topic, --keep-dataset" in err


def test_check_runs_on_the_kept_dataset(tmp_path: Path, bag: Path, recording: Recording,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    against = tmp_path / "extrinsics.yaml"
    against.write_text(yaml.safe_dump({"T_camera_lidar": {"rpy_deg": [-90.0, 0.0, -90.0], "xyz_m": [0.0, 0.0, 0.0]}}))
    kept = tmp_path / "kept"
    code = main(["check", str(bag), *_topics(recording), "--against", str(against), "--keep-dataset", str(kept)])
    out = capsys.readouterr().out
    assert code == 2 and "status: UNKNOWN" in out and "2 pairs at 2 places" in out  # fewer than 4 places
    assert len(open_dataset(kept)) == 2
    frames = yaml.safe_load((kept / "bag.yaml").read_text())["frames"]
    assert frames == {"camera": recording.camera_frame, "lidar": recording.lidar_frame}


def test_a_missing_bag_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "gone.mcap"
    assert main(["calibrate", str(missing), "--image-topic", "/a", "--cloud-topic", "/b"]) == ERROR
    assert f"{missing}: bag does not exist" in capsys.readouterr().err


def test_export_names_the_bag_frames_after_the_temporary_dataset_is_gone(tmp_path: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    dataset, out = tmp_path / "tmp-dataset", tmp_path / "run_calibration"
    dataset.mkdir()
    out.mkdir()
    (dataset / "bag.yaml").write_text(yaml.safe_dump({"frames": {"camera": "cam_optical", "lidar": "vlp16"}}))
    (out / "extrinsics.yaml").write_text(yaml.safe_dump({"dataset": str(dataset), "T_camera_lidar": {
        "rpy_deg": [-90.0, 0.0, -90.0], "xyz_m": [0.1, 0.0, -0.2]}}))
    input_ = DatasetInput(dataset, tmp_path / "run.mcap", temporary=True)
    assert input_.default_out("calibration") == out
    input_.record_bag(out)
    shutil.rmtree(dataset)
    assert main(["export", str(out), "--format", "ros-tf"]) == 0
    tf = yaml.safe_load(capsys.readouterr().out)
    assert (tf["header"]["frame_id"], tf["child_frame_id"]) == ("cam_optical", "vlp16")


def test_a_vlp16s_clouds_without_their_lasers_offsets_get_them_on_load(tmp_path: Path, bag: Path,
                                                                      recording: Recording,
                                                                      monkeypatch: pytest.MonkeyPatch,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """Clouds a ROS driver decoded without the VLP-16's vertical offsets (detection: tests/rigd/dataset/test_lasers.py):
    the import says so and rig.yaml adds them as each cloud is loaded."""
    import rigd.importers.bag.importer as importer
    from rigd.dataset.lasers import VerticalOffsets

    monkeypatch.setattr(importer, "lacks_vertical_offsets", lambda cloud: True)
    assert main(["import", "bag", str(bag), str(tmp_path / "d"), *_topics(recording)]) == 0
    assert "lack its lasers' vertical offsets" in capsys.readouterr().out
    assert open_dataset(tmp_path / "d").rig.lidar_vertical_offsets is VerticalOffsets.MANUAL
