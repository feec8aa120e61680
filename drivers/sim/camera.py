"""The simulated camera: a Ladybug5-like equirectangular panorama, and pinhole views of the same scene.

Radiance is Lambertian (``albedo * (ambient + sun * cos)``, hard sun shadows outdoors, lamps emit), the sky
fills rays that hit nothing. A pixel integrates radiance over its footprint (``supersample`` x
``supersample`` rays, averaged in linear radiance), then the camera applies its exposure, a gamma 1/2.2
response and Gaussian read noise in 8-bit grey levels.

Panorama projection (docs/conventions.md, written here again because drivers may not import calib):
camera frame x forward, y left, z up; pixel (row i, column j) has centre ``(u, v) = (j, i)`` with
``u = w (pi - theta) / (2 pi)``, ``v = h phi / pi``, ``theta = atan2(y, x)``, ``phi = acos(z / r)``.
"""

from __future__ import annotations

import typing
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.sim.errors import SimError
from drivers.sim.pose import Pose, rotate
from drivers.sim.raycast import cast
from drivers.sim.scene import Scene
from drivers.sim.stitched import StitchConfig, sensor_gains, split_rays

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]

GAMMA = 2.2
SHADOW_OFFSET_M = 1e-3  # shadow rays start this far off the surface so they do not hit it again
BAND_RAYS = 1 << 19  # rays rendered at once (bounds memory)

# Maps OpenCV optical-frame vectors (z forward, x right, y down) into the panorama frame (x fwd, y left, z up).
ROTATION_PANORAMA_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def equirectangular_rays(uv: F64, width: int, height: int) -> F64:
    """Unit rays (N,3) in the panorama frame through image points ``uv`` (N,2) px."""
    theta = np.pi - 2.0 * np.pi * uv[:, 0] / width
    phi = np.pi * uv[:, 1] / height
    return np.stack([np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta), np.cos(phi)], axis=1)


def radiance(scene: Scene, origin_world: F64, directions_world: F64) -> F64:
    """Linear radiance (N,) arriving at ``origin_world`` (3,) or (N,3) m from unit ``directions_world`` (N,3)."""
    light = scene.lighting
    hits = cast(scene, origin_world, directions_world)
    sun_dir = np.asarray(light.sun_dir_world, dtype=np.float64)
    cos_sun = np.maximum(np.einsum("ij,j->i", hits.normal, sun_dir), 0.0)
    if light.shadows:
        lit = np.flatnonzero(hits.hit & (cos_sun > 0))
        origins = np.broadcast_to(origin_world, directions_world.shape)[lit]  # one centre or one per ray
        points = origins + hits.depth_m[lit, None] * directions_world[lit]
        starts = points + SHADOW_OFFSET_M * hits.normal[lit]
        blocked = cast(scene, starts, np.broadcast_to(sun_dir, starts.shape)).hit
        cos_sun[lit[blocked]] = 0.0
    out = hits.albedo * (light.ambient + light.sun * cos_sun) + hits.emission
    up = np.clip(directions_world[:, 2], 0.0, 1.0)
    sky = light.sky_horizon + (light.sky_zenith - light.sky_horizon) * up
    return np.where(hits.hit, out, sky)


def tone(scene: Scene, linear: F64) -> F64:
    """The camera response: exposure, saturation at 1, gamma 1/2.2 -> display value in [0, 1]."""
    return np.clip(scene.lighting.exposure * linear, 0.0, 1.0) ** (1.0 / GAMMA)


def render_rays(scene: Scene, origin_world: F64, rotation_world_cam: F64, rays_cam: F64) -> F32:
    """Noise-free display value (N,) float32 in [0, 1] seen along ``rays_cam`` (N,3) (one ray each).

    ``rotation_world_cam`` (3,3) maps camera-frame vectors into the world; ``origin_world`` (3,) m is the
    camera centre. Use any camera frame (panorama or optical) as long as the rays are in it.
    """
    rays = np.asarray(rays_cam, dtype=np.float64)
    if rays.ndim != 2 or rays.shape[1] != 3:
        raise SimError(f"rays_cam must be (N,3), got shape {rays.shape}")
    out = np.empty(len(rays), dtype=np.float32)
    for s in range(0, len(rays), BAND_RAYS):
        dirs = rotate(rays[s : s + BAND_RAYS], rotation_world_cam)
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        out[s : s + BAND_RAYS] = tone(scene, radiance(scene, np.asarray(origin_world, float), dirs))
    return out


def render_panorama(scene: Scene, pose_world_camera: Pose, width: int, height: int, rng: np.random.Generator,
                    noise_grey: float = 1.5, supersample: int = 2, color: bool = False,
                    stitch: StitchConfig | None = None, jpeg_quality: int | None = None) -> U8:
    """An equirectangular panorama (H,W) uint8 grey, or (H,W,3) BGR when ``color``: from one projection
    centre, or stitched from the Ladybug5's side sensors (``stitch``: parallax, seams, gains, falloff;
    drivers.sim.stitched), then JPEG-compressed at ``jpeg_quality`` (1..100) if given."""
    gains = None if stitch is None else sensor_gains(stitch, rng)  # drawn first: the noise then follows
    display = panorama_display(scene, pose_world_camera, width, height, supersample, stitch, gains)
    image = quantise(display, rng, noise_grey, color)
    return image if jpeg_quality is None else jpeg_round_trip(image, jpeg_quality)


