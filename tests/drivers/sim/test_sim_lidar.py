"""The simulated VLP-16 against hand geometry and the documented VLP-16 conventions."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.sim import Footprint, LidarConfig, Lighting, Pose, SceneBuilder, SceneKind, SimError, scan
from drivers.sim.lidar import FIRINGS_PER_TURN, LASER_ELEVATIONS_DEG, RINGS64_ELEVATIONS_DEG

# The VLP-16 manual: laser k's origin is 41.91 mm * tan(-elevation) above the sensor origin (11.2 mm at -15 deg).
OFFSET_M = 0.04191 * np.tan(np.radians(-LASER_ELEVATIONS_DEG))
LIGHT = Lighting(sun_dir_world=np.array([0.0, 0.0, 1.0]), ambient=0.5, sun=0.5, shadows=False)
HEIGHT_M = 1.7


def _floor_scene(albedo: float = 0.5):
    """Only a floor (top at z = 0): upward beams see the sky."""
    b = SceneBuilder()
    b.box((-500.0, -500.0, -1.0), (500.0, 500.0, 0.0), albedo, texture=0.0)
    return b.build(SceneKind.OUTDOOR, LIGHT, (0, 1, 0, 1), 0.0, (1.0, 1.5))


def _level_pose() -> Pose:
    return Pose(np.eye(3), np.array([0.0, 0.0, HEIGHT_M]))


def test_floor_ranges_follow_the_elevation_of_each_laser():
    sweep = scan(_floor_scene(), _level_pose(), np.random.default_rng(0), LidarConfig(range_noise_m=0.0))
    # A beam at elevation w < 0 from its laser at height h + offset meets the floor after (h + offset) / sin(-w)
    # metres (-1 deg: 97.4 m, inside the 100 m range); upward beams see the sky: range 0, no return.
    w = np.radians(LASER_ELEVATIONS_DEG)
    expected = np.where(w < 0, (HEIGHT_M + OFFSET_M) / np.sin(np.maximum(-w, 1e-9)), 0.0)
    expected = np.where(expected <= 100.0, expected, 0.0)
    for laser in range(16):
        ranges = sweep.ranges_m[:, laser]
        np.testing.assert_allclose(ranges, expected[laser], atol=0.001 + 1e-9)  # 2 mm range steps
    assert sweep.ranges_m.shape == (FIRINGS_PER_TURN, 16)


def test_points_follow_the_vlp16_formula_and_ring_order():
    sweep = scan(_floor_scene(), _level_pose(), np.random.default_rng(1), LidarConfig(range_noise_m=0.02))
    p = sweep.points_lidar - np.c_[np.zeros((len(sweep), 2)), OFFSET_M[sweep.laser_id]]  # from each laser
    r = np.linalg.norm(p, axis=1)
    # Inverting x = r cos w cos a, y = -r cos w sin a, z = r sin w + offset (docs/vlp16.md):
    elevation = np.degrees(np.arcsin(p[:, 2] / r))
    azimuth = np.mod(np.degrees(np.arctan2(-p[:, 1], p[:, 0])), 360.0)
    np.testing.assert_allclose(elevation, LASER_ELEVATIONS_DEG[sweep.laser_id], atol=1e-9)
    d_az = np.mod(azimuth - sweep.azimuth_deg + 180.0, 360.0) - 180.0
    np.testing.assert_allclose(d_az, 0.0, atol=1e-9)
    # ring = elevation order, 0 = lowest
    np.testing.assert_array_equal(sweep.ring, np.round((LASER_ELEVATIONS_DEG[sweep.laser_id] + 15) / 2))
    # The per-firing grid holds the same ranges in firing-major order.
    grid = sweep.ranges_m.reshape(-1)
    np.testing.assert_allclose(r, grid[grid > 0], rtol=1e-12)
    assert np.all(np.diff(sweep.time_s) > 0) and 0 <= sweep.time_s.min() and sweep.time_s.max() < 0.1
    # 600 rpm: the head turns 3600 deg/s, clockwise, so azimuth = 3600 * time.
    np.testing.assert_allclose(np.mod(3600.0 * sweep.time_s, 360.0), sweep.azimuth_deg, atol=1e-9)


def test_range_noise_sigma_and_quantisation():
    sigma = 0.03
    sweep = scan(_floor_scene(), _level_pose(), np.random.default_rng(2), LidarConfig(range_noise_m=sigma))
    w = np.radians(LASER_ELEVATIONS_DEG[sweep.laser_id])
    true = (HEIGHT_M + OFFSET_M[sweep.laser_id]) / np.sin(-w)
    residual = sweep.ranges_m.reshape(-1)[sweep.ranges_m.reshape(-1) > 0] - true
    assert residual.std() == pytest.approx(sigma, rel=0.05)
    assert abs(residual.mean()) < 0.002
    steps = sweep.ranges_m[sweep.ranges_m > 0] / 0.002
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)


def test_points_lie_on_the_surface_they_hit():
    """The points are where the rays end: on the floor, whatever the laser's offset (the ground truth)."""
    sweep = scan(_floor_scene(), _level_pose(), np.random.default_rng(5), LidarConfig(range_noise_m=0.0))
    np.testing.assert_allclose(sweep.points_lidar[:, 2], -HEIGHT_M, atol=0.001)  # half the 2 mm range step
    assert len(sweep) > 1000


