"""Reading the factory head calibration out of the Ladybug SDK (needs FLIR's SDK; kept thin).

The SDK must hold a configuration: ``ladybugLoadConfig`` with NULL (from the camera head) after initialising a
camera, or with the path of a configuration file (a ``.cal``, or a .pgr stream's embedded configuration
written to a file) on a context with no camera. Then, per FLIR's ladybuggeom.h / ladybugrenderer.h and in the
order every public caller uses: ``ladybugConfigureOutputImages(LADYBUG_ALL_RECTIFIED_IMAGES)``,
``ladybugSetOffScreenImageSize(LADYBUG_ALL_RECTIFIED_IMAGES, cols, rows)`` to set the rectified resolution
(here: the raw size, so focal lengths are in raw pixels), and per sensor ``ladybugGetCameraUnitFocalLength``,
``ladybugGetCameraUnitImageCenter``, ``ladybugGetCameraUnitExtrinsics`` and the rectification sampled with
``ladybugRectifyPixel`` / ``ladybugUnrectifyPixel`` (row, column order; negative or failing: outside). A refused
configuration (it may want OpenGL) is logged and the reading goes on. Where the rectified geometry cannot be had (a
headless rig: FLIR renders rectified images with OpenGL, and its software renderer is not for Ladybug3 or newer), the
lens is fitted to ``ladybugGet3dMap`` instead, the raw pixels' points on the stitching sphere, which ladybuggeom.h
computes without a rendering context; should that fail too, the error names every failed call and the way out.
"""

from __future__ import annotations

import ctypes
import logging
import tempfile
from enum import Enum
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import HeadCalibrationError, Ladybug5Error
from drivers.ladybug5.head import (
    HeadCalibration,
    HeadSource,
    RectificationMaps,
    SensorCalibration,
    sensor_from_rays,
    sensor_from_sdk,
)
from drivers.ladybug5.pgr import PgrStream
from drivers.ladybug5.raw import NUM_SENSORS
from drivers.ladybug5.sdk_library import LadybugLibrary

DEFAULT_MAP_STEP_PX = 16  # every 16 px: ~19 000 points a sensor of 2448x2048; the head reads in a few s
MAP_SPHERE_M = 1000.0  # the 3D map's sphere: a sensor 6-8 cm off the head centre sees it within 0.1 mrad of its ray
log = logging.getLogger(__name__)


def grid(size: int, step: int) -> NDArray[np.float64]:
    """Sample positions 0, step, 2 step, ... and the last pixel ``size - 1``."""
    return np.unique(np.append(np.arange(0, size, step, dtype=np.float64), size - 1.0))


def _sample(lib: LadybugLibrary, context: ctypes.c_void_p, camera: int, function: str,
            gx: NDArray[np.float64], gy: NDArray[np.float64]) -> NDArray[np.float64]:
    """(Hg, Wg, 2) the SDK's image of each grid point (x, y); NaN where it has none. An error if it has none at
    all, naming the SDK's last error."""
    call, ok = lib.function(function), lib.ok
    row, col = ctypes.c_double(), ctypes.c_double()
    out = np.full((len(gy), len(gx), 2), np.nan)
    last_error = ok
    for i, y in enumerate(gy):
        for j, x in enumerate(gx):
            code = call(context, camera, float(y), float(x), ctypes.byref(row), ctypes.byref(col))
            if code != ok:
                last_error = code
            elif row.value >= 0.0 and col.value >= 0.0:
                out[i, j] = col.value, row.value
    if not np.isfinite(out).any():
        why = lib.error_text(last_error) if last_error != ok else "every point maps outside the image"
        raise HeadCalibrationError(f"{function} for camera {camera}: no pixel maps ({why})")
    return out


def _sensor(lib: LadybugLibrary, context: ctypes.c_void_p, camera: int, size_px: tuple[int, int],
            step_px: int) -> SensorCalibration:
    focal, cx, cy = ctypes.c_double(), ctypes.c_double(), ctypes.c_double()
    extrinsics = (ctypes.c_double * 6)()
    lib.call("ladybugGetCameraUnitFocalLength", context, camera, ctypes.byref(focal))
    lib.call("ladybugGetCameraUnitImageCenter", context, camera, ctypes.byref(cx), ctypes.byref(cy))
    lib.call("ladybugGetCameraUnitExtrinsics", context, camera, extrinsics)
    gx, gy = grid(size_px[0], step_px), grid(size_px[1], step_px)
    maps = RectificationMaps(gx, gy, _sample(lib, context, camera, "ladybugRectifyPixel", gx, gy),
                             _sample(lib, context, camera, "ladybugUnrectifyPixel", gx, gy))
    return sensor_from_sdk(f"cam{camera}", size_px, focal.value, (cx.value, cy.value), tuple(extrinsics), maps)


