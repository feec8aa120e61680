"""Evidence of motion besides the LiDAR (rigd/importers/bag/motion.py): a stretch the LiDAR gate holds is not kept
when the IMU, the odometry or the images say the rig moved in it, and the reason names the source, the value and
the time. The bags hold two stops (the LiDAR still at each); each source speaks up at one of them."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from rigd.cli import main
from rigd.cli.exit_codes import ERROR
from rigd.importers.bag import BagImportOptions, import_bag
from rigd.importers.bag.motion import (
    MotionSamples,
    MotionSource,
    MotionThresholds,
    Quantity,
    moving_intervals,
)
from rigd.importers.bag.stills import StillOptions, Verdict
from tests.rigd.importers.bag.bags import (
    T0_S,
    BagFormat,
    BagTypes,
    Messages,
    Recording,
    imu_messages,
    odometry_messages,
    stops,
    write_bag,
)

STILL = StillOptions(still_seconds=1.0, sweeps=5)
IMAGE_MOTION_GREY = 4.0  # --image-motion: the images are consulted only when asked
IMU_TOPIC, ODOM_TOPIC = "/imu/data", "/odom"
# stop 0: 0 - 1.25 s, turning 1.25 - 1.65 s, stop 1: 1.65 - 2.9 s (s from the first sweep)
TURNING_S = (1.25, 1.65)
IMU_JOLT_S = (2.0, 2.2)  # the IMU turns at 3.2 deg/s while the LiDAR sees stop 1 still
ODOM_CREEP_S = (0.5, 0.6)  # the odometry creeps at 5 cm/s while the LiDAR sees stop 0 still


def _recording(**changes: object) -> Recording:
    base = stops(yaws_deg=[0.0, 90.0], still_sweeps=25, move_sweeps=8)
    return Recording(base.sweeps, base.image_t_s, **changes)  # type: ignore[arg-type]


def _within(t: float, span: tuple[float, float]) -> bool:
    return span[0] <= t - T0_S <= span[1] + 1e-9


def _sensors(types: BagTypes) -> Messages:
    times = T0_S + np.arange(0.0, 2.9, 0.05)
    imu = [(float(t), 20.0 if _within(t, TURNING_S) else 3.2 if _within(t, IMU_JOLT_S) else 0.0) for t in times]
    odom = [(float(t), 0.3 if _within(t, TURNING_S) else 0.05 if _within(t, ODOM_CREEP_S) else 0.0) for t in times]
    return imu_messages(types, IMU_TOPIC, imu) + odometry_messages(types, ODOM_TOPIC, odom)


@pytest.fixture(scope="module")
def sensor_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_bag(tmp_path_factory.mktemp("bag") / "run", BagFormat.MCAP, _recording(), extra=_sensors)


def _import(bag: Path, out: Path, **options: object) -> list[tuple[Verdict, str]]:
    recording = _recording()
    summary = import_bag(bag, out, options=BagImportOptions(recording.image_topic, recording.cloud_topic,
                                                            recording.info_topic, None, STILL, **options))  # type: ignore[arg-type]
    return [(d.verdict, d.reason) for d in summary.decisions if d.window is not None]


def test_imu_turning_at_a_still_lidar_stop_rejects_it(tmp_path: Path, sensor_bag: Path) -> None:
    (first, _), (second, reason) = _import(sensor_bag, tmp_path / "out", imu_topic=IMU_TOPIC)
    assert first is Verdict.KEPT
    assert second is Verdict.MOVING
    assert reason.startswith("the LiDAR still") and reason.endswith("but imu: 3.20 deg/s at 2.00 s")


def test_odometry_creeping_at_a_still_lidar_stop_rejects_it(tmp_path: Path, sensor_bag: Path) -> None:
    (first, reason), (second, _) = _import(sensor_bag, tmp_path / "out", odom_topic=ODOM_TOPIC)
    assert first is Verdict.MOVING and reason.endswith("but odometry: 0.05 m/s at 0.50 s")
    assert second is Verdict.KEPT  # the IMU's jolt is not consulted


def test_image_motion_rejects_a_still_lidar_stop(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    recording = _recording(image_motion_s=(T0_S + 2.0, T0_S + 2.3))
    bag = write_bag(tmp_path / "run.bag", BagFormat.ROS1, recording)
    code = main(["import", "bag", str(bag), str(tmp_path / "out"), "--image-topic", recording.image_topic,
                 "--cloud-topic", recording.cloud_topic, "--camera-info-topic", recording.info_topic,
                 "--still-seconds", "1", "--image-motion", str(IMAGE_MOTION_GREY)])
    out = capsys.readouterr().out
    assert code == 0
    lines = [line for line in out.splitlines() if "still" in line and " s  " in line]
    assert "kept as pair 0000" in lines[0]
    found = re.search(r"not kept \(moving\): the LiDAR still .*, but image: ([\d.]+) grey levels of change at "
                      r"([\d.]+) s$", lines[-1])
    assert found is not None, out
    assert float(found[1]) > IMAGE_MOTION_GREY and 1.95 <= float(found[2]) <= 2.35, out


@pytest.mark.parametrize(("flag", "topic", "wanted"), [("--imu-topic", ODOM_TOPIC, "sensor_msgs/msg/Imu"),
                                                         ("--odom-topic", IMU_TOPIC, "nav_msgs/msg/Odometry")])
def test_wrong_motion_topic_type_is_named(tmp_path: Path, sensor_bag: Path, capsys: pytest.CaptureFixture[str],
                                          flag: str, topic: str, wanted: str) -> None:
    recording = _recording()
    code = main(["import", "bag", str(sensor_bag), str(tmp_path / "out"), "--image-topic", recording.image_topic,
                 "--cloud-topic", recording.cloud_topic, flag, topic])
    err = capsys.readouterr().err
    assert code == ERROR and err.startswith("rigd: error: ")
    assert f"topic {topic!r} ({flag}) carries" in err and f"not {wanted}" in err
    assert not (tmp_path / "out").exists()


def test_moving_intervals_are_runs_of_samples_above_the_threshold() -> None:
    samples = MotionSamples()
    for t, rate in [(0.0, 0.1), (0.1, 2.0), (0.2, 3.0), (0.3, 0.2), (0.4, 0.9)]:
        samples.times[Quantity.IMU_RATE].append(t)
        samples.values[Quantity.IMU_RATE].append(rate)
    runs = moving_intervals(samples=samples, thresholds=MotionThresholds())[MotionSource.IMU]
    assert [(r.t_start_s, r.t_end_s, r.peak) for r in runs] == [(0.1, 0.2, 3.0), (0.4, 0.4, 0.9)]
    strongest = samples.strongest(t_start_s=0.15, t_end_s=1.0, thresholds=MotionThresholds())
    assert strongest is not None and (strongest.t_s, strongest.value) == (0.2, 3.0)
    assert samples.strongest(t_start_s=0.25, t_end_s=0.35, thresholds=MotionThresholds()) is None
