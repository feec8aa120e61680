"""The stationarity gate: direction grids, the motion estimate against real and simulated noise and small
motions, thresholds from the tolerance, the still window's anchor, and the camera's shift."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.sim import LASER_ELEVATIONS_DEG, Pose, make_scene, scan
from drivers.sim.disturbance import axis_angle_matrix
from drivers.sim.rig import PAPER_T_CAMERA_LIDAR, place_rig, rng_for
from drivers.sim.scene import SceneKind
from drivers.vlp16 import Vlp16Config, read_sweeps
from rigd.capture.gate import (
    AZIMUTH_BINS,
    RINGS,
    FrameSample,
    StillnessGate,
    StillThresholds,
    SweepSample,
    camera_shift_deg,
    direction_grid,
    estimate_motion,
    plane_bins,
    range_change_m,
    range_image,
)
from tests.testdata import LEGACY_PCAP

RING_ELEVATION_DEG = np.sort(LASER_ELEVATIONS_DEG)
LIMITS = StillThresholds.from_tolerance(0.2)


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
    grid = direction_grid(points, np.array([3, 3, 15, 0]))
    assert grid.returns == 3 and grid.count[3, 10] == 2
    assert grid.spread_m[3, 10] == pytest.approx(1.0, abs=1e-5)  # ranges 4 and 6: one metre either side
    np.testing.assert_allclose(grid.points[3, 10], (points[0] + points[1]) / 2, atol=1e-5)


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


def test_thresholds_come_from_the_tolerance() -> None:
    """A quarter of the tolerance from the anchor, so any two instants of a window are within half of it."""
    assert LIMITS.rotation_deg == pytest.approx(0.05)
    assert LIMITS.translation_m == pytest.approx(math.radians(0.05) * 3.0)  # 2.6 mm: 0.05 deg at 3 m
    assert StillThresholds.from_tolerance(0.1).rotation_deg == pytest.approx(0.025)
    assert LIMITS.camera_threshold_deg(1024) == pytest.approx(0.2)  # the tolerance: half a pixel is 0.18 deg
    assert LIMITS.camera_threshold_deg(64) == pytest.approx(2.8125)  # a tiny frame resolves only gross motion


def test_a_real_vlp16_still_then_creeping_then_turning() -> None:
    """VeloView's test capture (1200 rpm, 50 turns). Its first half second is still within the simulator's
    noise (0.02 deg, 1 mm from the first turn); then it creeps, 3 mm by 1.5 s, and moves off. The 90th-
    percentile range change of the old gate saw nothing until 1.9 s; the motion estimate sees the creep."""
    sweeps, _ = read_sweeps(LEGACY_PCAP, Vlp16Config(product_ids=None))
    complete = [s for s in sweeps if s.complete]
    grids = [direction_grid(np.stack([s.points[c] for c in "xyz"], axis=1), s.points["ring"]) for s in complete]
    first = plane_bins(grids[0])
    early = [estimate_motion(first, g) for g in grids[1:10]]  # 0.05-0.45 s
    assert max(m.rotation_deg for m in early) < LIMITS.rotation_deg / 2
    assert max(m.translation_m for m in early) < LIMITS.translation_m / 2
    assert min(m.inlier_fraction for m in early) > 0.9
    assert estimate_motion(first, grids[-1]).translation_m > 0.05  # 10 cm by 2.45 s
    gate = StillnessGate(LIMITS)
    restarts = []
    for k, sweep in enumerate(complete):
        gate.add_sweep(SweepSample(sweep.start.device, sweep.end.device, grids[k].range_m, grids[k]))
        if gate.sweeps == 1:
            restarts.append(k)
    start = complete[0].start.device
    first_window_s = complete[restarts[1]].start.device - start
    assert 1.0 < first_window_s < 1.6  # still long enough to take a pair, and the creep ends it well before 1.9 s
    assert len(restarts) > 8  # the motion after it keeps restarting the window


@pytest.fixture(scope="module", params=[("indoor", 0), ("indoor", 1), ("outdoor", 0)])
def place(request: pytest.FixtureRequest) -> tuple[object, Pose]:
    kind, index = request.param
    scene = make_scene(kind, 3, index)
    return scene, place_rig(scene, rng_for(SceneKind(kind), 3, index, "pose"), PAPER_T_CAMERA_LIDAR)


def sample_at(scene: object, camera_pose: Pose, seed: int, t: float = 0.0) -> SweepSample:
    sweep = scan(scene, camera_pose.compose(PAPER_T_CAMERA_LIDAR), np.random.default_rng(seed))  # type: ignore[arg-type]
    grid = direction_grid(sweep.points_lidar, sweep.ring)
    return SweepSample(t, t + 0.1, grid.range_m, grid)


def turned(pose: Pose, axis: np.ndarray, deg: float) -> Pose:
    return Pose(pose.rotation @ axis_angle_matrix(axis / np.linalg.norm(axis), math.radians(deg)), pose.translation_m)


def moved(pose: Pose, offset_m: list[float]) -> Pose:
    return Pose(pose.rotation, pose.translation_m + np.asarray(offset_m))


def test_the_motion_estimate_separates_noise_from_what_the_tolerance_allows(place: tuple[object, Pose]) -> None:
    scene, pose = place
    reference = plane_bins(sample_at(scene, pose, 0).directions)
    assert len(reference.index) > 2000

    def motion(camera_pose: Pose):  # noqa: ANN202
        return estimate_motion(reference, sample_at(scene, camera_pose, 1).directions)

    still = motion(pose)  # 2 cm range noise only
    assert still.rotation_deg < LIMITS.rotation_deg / 2 and still.translation_m < LIMITS.translation_m / 2
    for axis in ([1, 0, 0], [0, 1, 0], [0, 0, 1]):
        assert motion(turned(pose, np.array(axis, float), 0.1)).rotation_deg > LIMITS.rotation_deg  # tolerance / 2
    assert motion(moved(pose, [0.004, 0.004, 0.0])).translation_m > LIMITS.translation_m  # 5.7 mm
    assert motion(moved(pose, [0.0, 0.0, 0.005])).translation_m > LIMITS.translation_m
    for big in (moved(pose, [0.2, 0.0, 0.0]), turned(pose, np.array([0.0, 0.0, 1.0]), 2.0)):  # 20 cm, 2 deg
        gate = StillnessGate(LIMITS)
        gate.add_sweep(sample_at(scene, pose, 0))
        gate.add_sweep(sample_at(scene, big, 1))
        assert gate.sweeps == 1  # restarted


def test_still_window_grows_and_creep_restarts_it(place: tuple[object, Pose]) -> None:
    scene, pose = place
    gate = StillnessGate(LIMITS)
    for k in range(12):
        gate.add_sweep(sample_at(scene, pose, k, 0.1 * k))
    assert gate.sweeps == 12 and gate.still_for_s == pytest.approx(1.2)
    assert gate.held(1.0, 5) and not gate.held(1.5, 5) and not gate.held(1.0, 13)
    gate = StillnessGate(LIMITS)
    restarts = []
    for k in range(12):  # 1 mm per sweep (1 cm/s): each step alone is below the threshold, the drift is not
        gate.add_sweep(sample_at(scene, moved(pose, [0.001 * k, 0.0, 0.0]), k, 0.1 * k))
        if gate.sweeps == 1:
            restarts.append(k)
    assert restarts[0] == 0 and len(restarts) >= 3
    assert all(2 <= b - a <= 5 for a, b in zip(restarts, restarts[1:], strict=False))


def textured(seed: int, width: int = 512, height: int = 256) -> np.ndarray:
    rng = np.random.default_rng(seed)
    coarse = rng.uniform(0, 255, (height // 8, width // 8)).astype(np.float32)
    return np.asarray(np.clip(np.kron(coarse, np.ones((8, 8))), 0, 255), np.uint8)


def test_camera_shift_is_in_degrees_and_ignores_exposure() -> None:
    image = textured(0)
    assert camera_shift_deg(image, np.clip(image.astype(int) + 12, 0, 255).astype(np.uint8)) < 0.05  # exposure
    shifted = np.roll(image, 3, axis=1)  # 3 px of 512: 2.1 deg
    assert camera_shift_deg(image, shifted) == pytest.approx(3 * 360 / 512, abs=0.1)
    assert math.isnan(camera_shift_deg(image, np.zeros((128, 256), np.uint8)))  # sizes differ: no verdict


def test_camera_change_is_over_frames_in_the_window(place: tuple[object, Pose]) -> None:
    scene, pose = place
    gate = StillnessGate(LIMITS)
    image = textured(1)
    gate.add_frame(FrameSample(-0.5, np.roll(image, 20, axis=1)))  # before the window: ignored
    for k in range(5):
        gate.add_sweep(sample_at(scene, pose, k, 0.1 * k))
    assert gate.camera_change() is None
    gate.add_frame(FrameSample(0.2, image))
    assert gate.camera_change() is None  # one frame: nothing to compare
    gate.add_frame(FrameSample(0.3, image))
    assert gate.camera_change() == pytest.approx(0.0, abs=0.05) and not gate.camera_saw_motion()
    gate.add_frame(FrameSample(0.4, np.roll(image, 2, axis=1)))  # 1.4 deg, above 0.5 px (0.35 deg) at 512 px
    assert gate.camera_change() == pytest.approx(2 * 360 / 512, abs=0.1) and gate.camera_saw_motion()