def test_range_limits_and_sky_give_no_return():
    sweep = scan(_floor_scene(), _level_pose(), np.random.default_rng(3),
                 LidarConfig(range_noise_m=0.0, max_range_m=20.0))
    assert np.all(LASER_ELEVATIONS_DEG[sweep.laser_id] < 0)  # the sky gives nothing
    assert np.linalg.norm(sweep.points_lidar, axis=1).max() <= 20.0
    # -3 deg reaches the floor at 32 m and -1 deg at 97 m: beyond 20 m, no return.
    assert not np.isin(sweep.laser_id, np.flatnonzero(LASER_ELEVATIONS_DEG >= -3)).any()
    with pytest.raises(SimError, match="range limits"):
        LidarConfig(min_range_m=5.0, max_range_m=2.0)


def test_reflectivity_is_albedo_times_cosine_of_incidence():
    albedo = 0.6
    sweep = scan(_floor_scene(albedo), _level_pose(), np.random.default_rng(4), LidarConfig(range_noise_m=0.0))
    # Beam at elevation w onto a horizontal floor: cos(incidence) = sin(-w). Calibrated scale 0..100.
    w = np.radians(LASER_ELEVATIONS_DEG[sweep.laser_id])
    expected = 100.0 * albedo * np.sin(-w)
    assert np.abs(sweep.intensity - expected).max() <= 5.0
    assert abs(np.mean(sweep.intensity - expected)) < 0.1
    assert sweep.intensity.dtype == np.float32 and sweep.reflectivity.dtype == np.uint8


def test_energy_limited_detection_drops_a_dark_floor_at_grazing_incidence_first():
    """Echo energy albedo * cos(incidence) / r^2 against a 10 % target at normal incidence at detect_range_m.
    On a floor of albedo 0.12 from 1.7 m, cos(incidence) = sin(-w): each laser's share of returns follows
    the chance that the log-normal pulse factor lifts its energy over the limit."""
    from scipy.stats import norm

    albedo, detect_m, noise = 0.12, 60.0, 0.3
    cfg = LidarConfig(range_noise_m=0.0, detect_range_m=detect_m, energy_noise=noise)
    sweep = scan(_floor_scene(albedo), _level_pose(), np.random.default_rng(5), cfg)
    w = np.radians(LASER_ELEVATIONS_DEG)
    down = w < 0
    r = (HEIGHT_M + OFFSET_M) / np.sin(np.maximum(-w, 1e-9))
    energy = albedo * np.sin(np.maximum(-w, 1e-9)) / r**2
    expected = norm.sf(np.log(0.1 / detect_m**2 / energy) / noise)  # P(energy * pulse >= limit)
    share = (sweep.ranges_m > 0).mean(axis=0)
    # 1800 firings per laser: a binomial share's sigma is at most 1.2 %
    np.testing.assert_allclose(share[down & (r <= 100.0)], expected[down & (r <= 100.0)], atol=0.05)
    assert share[np.argmin(np.where(down, -w, np.inf))] < 0.05  # -1 deg, 97 m: almost nothing
    assert share[np.argmin(w)] == 1.0  # -15 deg, 6.6 m: every pulse
    assert np.any((share > 0.2) & (share < 0.8))  # a patchy ring in between (-5 deg, 19 m: about half)
    same = scan(_floor_scene(albedo), _level_pose(), np.random.default_rng(5), LidarConfig(range_noise_m=0.0))
    kept = sweep.ranges_m > 0
    np.testing.assert_array_equal(sweep.ranges_m[kept], same.ranges_m[kept])  # the same draws otherwise
    with pytest.raises(SimError, match="detection range"):
        LidarConfig(detect_range_m=0.0)