def panorama_display(scene: Scene, pose_world_camera: Pose, width: int, height: int, supersample: int = 2,
                     stitch: StitchConfig | None = None, gains: F64 | None = None) -> F64:
    """The noise-free panorama (H,W) in [0, 1] that :func:`render_panorama` quantises: what a still camera
    sees in every frame (``gains``: the stitched sensors', drawn by the caller)."""
    _check_size(width, height, supersample)
    rays_cam = _panorama_rays(width, height, supersample)
    per_row = width * supersample * supersample
    band = max(1, BAND_RAYS // (per_row * (1 if stitch is None else 2)))
    linear = np.empty((height, width))
    for r0 in range(0, height, band):
        r1 = min(r0 + band, height)
        rays = rays_cam[r0 * per_row : r1 * per_row]
        if stitch is None or gains is None:
            lin = radiance(scene, pose_world_camera.translation_m, rotate(rays, pose_world_camera.rotation))
        else:
            lin = _stitched_radiance(scene, pose_world_camera, rays, stitch, gains)
        linear[r0:r1] = lin.reshape(-1, supersample, width, supersample).mean(axis=(1, 3))
    return tone(scene, linear)


def _stitched_radiance(scene: Scene, pose_world_camera: Pose, rays_cam: F64, stitch: StitchConfig,
                       gains: F64) -> F64:
    """Linear radiance (N,) of panorama rays as the blend of the sensors that see them."""
    out = np.zeros(len(rays_cam))
    for sensor in split_rays(rays_cam, stitch, gains):
        seen = np.flatnonzero(sensor.weight > 0)
        if seen.size == 0:
            continue
        origins = pose_world_camera.apply(sensor.origins[seen])
        dirs = rotate(sensor.directions[seen], pose_world_camera.rotation)
        out[seen] += sensor.weight[seen] * sensor.gain[seen] * radiance(scene, origins, dirs)
    return out


def jpeg_round_trip(image: U8, quality: int) -> U8:
    """``image`` as it comes back from JPEG at ``quality`` (blocking and ringing at edges)."""
    if not 1 <= quality <= 100:
        raise SimError(f"JPEG quality must be 1..100, got {quality}")
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise SimError("OpenCV could not JPEG-encode the simulated image")
    flag = cv2.IMREAD_COLOR if image.ndim == 3 else cv2.IMREAD_GRAYSCALE
    return np.asarray(cv2.imdecode(data, flag), dtype=np.uint8)


@lru_cache(maxsize=2)
def _panorama_rays(width: int, height: int, supersample: int) -> F64:
    """Camera-frame rays (H*s*W*s, 3) of every sub-pixel sample, row by row; read-only, cached per size."""
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    vv, uu = np.meshgrid((np.arange(height)[:, None] + sub).ravel(), (np.arange(width)[:, None] + sub).ravel(),
                         indexing="ij")
    rays = equirectangular_rays(np.stack([uu.ravel(), vv.ravel()], axis=1), width, height)
    rays.flags.writeable = False
    return rays


def render_pinhole(scene: Scene, origin_world: F64, rotation_world_optical: F64, K: F64, width: int,
                   height: int, rng: np.random.Generator, D: F64 | None = None, noise_grey: float = 1.5,
                   supersample: int = 2, color: bool = False) -> U8:
    """An OpenCV pinhole image (H,W) uint8 (or (H,W,3) BGR) with intrinsics ``K`` (3,3) px, ``D`` (k1 k2 p1 p2 [k3]).

    ``rotation_world_optical`` maps optical-frame vectors (z forward, x right, y down) into the world; for a
    camera looking along the panorama's forward axis use ``R_world_panorama @ ROTATION_PANORAMA_OPTICAL``.
    The image is the raw (distorted) one, as ``cv2.projectPoints`` maps points into it.
    """
    _check_size(width, height, supersample)
    k = np.asarray(K, dtype=np.float64)
    if k.shape != (3, 3):
        raise SimError(f"K must be 3x3, got shape {k.shape}")
    dist = np.zeros(5) if D is None else np.asarray(D, dtype=np.float64).reshape(-1)
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    vv, uu = np.meshgrid((np.arange(height)[:, None] + sub).ravel(), (np.arange(width)[:, None] + sub).ravel(),
                         indexing="ij")
    pixels = np.stack([uu.ravel(), vv.ravel()], axis=1).reshape(-1, 1, 2)
    normalised = cv2.undistortPoints(pixels, k, dist).reshape(-1, 2)
    rays = typing.cast(F64, np.column_stack([normalised, np.ones(len(normalised))]))
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    dirs = rotate(rays, rotation_world_optical)
    origin = np.asarray(origin_world, dtype=np.float64)
    lin = np.concatenate([radiance(scene, origin, dirs[s : s + BAND_RAYS]) for s in range(0, len(dirs), BAND_RAYS)])
    linear = lin.reshape(height, supersample, width, supersample).mean(axis=(1, 3))
    return quantise(tone(scene, linear), rng, noise_grey, color)


def quantise(display: F64, rng: np.random.Generator, noise_grey: float, color: bool = False) -> U8:
    """Quantise a display image in [0, 1] to 8 bits with Gaussian read noise (per channel if colour)."""
    channels = 3 if color else 1
    shape = (*display.shape, channels)
    noisy = 255.0 * display[..., None] + rng.normal(0.0, noise_grey, size=shape)
    image = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    return image if color else image[..., 0]


def _check_size(width: int, height: int, supersample: int) -> None:
    if width <= 0 or height <= 0 or supersample <= 0:
        raise SimError(f"image size and supersampling must be positive, got {width}x{height} x{supersample}")