class LensSource(Enum):
    """Where the head's lens comes from: the rectified pinhole and its rectification (needs the rectified images
    configured, which may want OpenGL), the 3D map of raw pixels (no rendering context), or the first that works."""

    AUTO = "auto"
    RECTIFIED = "rectified"
    MAP = "3d-map"


def read_head(lib: LadybugLibrary, context: ctypes.c_void_p, size_px: tuple[int, int], description: str,
              serial: int | None = None, step_px: int = DEFAULT_MAP_STEP_PX,
              lens: LensSource = LensSource.AUTO) -> HeadCalibration:
    """The factory head of a context whose configuration is loaded; ``size_px`` the sensors' raw (border-cropped)
    (width, height). With ``LensSource.AUTO`` a rectified geometry the SDK will not give (a headless rig) is read from
    the 3D map instead. Errors: :class:`HeadCalibrationError` naming every call that failed and the way out."""
    cols, rows = size_px
    if cols <= 0 or rows <= 0 or step_px <= 0:
        raise HeadCalibrationError(f"read_head: bad sensor size {size_px} or map step {step_px}")
    rectified_error = ""
    if lens is not LensSource.MAP:
        try:
            return HeadCalibration(_rectified_sensors(lib, context, size_px, description, step_px),
                                   HeadSource.FACTORY, description, serial)
        except HeadCalibrationError as exc:
            if lens is LensSource.RECTIFIED:
                raise
            rectified_error = str(exc)
            log.warning("%s; reading the lens from ladybugGet3dMap, which needs no rendering context", exc)
    try:
        sensors = map_sensors(lib, context, size_px, step_px)
    except Ladybug5Error as exc:
        raise HeadCalibrationError(_headless_message(description, rectified_error, exc)) from exc
    why = f" ({rectified_error})" if rectified_error else ""
    return HeadCalibration(sensors, HeadSource.FACTORY, f"{description}; lens from ladybugGet3dMap, no rectified "
                           f"pinhole{why}", serial)


def _headless_message(description: str, rectified_error: str, map_error: Ladybug5Error) -> str:
    first = f"the rectified geometry failed ({rectified_error}) and " if rectified_error else ""
    return (f"cannot read the head calibration of {description}: {first}ladybugGet3dMap failed ({map_error}). FLIR's "
            "rectified images are rendered with OpenGL and its software renderer is not for Ladybug3 or newer "
            "cameras (ladybugrenderer.h): run `rigd camera export-head` once where OpenGL works (a computer with a "
            "GPU, or under a virtual X server: xvfb-run rigd camera export-head ...) with the camera, its .pgr or its "
            ".cal, and give the head file to this rig (camera.sdk.rig_file)")


def _rectified_sensors(lib: LadybugLibrary, context: ctypes.c_void_p, size_px: tuple[int, int], description: str,
                       step_px: int) -> tuple[SensorCalibration, ...]:
    refused = _configure_rectified(lib, context, description)
    try:
        lib.call("ladybugSetOffScreenImageSize", context, lib.layout.output_images["ALL_RECTIFIED_IMAGES"], *size_px)
        return tuple(_sensor(lib, context, c, size_px, step_px) for c in range(NUM_SENSORS))
    except HeadCalibrationError as exc:
        if refused is None:
            raise
        raise HeadCalibrationError(f"{exc} (after {refused})") from exc
    except Ladybug5Error as exc:
        after = f" (after {refused})" if refused else ""
        raise HeadCalibrationError(f"cannot read the rectified geometry of {description}: {exc}{after}") from exc


def map_sensors(lib: LadybugLibrary, context: ctypes.c_void_p, size_px: tuple[int, int],
                step_px: int) -> tuple[SensorCalibration, ...]:
    """Each sensor's lens fitted to ``ladybugGet3dMap``: the point on the stitching sphere of every ``step_px``-th
    raw pixel (pixel centres), with the sphere far away (MAP_SPHERE_M) and the mesh unrotated, so a point's direction
    from the sensor is its pixel's ray; the SDK's sphere size and rotation are put back afterwards."""
    radius, rotation = ctypes.c_double(), (ctypes.c_double(), ctypes.c_double(), ctypes.c_double())
    lib.call("ladybugGet3dMapSphereSize", context, ctypes.byref(radius))
    lib.call("ladybugGet3dMapRotation", context, *(ctypes.byref(r) for r in rotation))
    try:
        lib.call("ladybugSet3dMapSphereSize", context, MAP_SPHERE_M)
        lib.call("ladybugSet3dMapRotation", context, 0.0, 0.0, 0.0)
        return tuple(_map_sensor(lib, context, c, size_px, step_px) for c in range(NUM_SENSORS))
    finally:
        lib.call("ladybugSet3dMapSphereSize", context, radius.value)
        lib.call("ladybugSet3dMapRotation", context, *(r.value for r in rotation))


