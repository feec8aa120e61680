"""rigd import bag end to end on small bags written here (tests/rigd/importers/bag/bags.py): a rig turning between
stops yields a pair per new stop in all three formats; bad input gives a clear error and exit 2."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from rigd.cli import main
from rigd.cli.exit_codes import ERROR
from rigd.dataset import open_dataset
from rigd.importers.bag import BagError, BagImportOptions, import_bag
from rigd.importers.bag.stills import StillOptions, Verdict
from tests.rigd.importers.bag.bags import BagFormat, Recording, bag_file, pinhole_jpeg, stops, write_bag

STILL = StillOptions(still_seconds=1.0, sweeps=5)
YAWS = [0.0, 90.0, 0.0]  # the third stop is the first place again


def _options(recording: Recording, **changes: str | None) -> BagImportOptions:
    topics = {"image_topic": recording.image_topic, "cloud_topic": recording.cloud_topic,
              "camera_info_topic": recording.info_topic, **changes}
    return BagImportOptions(topics["image_topic"], topics["cloud_topic"], topics["camera_info_topic"], None, STILL)


def _name(fmt: BagFormat) -> str:
    return "run.bag" if fmt is BagFormat.ROS1 else f"run_{fmt.value}"


@pytest.fixture(scope="module")
def recording() -> Recording:
    return stops(yaws_deg=YAWS, still_sweeps=25, move_sweeps=8)


@pytest.fixture(scope="module")
def mcap_bag(tmp_path_factory: pytest.TempPathFactory, recording: Recording) -> Path:
    return write_bag(tmp_path_factory.mktemp("bag") / "run", BagFormat.MCAP, recording)


def _stop_spans(recording: Recording) -> list[tuple[float, float]]:
    """[first start, last end] s of each run of sweeps at one yaw (the stops as written)."""
    spans: list[tuple[float, float]] = []
    previous = None
    for t, yaw in recording.sweeps:
        if yaw == previous:
            spans[-1] = (spans[-1][0], t + 0.05)
        else:
            spans.append((t, t + 0.05))
        previous = yaw
    return [s for s in spans if s[1] - s[0] > 0.5]


@pytest.mark.parametrize("fmt", list(BagFormat))
def test_turning_rig_yields_a_pair_per_new_stop(tmp_path: Path, recording: Recording, fmt: BagFormat) -> None:
    bag = write_bag(tmp_path / _name(fmt), fmt, recording)
    summary = import_bag(bag, tmp_path / "out", options=_options(recording))
    stops_s = _stop_spans(recording)
    verdicts = [d.verdict for d in summary.decisions]
    assert verdicts.count(Verdict.KEPT) == 2 == summary.pairs == len(stops_s) - 1
    assert verdicts[-1] is Verdict.SAME_PLACE  # back at the first place
    assert Verdict.MOVING in verdicts
    dataset = open_dataset(tmp_path / "out")
    assert len(dataset) == 2
    _, K, (width, height) = pinhole_jpeg()
    assert dataset.rig.camera.kind.value == "pinhole" and np.allclose(dataset.rig.camera.K, K)
    for pair, (start, end) in zip(dataset.pairs(), stops_s, strict=False):
        stamp = pair.meta["camera"]["stamp_s"]
        assert start <= stamp <= end  # the image of a stop, not of the turn
        first_s, last_s = pair.meta["lidar"]["stamp_s"]  # the image among its fused sweeps, as capture takes it
        assert first_s - STILL.max_offset_s <= stamp <= last_s + STILL.max_offset_s
        assert pair.image.shape[:2] == (height, width)
        assert pair.cloud.ring is not None and set(np.unique(pair.cloud.ring)) <= set(range(16))
        assert len(pair.cloud) > 10_000
    frames = yaml.safe_load((tmp_path / "out" / "bag.yaml").read_text())["frames"]
    assert frames == {"camera": recording.camera_frame, "lidar": recording.lidar_frame}


def test_cli_prints_what_was_kept_and_why_not(tmp_path: Path, mcap_bag: Path, recording: Recording,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["import", "bag", str(mcap_bag), str(tmp_path / "out"), "--image-topic", recording.image_topic,
                 "--cloud-topic", recording.cloud_topic, "--camera-info-topic", recording.info_topic,
                 "--still-seconds", "1", "--n", "1"])
    out = capsys.readouterr().out
    assert code == 0
    assert out.count("kept as pair") == 1 and "(moving)" in out and "(enough pairs)" in out
    assert len(open_dataset(tmp_path / "out")) == 1


def _cli_error(capsys: pytest.CaptureFixture[str], bag: Path, out: Path, *extra: str) -> str:
    code = main(["import", "bag", str(bag), str(out), "--still-seconds", "1", *extra])
    err = capsys.readouterr().err
    assert code == ERROR, err
    assert "Traceback" not in err and err.startswith("rigd: error: ")
    assert not out.exists() or not any(out.iterdir())  # nothing written
    return err


def test_wrong_topic_lists_the_topics(tmp_path: Path, mcap_bag: Path, recording: Recording,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    err = _cli_error(capsys, mcap_bag, tmp_path / "out", "--image-topic", "/cam", "--cloud-topic",
                     recording.cloud_topic)
    assert "'/cam'" in err and recording.image_topic in err and recording.cloud_topic in err
    err = _cli_error(capsys, mcap_bag, tmp_path / "out", "--image-topic", recording.cloud_topic, "--cloud-topic",
                     recording.cloud_topic)
    assert "VelodyneScan" in err and "sensor_msgs/msg/Image" in err


def test_truncated_bag_is_named(tmp_path: Path, mcap_bag: Path, recording: Recording,
                                capsys: pytest.CaptureFixture[str]) -> None:
    source = bag_file(mcap_bag, BagFormat.MCAP)
    cut = tmp_path / "cut.mcap"
    shutil.copyfile(source, cut)
    with cut.open("r+b") as fh:
        fh.truncate(source.stat().st_size // 2)
    err = _cli_error(capsys, cut, tmp_path / "out", "--image-topic", recording.image_topic, "--cloud-topic",
                     recording.cloud_topic)
    assert str(cut) in err


def test_no_time_overlap(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    late = stops(yaws_deg=[0.0], still_sweeps=10, move_sweeps=0, image_offset_s=100.0)
    bag = write_bag(tmp_path / "late.bag", BagFormat.ROS1, late, with_info=False)
    err = _cli_error(capsys, bag, tmp_path / "out", "--image-topic", late.image_topic, "--cloud-topic",
                     late.cloud_topic)
    assert "do not overlap in time" in err and late.image_topic in err


def test_no_still_moment(tmp_path: Path) -> None:
    turning = Recording(tuple((1.0e9 + 0.05 * k, 5.0 * k) for k in range(20)),
                        tuple(1.0e9 + 0.1 * k for k in range(10)))
    bag = write_bag(tmp_path / "turning.bag", BagFormat.ROS1, turning)
    with pytest.raises(BagError, match="no still moment") as caught:
        import_bag(bag, tmp_path / "out", options=_options(turning))
    assert "never stood still" in str(caught.value)
    assert not (tmp_path / "out").exists()
