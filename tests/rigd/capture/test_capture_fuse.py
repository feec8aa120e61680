"""Fusing K sweeps of a still rig: one real return per beam, the median range, less noise, ring kept."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.sim import make_scene, scan
from drivers.sim.lidar import LidarConfig
from drivers.sim.rig import PAPER_T_CAMERA_LIDAR, place_rig, rng_for
from drivers.sim.scene import SceneKind
from drivers.sim.stream import FIRING_AZIMUTH_DEG, TURN_S
from drivers.vlp16 import DatagramBatch, ReturnMode, SweepAssembler, encode_data_packets
from rigd.capture.fuse import fuse_sweeps

K = 5
NOISE_M = 0.02


@pytest.fixture(scope="module")
def turns():
    """(noise-free ranges (1800,16), K noisy scans) of one place: the per-firing arrays the VLP-16 sends."""
    scene = make_scene("indoor", 4, 0)
    pose = place_rig(scene, rng_for(SceneKind.INDOOR, 4, 0, "pose"), PAPER_T_CAMERA_LIDAR).compose(PAPER_T_CAMERA_LIDAR)
    truth = scan(scene, pose, np.random.default_rng(0), LidarConfig(range_noise_m=0.0))
    noisy = [scan(scene, pose, np.random.default_rng(k + 1), LidarConfig(range_noise_m=NOISE_M)) for k in range(K)]
    return truth, noisy


def sweeps_of(ranges: list[np.ndarray], reflectivity: list[np.ndarray], mode: ReturnMode = ReturnMode.STRONGEST,
              last: list[np.ndarray] | None = None) -> list:
    """Encode the turns one after the other as one packet stream and assemble it into sweeps (one per turn)."""
    payloads, times = [], []
    for k, (r, refl) in enumerate(zip(ranges, reflectivity, strict=True)):
        packets = encode_data_packets(r, refl, FIRING_AZIMUTH_DEG, 1000.0 + k * TURN_S, mode,
                                      last_ranges_m=None if last is None else last[k])
        payloads.append(packets.payloads)
        times.append(packets.time_s)
    data, host = np.concatenate(payloads), np.concatenate(times)
    assembler = SweepAssembler()
    sweeps = assembler.feed(DatagramBatch(data, host, np.arange(len(data), dtype=np.int64))) + assembler.flush()
    assert len(sweeps) == len(ranges)
    return sweeps


ELEVATION_OF_LASER = np.array([-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15])
RING_OF_LASER = np.argsort(np.argsort(ELEVATION_OF_LASER))
LASER_OF_RING = np.argsort(ELEVATION_OF_LASER)


def beam_ranges(cloud) -> dict[tuple[int, int], float]:
    """{(ring, firing): range} of a cloud of the simulated sensor: firing f starts at 0.2 f degrees and laser
    k fires k * 2.304 us later, while the head turns 360 degrees per TURN_S."""
    xyz = cloud.points_lidar
    azimuth = np.degrees(np.arctan2(-xyz[:, 1], xyz[:, 0])) % 360.0
    delay_deg = LASER_OF_RING[cloud.ring] * 2.304e-6 * 360.0 / TURN_S
    firing = np.rint((azimuth - delay_deg) / 0.2).astype(int) % 1800
    return dict(zip(zip(cloud.ring.tolist(), firing.tolist(), strict=True), np.linalg.norm(xyz, axis=1), strict=True))


def test_fused_points_are_real_returns_one_per_beam(turns) -> None:
    _, noisy = turns
    sweeps = sweeps_of([s.ranges_m for s in noisy], [s.reflectivity for s in noisy])
    cloud = fuse_sweeps(sweeps)
    rows = {(float(p["x"]), float(p["y"]), float(p["z"]), int(p["ring"]), float(p["intensity"]))
            for s in sweeps for p in s.points}
    fused = set(zip(*(cloud.points_lidar[:, i].tolist() for i in range(3)), cloud.ring.tolist(),
                    cloud.intensity.tolist(), strict=True))
    assert fused <= rows  # nothing invented: every fused point is one of the returns, with its ring and intensity
    beams = beam_ranges(cloud)
    assert len(beams) == len(cloud)  # one per beam
    returns = np.count_nonzero(np.stack([s.ranges_m for s in noisy]) > 0, axis=0)
    assert len(cloud) == int(np.count_nonzero(returns >= (K + 1) // 2))


def test_median_of_five_turns_cuts_the_range_noise(turns) -> None:
    truth, noisy = turns
    cloud = fuse_sweeps(sweeps_of([s.ranges_m for s in noisy], [s.reflectivity for s in noisy]))
    true_range = {(int(r), f): truth.ranges_m[f, laser] for f in range(1800) for laser, r in enumerate(RING_OF_LASER)}
    errors = np.array([rng - true_range[key] for key, rng in beam_ranges(cloud).items() if true_range[key] > 0])
    single = (noisy[0].ranges_m - truth.ranges_m)[(noisy[0].ranges_m > 0) & (truth.ranges_m > 0)]
    assert np.std(single) == pytest.approx(NOISE_M, rel=0.05)
    # Median of 5 Gaussian draws: sqrt(pi / 2) / sqrt(5) = 0.56 of one draw's sigma (plus 2 mm rounding).
    assert np.std(errors) < 0.65 * np.std(single)


def test_a_beam_needs_returns_in_most_turns(turns) -> None:
    _, noisy = turns
    ranges = [s.ranges_m.copy() for s in noisy]
    beam = np.argwhere(np.all(np.stack(ranges) > 0, axis=0))[1000]  # a beam that returned in every turn
    for k in range(3):
        ranges[k][tuple(beam)] = 0.0  # now it returns in 2 of 5 turns
    cloud = fuse_sweeps(sweeps_of(ranges, [s.reflectivity for s in noisy]))
    ring = RING_OF_LASER[beam[1]]
    assert (int(ring), int(beam[0])) not in beam_ranges(cloud)
    ranges[2][tuple(beam)] = noisy[2].ranges_m[tuple(beam)]  # 3 of 5: kept
    assert (int(ring), int(beam[0])) in beam_ranges(fuse_sweeps(sweeps_of(ranges, [s.reflectivity for s in noisy])))


def test_dual_return_streams_fuse_their_strongest_returns(turns) -> None:
    _, noisy = turns
    strongest = [s.ranges_m for s in noisy[:3]]
    last = [np.where(r > 0, r + 1.0, 0.0) for r in strongest]  # a second echo 1 m behind every return
    dual = fuse_sweeps(sweeps_of(strongest, [s.reflectivity for s in noisy[:3]], ReturnMode.DUAL, last))
    single = fuse_sweeps(sweeps_of(strongest, [s.reflectivity for s in noisy[:3]]))
    np.testing.assert_allclose(np.sort(np.linalg.norm(dual.points_lidar, axis=1)),
                               np.sort(np.linalg.norm(single.points_lidar, axis=1)), atol=1e-5)
