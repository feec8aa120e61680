"""A Ladybug5-like panorama stitched from separate sensors: parallax, blended seams, vignetting, gains.

A real Ladybug5 is not one projection centre. Its five side sensors look out at azimuths 0, +-72, +-144 deg
from centres ``sensor_radius_m`` out along their axes (6.1 cm on real heads: drivers.ladybug5.rig), and the SDK
stitches their images onto a sphere of radius ``sphere_radius_m`` around the head: panorama direction ``d`` shows
what the sensor sees towards the sphere point ``S = sphere_radius_m * d``, i.e. along ``S - c_k`` from the sensor
centre ``c_k``. An object at that radius lands where a single centre would put it; a nearer one is displaced by
up to about ``sensor_radius_m * sin(angle off the sensor axis) * (1/r - 1/sphere_radius)`` rad, in opposite directions
on the two sides of a seam. Within ``blend_deg`` of a seam the two sensors' views are cross-faded (near objects
there show twice, "ghosts"). Each sensor has its own exposure gain and a residual radial falloff.

Not modelled: the top sensor (it sees above ~50 deg elevation, beyond the VLP-16's beams on this rig: the
side sensors fill that part), lens distortion residuals and the sensors' rolling readout.

All vectors are in the panorama camera frame (x forward, y left, z up), metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.rig import LADYBUG5_CAMERA_RADIUS_M
from drivers.sim.errors import SimError

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

N_SIDE = 5
SECTOR_RAD = 2.0 * np.pi / N_SIDE


@dataclass(frozen=True)
class StitchConfig:
    """The stitched head: ``sensor_radius_m`` (sensor centre from the head's centre: the nominal Ladybug5
    head's, from real units' factory calibrations), ``sphere_radius_m`` (the SDK's stitching distance, 20 m by
    default there), ``blend_deg`` (half-width of the cross-fade at each seam), ``vignetting`` (relative loss of linear
    radiance at ``falloff_deg`` off a sensor's axis and beyond, quadratic in the angle), ``gain_sigma`` (per-sensor
    exposure spread, relative, drawn per capture)."""

    sensor_radius_m: float = LADYBUG5_CAMERA_RADIUS_M
    sphere_radius_m: float = 20.0
    blend_deg: float = 3.0
    vignetting: float = 0.15
    falloff_deg: float = 40.0
    gain_sigma: float = 0.04

    def __post_init__(self) -> None:
        if self.sensor_radius_m < 0 or self.sphere_radius_m <= 0:
            raise SimError("stitching needs sensor_radius_m >= 0 and sphere_radius_m > 0")
        if not 0 <= self.blend_deg < np.degrees(SECTOR_RAD) / 2:
            raise SimError(f"blend_deg must be in [0, 36), got {self.blend_deg}")
        if not 0 <= self.vignetting < 1 or self.gain_sigma < 0 or self.falloff_deg <= 0:
            raise SimError("vignetting must be in [0, 1), gain_sigma >= 0, falloff_deg > 0")


class SensorRays(NamedTuple):
    """One sensor's share of the panorama rays: ``weight`` (N,) blend weight (0: not seen by this slot),
    ``origins`` (N,3) m sensor centres, ``directions`` (N,3) unit rays, ``gain`` (N,) exposure x falloff."""

    weight: F64
    origins: F64
    directions: F64
    gain: F64


def sensor_axes() -> F64:
    """(5,3) unit optical axes of the side sensors (azimuth 0 = forward, counter-clockwise from above)."""
    a = np.arange(N_SIDE) * SECTOR_RAD
    return np.stack([np.cos(a), np.sin(a), np.zeros(N_SIDE)], axis=1)


def sensor_gains(config: StitchConfig, rng: np.random.Generator) -> F64:
    """(5,) per-sensor exposure gains of one capture."""
    return np.asarray(1.0 + config.gain_sigma * rng.standard_normal(N_SIDE), dtype=np.float64)


def split_rays(rays_cam: F64, config: StitchConfig, gains: F64) -> tuple[SensorRays, SensorRays]:
    """The primary and secondary sensor of every panorama ray ``rays_cam`` (N,3) unit: the nearest sensor by
    azimuth, and across a seam's blend band its neighbour (weights sum to 1)."""
    theta = np.arctan2(rays_cam[:, 1], rays_cam[:, 0])
    k1 = np.mod(np.rint(theta / SECTOR_RAD), N_SIDE).astype(np.int64)
    off = np.angle(np.exp(1j * (theta - k1 * SECTOR_RAD)))  # (-36, 36] deg from the primary axis
    k2 = np.mod(k1 + np.where(off >= 0, 1, -1), N_SIDE)
    blend = np.radians(config.blend_deg)
    to_seam = SECTOR_RAD / 2 - np.abs(off)
    w1 = np.ones(len(rays_cam)) if blend == 0 else np.clip(0.5 + to_seam / (2.0 * blend), 0.5, 1.0)
    return (_sensor(rays_cam, k1, w1, config, gains), _sensor(rays_cam, k2, 1.0 - w1, config, gains))


def _sensor(rays_cam: F64, k: I64, weight: F64, config: StitchConfig, gains: F64) -> SensorRays:
    axes = sensor_axes()[k]
    origins = config.sensor_radius_m * axes
    towards = config.sphere_radius_m * rays_cam - origins
    directions = towards / np.linalg.norm(towards, axis=1, keepdims=True)
    off_axis = np.arccos(np.clip(np.einsum("ij,ij->i", directions, axes), -1.0, 1.0))
    # Capped at falloff_deg: towards the zenith and nadir (the top sensor's and the tripod's) it stays there.
    falloff = 1.0 - config.vignetting * np.minimum(off_axis / np.radians(config.falloff_deg), 1.0) ** 2
    return SensorRays(weight, origins, directions, gains[k] * np.maximum(falloff, 0.0))
