"""The simulated rig on a trajectory: timeline and interpolation, places, the rig file, the VLP-16 stream it
sends (decoded back, and paced at the sensor's real rate over loopback) and its camera frames."""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
import pytest

from drivers.ladybug5.rig import scaled_ladybug5_rig
from drivers.ladybug5.sim import pixel_rays_optical, sensor_displays
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher
from drivers.sim import Pose, make_scene, render_panorama, scan
from drivers.sim.errors import SimError
from drivers.sim.lidar import LidarConfig
from drivers.sim.motion import PLACE_SPACING_M, MotionRigSpec, Trajectory, load_spec, plan_places, save_spec
from drivers.sim.rig import PAPER_T_CAMERA_LIDAR, place_rig, rng_for
from drivers.sim.scene import SceneKind
from drivers.sim.stream import TURN_S, CameraStream, LidarEmitter
from drivers.vlp16 import Ports, PpsStatus, UdpReceiver, decode_packets, parse_position_packet
from drivers.vlp16.calibration import LaserCalibration

A = Pose.from_rpy_xyz((1.0, -2.0, 170.0), (1.0, 2.0, 1.5))
B = Pose.from_rpy_xyz((-1.0, 2.0, -170.0), (4.0, -2.0, 1.7))


def test_timeline_stands_at_places_and_drives_smoothly_between() -> None:
    trajectory = Trajectory((A, B), still_s=2.0, move_s=1.0)
    assert trajectory.stop_interval(0) == (0.0, 2.0) and trajectory.stop_interval(1) == (3.0, math.inf)
    for t, stop in ((-1.0, 0), (0.0, 0), (1.99, 0), (2.5, None), (3.0, 1), (100.0, 1)):
        assert trajectory.stop_index(t) == stop
    np.testing.assert_array_equal(trajectory.pose_at(1.5).matrix, A.matrix)
    np.testing.assert_array_equal(trajectory.pose_at(50.0).matrix, B.matrix)
    middle = trajectory.pose_at(2.5)  # half way in time is half way in distance (symmetric easing)
    np.testing.assert_allclose(middle.translation_m, (A.translation_m + B.translation_m) / 2, atol=1e-12)
    assert abs(abs(middle.rpy_deg[2]) - 180.0) < 1e-9  # yaw 170 -> -170 goes through 180, not through 0
    # Speed is zero at both ends: 1 ms from a place the rig is within (1 - cos(pi/1000)) / 2 of the drive.
    gap = np.linalg.norm(B.translation_m - A.translation_m) * (1 - math.cos(math.pi * 1e-3)) / 2
    assert np.linalg.norm(trajectory.pose_at(2.001).translation_m - A.translation_m) <= gap + 1e-12
    assert np.linalg.norm(trajectory.pose_at(2.999).translation_m - B.translation_m) <= gap + 1e-12


def test_places_are_spaced_and_a_resumed_rig_starts_further_on() -> None:
    scene = make_scene("indoor", 7, 0)
    places = plan_places(scene, 7, 6)
    gaps = [np.linalg.norm(a.translation_m - b.translation_m) for a, b in zip(places, places[1:], strict=False)]
    assert all(PLACE_SPACING_M[0] <= g <= PLACE_SPACING_M[1] for g in gaps)
    later = plan_places(scene, 7, 2, first=3)
    expected = place_rig(scene, rng_for(SceneKind.INDOOR, 7, 3, "pose"), PAPER_T_CAMERA_LIDAR)
    np.testing.assert_array_equal(later[0].matrix, expected.matrix)  # place i comes from its own stream
    assert plan_places(scene, 7, 6)[4].matrix.tolist() == places[4].matrix.tolist()  # deterministic


def test_rig_file_round_trip_and_errors(tmp_path: Path) -> None:
    spec = MotionRigSpec(scene="outdoor", seed=4, stops=3, still_s=1.5, width=64, height=32).started(1.7e9)
    save_spec(tmp_path / "rig.yaml", spec)
    back = load_spec(tmp_path / "rig.yaml")
    assert back.to_yaml() == spec.to_yaml() and back.start_host_s == 1.7e9
    (tmp_path / "bad.yaml").write_text("scene: indoor\nstop: 3\n")
    with pytest.raises(SimError, match="unknown sim rig key.*'stop'"):
        load_spec(tmp_path / "bad.yaml")
    with pytest.raises(SimError, match="unknown scene kind"):
        MotionRigSpec(scene="forest")
    with pytest.raises(SimError, match="cannot read"):
        load_spec(tmp_path / "missing.yaml")


SPEC = MotionRigSpec(scene="indoor", seed=2, stops=2, still_s=0.3, move_s=1.0, width=64, height=32)