def _pole_scene(gap_m: float):
    """A floor, a 0.2 m wide pole 4 m ahead along +x and a wall ``gap_m`` behind it."""
    b = SceneBuilder()
    b.box((-500.0, -500.0, -1.0), (500.0, 500.0, 0.0), 0.5, texture=0.0)
    b.box((3.9, -0.1, 0.0), (4.1, 0.1, 4.0), 0.5, texture=0.0)
    b.box((4.1 + gap_m, -20.0, 0.0), (4.6 + gap_m, 20.0, 6.0), 0.5, texture=0.0)
    return b.build(SceneKind.OUTDOOR, LIGHT, (0, 1, 0, 1), 0.0, (1.0, 1.5))


def _horizontal_ranges(gap_m: float, footprint: Footprint | None) -> np.ndarray:
    """Ranges of the laser nearest 0 deg elevation over the firings within 10 deg of forward."""
    sweep = scan(_pole_scene(gap_m), _level_pose(), np.random.default_rng(0),
                 LidarConfig(range_noise_m=0.0, footprint=footprint))
    laser = int(np.argmin(np.abs(LASER_ELEVATIONS_DEG)))
    az = np.mod(np.arange(FIRINGS_PER_TURN) * 0.2 + 180.0, 360.0) - 180.0
    return sweep.ranges_m[np.abs(az) < 10.0, laser]


def test_beam_footprint_makes_veils_on_small_depth_gaps_and_widens_near_edges():
    # 0.3 m behind the pole (within a pulse): mixed returns between the two surfaces, none with a thin beam.
    for footprint, veils in ((None, 0), (Footprint(), 1)):
        r = _horizontal_ranges(0.3, footprint)
        between = np.count_nonzero((r > 3.95) & (r < 4.35))  # pole face 3.9 m, wall 4.4 m (+-2 mm steps)
        assert (between >= veils) if veils else between == 0
    # 3 m behind (separate echoes): no veil, and the nearer, brighter echo wins with less than half the spot,
    # so the pole looks wider than with a thin beam.
    thin, wide = _horizontal_ranges(3.0, None), _horizontal_ranges(3.0, Footprint(divergence_mrad=30.0))
    assert np.count_nonzero((wide > 4.2) & (wide < 7.0)) == 0
    assert np.count_nonzero(wide < 4.2) > np.count_nonzero(thin < 4.2)


def test_a_64_ring_table_scans_each_ring_at_its_elevation_from_the_origin():
    config = LidarConfig(range_noise_m=0.0, elevations_deg=RINGS64_ELEVATIONS_DEG)
    sweep = scan(_floor_scene(), _level_pose(), np.random.default_rng(2), config)
    p = sweep.points_lidar
    elevation = np.degrees(np.arcsin(p[:, 2] / np.linalg.norm(p, axis=1)))
    table = np.asarray(RINGS64_ELEVATIONS_DEG)
    np.testing.assert_allclose(elevation, table[sweep.laser_id], atol=1e-3)  # 2 mm range steps
    # ring = elevation order, 0 = lowest; only the rings below the horizon within 100 m reach the floor
    np.testing.assert_array_equal(sweep.ring, np.argsort(np.argsort(table))[sweep.laser_id])
    assert sweep.ranges_m.shape == (FIRINGS_PER_TURN, 64)
    reach = (table < 0) & (HEIGHT_M / np.sin(np.radians(np.maximum(-table, 1e-9))) <= 100.0)
    assert set(np.unique(sweep.laser_id)) == set(np.flatnonzero(reach))


@pytest.mark.parametrize("table", [(5.0,), (0.0, 95.0)])
def test_a_bad_elevation_table_is_refused(table):
    with pytest.raises(SimError, match="elevations"):
        LidarConfig(elevations_deg=table)
