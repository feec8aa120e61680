"""The simulated Velodyne VLP-16: one 360 degree sweep from a LiDAR pose.

16 lasers fire in sequence (2.304 us apart, laser ids 0..15 at the elevations of
:data:`LASER_ELEVATIONS_DEG`), one firing sequence every 0.2 degrees: 1800 firings per turn at 600 rpm.
Laser ``k`` of firing ``f`` fires at ``time_s = f * FIRING_PERIOD_S + k * LASER_INTERVAL_S`` and the head
turns clockwise (seen from above) at 3600 deg/s, so its azimuth is ``3600 * time_s`` degrees (0 at the
start of the sweep, pointing along +x). The geometry is the VLP-16 manual's, which the decoder applies by
default (docs/vlp16.md): laser ``k`` sits :data:`LASER_OFFSETS_M` ``[k]`` (41.91 mm * tan(-w), up to 11.2 mm)
above the LiDAR origin along z, its ray starts there, and ``r`` is measured from there:
``x = r cos(w) cos(a)``, ``y = -r cos(w) sin(a)``, ``z = r sin(w) + offset``. So the packets the simulated rig
sends decode back onto the scene's surfaces.

Ranges get Gaussian noise and are reported in 2 mm steps (the VLP-16's range unit). Returns beyond
``max_range_m`` or before ``min_range_m``, and rays into the sky, give no point (range 0 in ``ranges_m``).
Reflectivity follows the VLP-16's calibrated scale: 0..100 for diffuse surfaces, here ``100 * albedo *
cos(incidence)`` plus noise (the sensor cannot know the incidence angle, so it is in the reading).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.sim.errors import SimError
from drivers.sim.pose import Pose, rotate
from drivers.sim.raycast import cast
from drivers.sim.scene import Scene
from drivers.vlp16 import LaserCalibration

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
I16 = NDArray[np.int16]

_MANUAL = LaserCalibration()  # the decoder's default geometry: what the simulated sensor is built to
LASER_ELEVATIONS_DEG = _MANUAL.elevation_deg  # (16,) deg of laser ids 0..15
LASER_OFFSETS_M = _MANUAL.vertical_offset_m  # (16,) m: each laser's origin above the LiDAR origin, along z
N_LASERS = 16
FIRINGS_PER_TURN = 1800
ROTATION_HZ = 10.0  # 600 rpm
FIRING_PERIOD_S = 1.0 / (ROTATION_HZ * FIRINGS_PER_TURN)
LASER_INTERVAL_S = 2.304e-6
DEG_PER_S = 360.0 * ROTATION_HZ
RANGE_RESOLUTION_M = 0.002
# ring = position in elevation order, 0 = lowest (-15 deg) .. 15 = highest (+15 deg)
RING_OF_LASER = np.argsort(np.argsort(LASER_ELEVATIONS_DEG)).astype(np.int16)
# A 64-ring street LiDAR like the pinhole sample's (Hesai Pandar64-like, approximate): a few wide rings up to
# +15 deg, a dense band of 49 rings 0.167 deg apart from +2 to -6 deg, then 1 deg steps to -14 deg and two
# low rings. The firing order is the table's, all lasers of a firing at one azimuth.
RINGS64_ELEVATIONS_DEG = tuple(float(e) for e in np.concatenate([
    [15.0, 11.0, 8.0, 5.0, 3.0], np.linspace(2.0, -6.0, 49), np.arange(-7.0, -14.5, -1.0), [-19.0, -25.0]]))


@dataclass(frozen=True)
class Footprint:
    """The beam's width, which makes mixed returns at depth edges. The VLP-16's spot leaves a 12.7 mm wide
    exit and diverges by 3 mrad horizontally (user manual); it is traced as ``sub_rays`` rays across its
    width. Echoes within ``merge_m`` of the nearest one merge into one return at their energy-weighted range
    (a "veil" point between a foreground edge and its background); farther echoes are separate and the
    sensor, in its default strongest-return mode, reports the one with more energy (energy ~ albedo x
    cos(incidence) / r^2, so a near edge wins with less than half the spot). ``merge_m`` is an assumption
    of the order of the pulse's length."""

    divergence_mrad: float = 3.0
    aperture_m: float = 0.0127
    sub_rays: int = 5
    merge_m: float = 0.6

    def __post_init__(self) -> None:
        if self.divergence_mrad < 0 or self.aperture_m < 0 or self.sub_rays < 2 or self.merge_m < 0:
            raise SimError("beam footprint needs divergence, aperture, merge distance >= 0 and >= 2 sub-rays")