def test_a_turn_decodes_to_the_scan_at_the_rigs_pose() -> None:
    emitter = LidarEmitter(SPEC.started(1.7e9), "127.0.0.1", 2368, 8308)
    turn = 5  # 0.50-0.60 s: driving
    datagrams = emitter.turn_datagrams(turn)
    position = parse_position_packet(datagrams[0][2])
    assert datagrams[0][1] == 8308 and position is not None and position.pps is PpsStatus.ABSENT
    data = datagrams[1:]
    assert len(data) == 75 and {port for _, port, _ in data} == {2368}
    times = np.array([t for t, _, _ in data])
    assert times[0] == pytest.approx(1.7e9 + turn * TURN_S, abs=1e-6)
    np.testing.assert_allclose(np.diff(times), 1327.104e-6, atol=1e-6)  # the VLP-16's packet period
    payloads = np.frombuffer(b"".join(p for _, _, p in data), np.uint8).reshape(75, 1206)
    points = decode_packets(payloads, LaserCalibration(), np.zeros(75)).points
    pose = emitter.trajectory.pose_at(turn * TURN_S + TURN_S / 2).compose(SPEC.T_camera_lidar)
    truth = scan(emitter.scene, pose, np.random.default_rng([SPEC.seed, turn, 7]), LidarConfig())
    decoded = np.sort(np.sqrt(points["x"].astype(float) ** 2 + points["y"] ** 2 + points["z"] ** 2))
    np.testing.assert_allclose(decoded, np.sort(np.linalg.norm(truth.points_lidar, axis=1)), atol=2e-5)


def test_packets_arrive_at_the_sensors_rate_and_time() -> None:
    with UdpReceiver(host="127.0.0.1", ports=Ports(0, 0)) as receiver:
        with LidarEmitter(SPEC, "127.0.0.1", receiver.ports.data, receiver.ports.position) as emitter:
            sweeps = [s for s in receiver.sweeps(timeout_s=1.5) if s.complete]
        start = emitter.spec.start_host_s
    assert len(sweeps) >= 8
    span_device = sweeps[-1].end.device - sweeps[0].start.device
    packets = sum(s.packet_count for s in sweeps)
    assert packets / span_device == pytest.approx(1 / 1327.104e-6, rel=0.02)  # the VLP-16's 754 packets/s
    # ... and they arrive at that pace, not faster: the first may be late by the scan of its turn.
    assert sweeps[-1].end.host - sweeps[0].start.host > span_device - 0.15
    assert all(s.missing_packets == 0 for s in sweeps)
    for s in sweeps:  # each turn starts on the turn grid of the rig's clock, and is never received early
        k = (s.start.device - start) / TURN_S
        assert abs(k - round(k)) < 1e-3 and 0 <= s.start.host - s.start.device < 0.3


def test_camera_frames_show_the_pose_at_their_exposure() -> None:
    spec = SPEC.started(time.time())
    stream = CameraStream(spec)
    frames = stream.frames()
    frame = next(frames)
    stream.close()
    assert next(frames, None) is None  # close() ends the stream
    assert frame.exposure_host_s - spec.start_host_s == pytest.approx(frame.device_time_s)
    expected = render_panorama(stream.scene, stream.trajectory.pose_at(frame.device_time_s), 64, 32,
                               np.random.default_rng([spec.seed, 0, 11]), spec.image_noise_grey)
    np.testing.assert_array_equal(frame.image, expected)


def test_a_still_rig_streams_frames_without_rendering_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """Standing still, the view is rendered once; each frame adds its own noise, as render_panorama would."""
    import drivers.sim.stream as stream_module

    renders = []
    real = stream_module.panorama_display
    monkeypatch.setattr(stream_module, "panorama_display", lambda *a, **k: renders.append(1) or real(*a, **k))
    spec = dataclasses.replace(SPEC, still_s=5.0).started(time.time())
    stream = CameraStream(spec)
    frames = stream.frames()
    got = [next(frames) for _ in range(3)]
    stream.close()
    assert [f.sequence for f in got] == [0, 1, 2]
    assert len(renders) == 1  # the first place: the rig has not moved
    for f in got:
        expected = render_panorama(stream.scene, stream.trajectory.pose_at(f.device_time_s), 64, 32,
                                   np.random.default_rng([spec.seed, f.sequence, 11]), spec.image_noise_grey)
        np.testing.assert_array_equal(f.image, expected)
    assert not np.array_equal(got[0].image, got[1].image)  # fresh read noise


def test_a_head_rig_streams_its_sensor_images_and_their_stitch(tmp_path: Path) -> None:
    spec = dataclasses.replace(SPEC, sensor_width=32, frame_period_s=0.05).started(time.time())
    save_spec(tmp_path / "rig.yaml", spec)
    assert load_spec(tmp_path / "rig.yaml").sensor_width == 32
    with pytest.raises(SimError, match="sensor_width"):
        dataclasses.replace(SPEC, sensor_width=4)
    stream = CameraStream(spec)
    frames = stream.frames()
    frame = next(frames)
    stream.close()
    rig = scaled_ladybug5_rig(32)
    assert [s.shape for s in frame.sensors] == [(c.height, c.width) for c in rig.cameras]
    np.testing.assert_array_equal(frame.image, Stitcher(rig, PanoramaSpec(64, 32)).stitch(list(frame.sensors)))
    pose = stream.trajectory.pose_at(frame.device_time_s)
    truth = sensor_displays(stream.scene, pose, rig.cameras, [pixel_rays_optical(c) for c in rig.cameras])
    for image, display in zip(frame.sensors, truth, strict=True):  # each sensor's own view, with read noise
        assert 0 < np.abs(image - 255.0 * display).mean() < 3 * spec.image_noise_grey
