"""The stationarity gate: range images, the range-change statistic and its threshold against real and
simulated noise, the still window's anchor, and the camera's image change."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.sim import LASER_ELEVATIONS_DEG, Pose, make_scene, scan
from drivers.sim.rig import PAPER_T_CAMERA_LIDAR, place_rig, rng_for
from drivers.sim.scene import SceneKind
from drivers.vlp16 import Vlp16Config, read_sweeps
from rigd.capture.engine import CAMERA_CHANGE_GREY, STILL_RANGE_M
from rigd.capture.gate import (
    AZIMUTH_BINS,
    RINGS,
    FrameSample,
    StillnessGate,
    SweepSample,
    image_change_grey,
    range_change_m,
    range_image,
    thumbnail,
)
from tests.testdata import LEGACY_PCAP

RING_ELEVATION_DEG = np.sort(LASER_ELEVATIONS_DEG)


def vlp16_point(range_m: float, ring: int, azimuth_deg: float) -> np.ndarray:
    """docs/conventions.md: x = r cos w cos a, y = -r cos w sin a, z = r sin w."""
    w, a = np.radians(RING_ELEVATION_DEG[ring]), np.radians(azimuth_deg)
    return range_m * np.array([np.cos(w) * np.cos(a), -np.cos(w) * np.sin(a), np.sin(w)])


def test_range_image_is_the_mean_range_per_ring_and_degree() -> None:
    points = np.array([vlp16_point(4.0, 3, 10.2), vlp16_point(6.0, 3, 10.8), vlp16_point(7.5, 15, 359.9),
                       vlp16_point(2.0, 0, 90.5)])
    image = range_image(points, np.array([3, 3, 15, 0]))
    assert image.shape == (RINGS, AZIMUTH_BINS)
    assert image[3, 10] == pytest.approx(5.0, abs=1e-5)  # 4 and 6 m in the same bin
    assert image[15, 359] == pytest.approx(7.5, abs=1e-5)
    assert image[0, 90] == pytest.approx(2.0, abs=1e-5)  # clockwise: +90 deg azimuth is -y
    assert np.isnan(image).sum() == RINGS * AZIMUTH_BINS - 3


def test_range_change_is_the_90th_percentile_over_common_bins() -> None:
    a = np.full((RINGS, AZIMUTH_BINS), 5.0, np.float32)
    flat = np.arange(a.size)
    b = a.copy().ravel()
    b[:] += 0.01
    b[flat % 20 == 0] += 1.0  # 5 % of the directions change a lot (a person walking by)
    assert range_change_m(a, b.reshape(a.shape)) == pytest.approx(0.01, abs=1e-6)
    b[flat % 20 < 3] = 6.01  # 15 %: now the 90th percentile is among them
    assert range_change_m(a, b.reshape(a.shape)) == pytest.approx(1.01, abs=1e-5)
    sparse = np.full_like(a, np.nan)
    sparse[0, :50] = 5.0
    assert math.isinf(range_change_m(a, sparse))  # too few directions to judge


def test_a_real_vlp16_still_then_turning_slowly() -> None:
    """VeloView's test capture (1200 rpm, 50 turns): the sensor stands still for about 1.6 s, then turns
    slowly; turn to turn its range images differ by noise only (2-4 cm) all along."""
    sweeps, _ = read_sweeps(LEGACY_PCAP, Vlp16Config(product_ids=None))
    complete = [s for s in sweeps if s.complete]
    images = [range_image(np.stack([s.points[c] for c in "xyz"], axis=1), s.points["ring"]) for s in complete]
    consecutive = [range_change_m(a, b) for a, b in zip(images, images[1:], strict=False)]
    assert max(consecutive) < STILL_RANGE_M  # comparing neighbours only would never see the motion
    assert max(range_change_m(images[0], image) for image in images[1:30]) < STILL_RANGE_M  # real noise
    gate = StillnessGate(STILL_RANGE_M, CAMERA_CHANGE_GREY)
    restarts = []
    for k, sweep in enumerate(complete):
        gate.add_sweep(SweepSample(sweep.start.device, sweep.end.device, images[k]))
        if gate.sweeps == 1:
            restarts.append(k)
    assert restarts[0] == 0 and restarts[1] >= 30  # still for the first 1.5 s, then the drift is caught


@pytest.mark.parametrize("kind, index", [("indoor", 0), ("indoor", 1), ("outdoor", 0)])
def test_threshold_separates_simulated_noise_from_small_motions(kind: str, index: int) -> None:
    scene = make_scene(kind, 3, index)
    pose = place_rig(scene, rng_for(SceneKind(kind), 3, index, "pose"), PAPER_T_CAMERA_LIDAR)

    def image(camera_pose: Pose, seed: int) -> np.ndarray:
        sweep = scan(scene, camera_pose.compose(PAPER_T_CAMERA_LIDAR), np.random.default_rng(seed))
        return range_image(sweep.points_lidar, sweep.ring)

    reference = image(pose, 0)
    assert range_change_m(reference, image(pose, 1)) < STILL_RANGE_M / 2  # 2 cm range noise only
    moved = Pose(pose.rotation, pose.translation_m + np.array([0.2, 0.0, 0.0]))
    turned = Pose.from_rpy_xyz(pose.rpy_deg + np.array([0.0, 0.0, 2.0]), pose.translation_m)
    assert range_change_m(reference, image(moved, 1)) > STILL_RANGE_M  # 20 cm, even along a street
    assert range_change_m(reference, image(turned, 1)) > STILL_RANGE_M  # 2 degrees


def samples(offsets_m: list[float], seed: int = 0) -> list[SweepSample]:
    """Sweeps 0.1 s apart of a scene at 5-20 m, every range moved by ``offsets_m[k]``, 5 mm noise."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(5.0, 20.0, (RINGS, AZIMUTH_BINS)).astype(np.float32)
    return [SweepSample(0.1 * k, 0.1 * k + 0.1, base + offset + rng.normal(0, 0.005, base.shape).astype(np.float32))
            for k, offset in enumerate(offsets_m)]