def _map_sensor(lib: LadybugLibrary, context: ctypes.c_void_p, camera: int, size_px: tuple[int, int],
                step_px: int) -> SensorCalibration:
    extrinsics = (ctypes.c_double * 6)()
    lib.call("ladybugGetCameraUnitExtrinsics", context, camera, extrinsics)
    cols, rows = -(-size_px[0] // step_px), -(-size_px[1] // step_px)  # the raw image sampled at cols x rows
    pointer = ctypes.c_void_p()
    lib.call("ladybugGet3dMap", context, camera, cols, rows, cols, rows, True, ctypes.byref(pointer))
    points = lib.read_3d_map(pointer.value or 0, f"camera {camera}").reshape(-1, 3)
    if len(points) != cols * rows:
        raise HeadCalibrationError(f"camera {camera}: ladybugGet3dMap gave {len(points)} points for a {cols}x{rows} "
                                   "grid")
    # pixel centre j of the sampled image is raw column (j + 0.5) * width / cols - 0.5
    u = (np.arange(cols) + 0.5) * size_px[0] / cols - 0.5
    v = (np.arange(rows) + 0.5) * size_px[1] / rows - 0.5
    raw_xy = np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)
    return sensor_from_rays(f"cam{camera}", size_px, tuple(extrinsics), raw_xy, points)


def _configure_rectified(lib: LadybugLibrary, context: ctypes.c_void_p, description: str) -> str | None:
    """``ladybugConfigureOutputImages(LADYBUG_ALL_RECTIFIED_IMAGES)``, which public callers make before setting the
    rectified size and reading the geometry; None when done, else the refusal (logged), for a later error to name.
    Not fatal: the SDK may want OpenGL for it and still give the geometry without."""
    try:
        lib.call("ladybugConfigureOutputImages", context, lib.layout.output_images["ALL_RECTIFIED_IMAGES"])
    except Ladybug5Error as exc:
        log.warning("%s: the rectified images are not configured (%s); reading the geometry anyway", description, exc)
        return str(exc)
    return None


def head_from_config_file(lib: LadybugLibrary, config: Path, size_px: tuple[int, int], description: str = "",
                          serial: int | None = None, step_px: int = DEFAULT_MAP_STEP_PX,
                          lens: LensSource = LensSource.AUTO) -> HeadCalibration:
    """The head of a configuration file (a camera's ``.cal``), loaded into a context with no camera."""
    context = ctypes.c_void_p()
    lib.call("ladybugCreateContext", ctypes.byref(context))
    try:
        try:
            lib.call("ladybugLoadConfig", context, str(config).encode())
        except Ladybug5Error as exc:
            raise HeadCalibrationError(f"ladybugLoadConfig cannot load {config}: {exc}") from exc
        return read_head(lib, context, size_px, description or f"configuration file {config}", serial, step_px, lens)
    finally:
        lib.call("ladybugDestroyContext", ctypes.byref(context))


def head_from_pgr(lib: LadybugLibrary, stream: PgrStream, size_px: tuple[int, int] | None = None,
                  step_px: int = DEFAULT_MAP_STEP_PX, lens: LensSource = LensSource.AUTO) -> HeadCalibration:
    """The head of a .pgr stream's embedded configuration (the bytes after its head info). ``size_px``: the
    sensors' raw size (default: the head info's resolution)."""
    header = stream.header
    if not header.calibration:
        raise HeadCalibrationError(f"{stream.path}: the stream holds no configuration (size field "
                                   f"{stream.layout.head_config_size:#x} of the head info is 0 or past the end)")
    size = size_px or header.resolution
    if size is None:
        raise HeadCalibrationError(f"{stream.path}: unknown resolution code {header.resolution_code}; give the "
                                   "sensor size")
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / f"ladybug{header.serial}.cal"
        config.write_bytes(header.calibration)
        description = f"{stream.path} (configuration of camera {header.serial} embedded in the stream)"
        return head_from_config_file(lib, config, size, description, header.serial or None, step_px, lens)