@dataclass(frozen=True)
class LidarConfig:
    """Noise and limits: range noise sigma (m), usable range (m), reflectivity noise sigma (counts), the beam
    ``footprint`` (None: an ideal thin beam, no mixed returns), and energy-limited detection.

    ``detect_range_m``: a return needs the echo energy ``albedo * cos(incidence) / r^2`` of a 10 % diffuse
    target at normal incidence at this range, varied from pulse to pulse by a log-normal factor of sigma
    ``energy_noise`` (None: every hit within range returns). Dark asphalt seen at grazing incidence then drops
    out some tens of metres ahead, at random near the limit, as real returns do. 60 m for a 10 % target is an
    assumption in the VLP-16's range ("up to 100 m"), not a datasheet figure."""

    range_noise_m: float = 0.02
    min_range_m: float = 0.5
    max_range_m: float = 100.0
    reflectivity_noise: float = 1.0
    footprint: Footprint | None = None
    detect_range_m: float | None = None
    energy_noise: float = 0.3
    elevations_deg: tuple[float, ...] | None = None  # None: the VLP-16; else these lasers (deg), no offsets

    def __post_init__(self) -> None:
        if self.range_noise_m < 0 or self.reflectivity_noise < 0 or self.energy_noise < 0:
            raise SimError("LiDAR noise figures must be >= 0")
        if self.detect_range_m is not None and not self.detect_range_m > 0:
            raise SimError(f"LiDAR detection range must be > 0 m, got {self.detect_range_m}")
        if self.elevations_deg is not None and not (
                len(self.elevations_deg) >= 2 and all(-90 < e < 90 for e in self.elevations_deg)):
            raise SimError(f"LiDAR elevations must be 2 or more angles within (-90, 90) deg, got {self.elevations_deg}")
        if not 0 <= self.min_range_m < self.max_range_m:
            raise SimError(f"LiDAR range limits must satisfy 0 <= min < max, got {self.min_range_m}, "
                           f"{self.max_range_m}")


@dataclass(frozen=True)
class Sweep:
    """One turn of the VLP-16 (or of a multi-beam table, with L lasers for 16), in the LiDAR frame, points in
    firing order (firing-major, then laser id).

    Per point (N returns): ``points_lidar`` (N,3) float64 m; ``intensity`` (N,) float32 calibrated
    reflectivity 0..255; ``ring`` (N,) int16 elevation order (0 = -15 deg); ``laser_id`` (N,) int16 firing
    order 0..15; ``azimuth_deg`` (N,) float64 clockwise in [0, 360); ``time_s`` (N,) float64 since the start
    of the sweep. Per firing, for the packet encoder: ``ranges_m`` (1800,16) float64 indexed
    [firing, laser_id], multiples of 2 mm, 0 where there was no return; ``reflectivity`` (1800,16) uint8.
    Firing ``f`` starts at azimuth ``0.2 * f`` degrees.
    """

    points_lidar: F64
    intensity: F32
    ring: I16
    laser_id: I16
    azimuth_deg: F64
    time_s: F64
    ranges_m: F64
    reflectivity: NDArray[np.uint8]

    def __len__(self) -> int:
        return len(self.points_lidar)


def firing_grid(n_lasers: int = N_LASERS) -> tuple[F64, F64]:
    """``time_s`` and ``azimuth_deg`` of every (firing, laser id), each (1800, n_lasers). Lasers beyond the
    VLP-16's 16 fire at one time per firing (a multi-beam table, :class:`LidarConfig` ``elevations_deg``)."""
    interval = LASER_INTERVAL_S if n_lasers == N_LASERS else 0.0
    time_s = (np.arange(FIRINGS_PER_TURN)[:, None] * FIRING_PERIOD_S + np.arange(n_lasers)[None, :] * interval)
    return time_s, np.mod(DEG_PER_S * time_s, 360.0)