def test_still_window_grows_while_the_range_change_stays_small() -> None:
    gate = StillnessGate(STILL_RANGE_M, CAMERA_CHANGE_GREY)
    for sample in samples([0.0] * 20):
        gate.add_sweep(sample)
    assert gate.sweeps == 20 and gate.still_for_s == pytest.approx(2.0)
    assert gate.lidar_change_m < 0.02


def test_slow_creep_restarts_the_window_although_consecutive_sweeps_agree() -> None:
    gate = StillnessGate(STILL_RANGE_M, CAMERA_CHANGE_GREY)
    restarts = []
    for k, sample in enumerate(samples([0.01 * k for k in range(20)])):  # 1 cm per sweep: 10 cm/s
        gate.add_sweep(sample)
        if gate.sweeps == 1:
            restarts.append(k)
    # Each window restarts once the drift from its anchor passes 5 cm, i.e. every 5-6 sweeps.
    assert restarts[0] == 0 and len(restarts) >= 3
    assert all(5 <= b - a <= 6 for a, b in zip(restarts, restarts[1:], strict=False))
    assert gate.still_for_s < 0.65


def test_camera_change_ignores_exposure_steps_and_sees_shifts() -> None:
    rng = np.random.default_rng(0)
    texture = rng.uniform(0, 255, (64, 128)).astype(np.float32)
    texture = np.asarray(thumbnail(np.kron(texture, np.ones((8, 8))).astype(np.uint8)), np.float32)
    assert image_change_grey(texture, texture + 12.0) == pytest.approx(0.0, abs=1e-4)  # exposure step
    assert image_change_grey(texture, np.roll(texture, 3, axis=1)) > CAMERA_CHANGE_GREY


def test_camera_change_is_over_frames_in_the_window() -> None:
    gate = StillnessGate(STILL_RANGE_M, CAMERA_CHANGE_GREY)
    still = np.full((64, 128), 100.0, np.float32)
    gate.add_frame(FrameSample(-0.5, still + 50 * (np.arange(128) % 2)))  # before the window: ignored
    for sample in samples([0.0] * 10):
        gate.add_sweep(sample)
    assert gate.camera_change() is None
    gate.add_frame(FrameSample(0.3, still))
    assert gate.camera_change() is None  # one frame: nothing to compare
    gate.add_frame(FrameSample(0.6, still + 1.0))
    assert gate.camera_change() == pytest.approx(0.0) and not gate.camera_saw_motion()
    gate.add_frame(FrameSample(0.9, still + 20.0 * (np.arange(128) % 2)))
    assert gate.camera_change() == pytest.approx(10.0) and gate.camera_saw_motion()