def _lasers(cfg: LidarConfig) -> tuple[F64, F64, NDArray[np.int16]]:
    """Elevation (deg), origin height (m) and ring of each laser id: the VLP-16's, or ``cfg``'s table."""
    if cfg.elevations_deg is None:
        return LASER_ELEVATIONS_DEG, LASER_OFFSETS_M, RING_OF_LASER
    elevation = np.asarray(cfg.elevations_deg, dtype=np.float64)
    ring = np.argsort(np.argsort(elevation, kind="stable"), kind="stable").astype(np.int16)
    return elevation, np.zeros(len(elevation)), ring


def beam_directions_lidar(azimuth_deg: F64, elevation_deg: F64) -> F64:
    """Unit beam directions (..., 3) in the LiDAR frame for clockwise azimuth and elevation (degrees)."""
    a, w = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.stack([np.cos(w) * np.cos(a), -np.cos(w) * np.sin(a), np.sin(w)], axis=-1)


@dataclass(frozen=True)
class BeamReturns:
    """What every beam of one turn hits before any noise: ``depth_m`` (M,) m from its laser's origin (inf:
    nothing) and ``bright`` (M,) ``albedo * cos(incidence)``, M = 1800 x lasers, firing-major."""

    depth_m: F64
    bright: F64


def beam_returns(scene: Scene, pose_world_lidar: Pose, config: LidarConfig | None = None) -> BeamReturns:
    """The noiseless part of :func:`scan` (the costly ray casting): a rig that stands still hits the same
    surfaces turn after turn, so a caller may reuse it and draw only the noise anew."""
    cfg = config or LidarConfig()
    elevation_deg, offsets_m, _ = _lasers(cfg)
    beams, laser_origins = _beams(elevation_deg, offsets_m)
    if cfg.footprint is None:
        beams_world = rotate(beams, pose_world_lidar.rotation)
        hits = cast(scene, pose_world_lidar.apply(laser_origins), beams_world)
        return BeamReturns(hits.depth_m, hits.albedo * np.abs(np.sum(hits.normal * beams_world, axis=1)))
    return BeamReturns(*_footprint_returns(scene, pose_world_lidar, laser_origins, beams, cfg.footprint))


def _beams(elevation_deg: F64, offsets_m: F64) -> tuple[F64, F64]:
    """Unit beam directions (M,3) and laser origins (M,3) m in the LiDAR frame, firing-major."""
    n_lasers = len(elevation_deg)
    _, azimuth_deg = firing_grid(n_lasers)
    beams = beam_directions_lidar(azimuth_deg, np.broadcast_to(elevation_deg, azimuth_deg.shape)).reshape(-1, 3)
    laser_origins = np.zeros_like(beams)
    laser_origins[:, 2] = np.tile(offsets_m, FIRINGS_PER_TURN)
    return beams, laser_origins


def scan(scene: Scene, pose_world_lidar: Pose, rng: np.random.Generator, config: LidarConfig | None = None,
         returns: BeamReturns | None = None) -> Sweep:
    """Simulate one sweep from ``pose_world_lidar`` (LiDAR frame -> world); ``returns``: this pose's
    :func:`beam_returns` when the caller has them already (only the noise is drawn then)."""
    cfg = config or LidarConfig()
    elevation_deg, offsets_m, ring_of_laser = _lasers(cfg)
    n_lasers = len(elevation_deg)
    time_s, azimuth_deg = firing_grid(n_lasers)
    beams, laser_origins = _beams(elevation_deg, offsets_m)
    hit = returns if returns is not None else beam_returns(scene, pose_world_lidar, cfg)
    depth_m, bright = hit.depth_m, hit.bright
    noisy = depth_m + rng.normal(0.0, cfg.range_noise_m, size=len(beams))
    ranges = np.round(noisy / RANGE_RESOLUTION_M) * RANGE_RESOLUTION_M
    valid = np.isfinite(depth_m) & (ranges >= cfg.min_range_m) & (ranges <= cfg.max_range_m)
    counts = 100.0 * bright + rng.normal(0.0, cfg.reflectivity_noise, size=len(beams))
    if cfg.detect_range_m is not None:  # drawn last: the same seed gives the same ranges with or without it
        valid &= _detected(depth_m, bright, cfg.detect_range_m, cfg.energy_noise, rng)
    ranges = np.where(valid, ranges, 0.0)
    reflectivity = np.where(valid, np.clip(np.rint(counts), 0, 255), 0).astype(np.uint8)
    laser = np.tile(np.arange(n_lasers, dtype=np.int16), FIRINGS_PER_TURN)
    keep = np.flatnonzero(valid)
    return Sweep(
        points_lidar=ranges[keep, None] * beams[keep] + laser_origins[keep],
        intensity=reflectivity[keep].astype(np.float32),
        ring=ring_of_laser[laser[keep]],
        laser_id=laser[keep],
        azimuth_deg=azimuth_deg.reshape(-1)[keep],
        time_s=time_s.reshape(-1)[keep],
        ranges_m=ranges.reshape(FIRINGS_PER_TURN, n_lasers),
        reflectivity=reflectivity.reshape(FIRINGS_PER_TURN, n_lasers),
    )


def _detected(depth_m: F64, bright: F64, detect_range_m: float, energy_noise: float,
              rng: np.random.Generator) -> NDArray[np.bool_]:
    """(M,) whether each beam's echo (range ``depth_m``, ``albedo * cos(incidence)`` ``bright``) is strong
    enough to be detected (:class:`LidarConfig`)."""
    pulse = np.exp(rng.normal(0.0, energy_noise, size=len(depth_m)))
    return np.asarray(_echo_energy(depth_m, bright) * pulse >= 0.1 / detect_range_m**2, dtype=bool)


def _echo_energy(depth_m: F64, bright: F64) -> F64:
    """Echo energy ``albedo * cos(incidence) / r^2`` (same shape as ``depth_m``; 0 where inf: no hit), the range
    floored at 0.5 m."""
    hit = np.isfinite(depth_m)
    return np.where(hit, bright / np.maximum(np.where(hit, depth_m, 1.0), 0.5) ** 2, 0.0)


def _footprint_returns(scene: Scene, pose_world_lidar: Pose, origins: F64, beams: F64,
                       footprint: Footprint) -> tuple[F64, F64]:
    """Range (M,) m (inf: no return) and brightness ``albedo * cos(incidence)`` (M,) of each beam (M,3) from
    ``origins`` (M,3) (LiDAR frame) with a horizontal footprint (:class:`Footprint`), reported along the
    beam's nominal direction as the sensor does."""
    k = footprint.sub_rays
    tangent = np.stack([-beams[:, 1], beams[:, 0], np.zeros(len(beams))], axis=1)  # horizontal, across the beam
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    across = np.linspace(-0.5, 0.5, k)
    dirs = beams[:, None, :] + np.tan(across * footprint.divergence_mrad * 1e-3)[None, :, None] * tangent[:, None]
    starts = origins[:, None, :] + (across * footprint.aperture_m)[None, :, None] * tangent[:, None]
    dirs_world = rotate(dirs.reshape(-1, 3), pose_world_lidar.rotation)
    dirs_world /= np.linalg.norm(dirs_world, axis=1, keepdims=True)
    hits = cast(scene, pose_world_lidar.apply(starts.reshape(-1, 3)), dirs_world)
    depth = hits.depth_m.reshape(-1, k)
    bright = (hits.albedo * np.abs(np.sum(hits.normal * dirs_world, axis=1))).reshape(-1, k)
    hit = np.isfinite(depth)
    # (+ a tiny floor: a black surface still returns a range when nothing brighter shares the spot)
    energy = _echo_energy(depth, bright) + hit * 1e-12
    nearest = np.min(np.where(hit, depth, np.inf), axis=1, keepdims=True)
    near = hit & (depth <= nearest + footprint.merge_m)
    far = hit & ~near
    use = np.where((energy * near).sum(axis=1, keepdims=True) >= (energy * far).sum(axis=1, keepdims=True), near, far)
    weight = energy * use
    total = np.maximum(weight.sum(axis=1), 1e-300)
    range_m = (weight * np.where(hit, depth, 0.0)).sum(axis=1) / total
    out_bright = (weight * bright).sum(axis=1) / total
    any_hit = hit.any(axis=1)
    return np.where(any_hit, range_m, np.inf), np.where(any_hit, out_bright, 0.0)
