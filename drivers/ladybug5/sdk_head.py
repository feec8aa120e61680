"""Reading the factory head calibration out of the Ladybug SDK (needs FLIR's SDK; kept thin).

The SDK must hold a configuration: ``ladybugLoadConfig`` with NULL (from the camera head) after initialising a
camera, or with the path of a configuration file (a ``.cal``, or a .pgr stream's embedded configuration
written to a file) on a context with no camera. Then, per FLIR's ladybuggeom.h / ladybugrenderer.h and in the
order every public caller uses: ``ladybugConfigureOutputImages(LADYBUG_ALL_RECTIFIED_IMAGES)``,
``ladybugSetOffScreenImageSize(LADYBUG_ALL_RECTIFIED_IMAGES, cols, rows)`` to set the rectified resolution
(here: the raw size, so focal lengths are in raw pixels), and per sensor ``ladybugGetCameraUnitFocalLength``,
``ladybugGetCameraUnitImageCenter``, ``ladybugGetCameraUnitExtrinsics`` and the rectification sampled with
``ladybugRectifyPixel`` / ``ladybugUnrectifyPixel`` (row, column order; negative or failing: outside). A refused
configuration (it may want OpenGL) is logged and the reading goes on; should a later call fail too, its error
says both.
"""

from __future__ import annotations

import ctypes
import logging
import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import HeadCalibrationError, Ladybug5Error
from drivers.ladybug5.head import HeadCalibration, HeadSource, RectificationMaps, SensorCalibration, sensor_from_sdk
from drivers.ladybug5.pgr import PgrStream
from drivers.ladybug5.raw import NUM_SENSORS
from drivers.ladybug5.sdk_library import LadybugLibrary

DEFAULT_MAP_STEP_PX = 16  # every 16 px: ~19 000 points a sensor of 2448x2048; the head reads in a few s
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


def read_head(lib: LadybugLibrary, context: ctypes.c_void_p, size_px: tuple[int, int], description: str,
              serial: int | None = None, step_px: int = DEFAULT_MAP_STEP_PX) -> HeadCalibration:
    """The factory head of a context whose configuration is loaded; ``size_px`` the sensors' raw (border-cropped)
    (width, height). Errors: :class:`HeadCalibrationError` (or the SDK's own) naming the call."""
    cols, rows = size_px
    if cols <= 0 or rows <= 0 or step_px <= 0:
        raise HeadCalibrationError(f"read_head: bad sensor size {size_px} or map step {step_px}")
    refused = _configure_rectified(lib, context, description)
    try:
        lib.call("ladybugSetOffScreenImageSize", context, lib.layout.output_images["ALL_RECTIFIED_IMAGES"], cols, rows)
        sensors = tuple(_sensor(lib, context, c, size_px, step_px) for c in range(NUM_SENSORS))
    except HeadCalibrationError as exc:
        if refused is None:
            raise
        raise HeadCalibrationError(f"{exc} (after {refused})") from exc
    except Ladybug5Error as exc:
        after = f" (after {refused})" if refused else ""
        raise HeadCalibrationError(f"cannot read the head calibration of {description}: {exc}{after}") from exc
    return HeadCalibration(sensors, HeadSource.FACTORY, description, serial)


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
                          serial: int | None = None, step_px: int = DEFAULT_MAP_STEP_PX) -> HeadCalibration:
    """The head of a configuration file (a camera's ``.cal``), loaded into a context with no camera."""
    context = ctypes.c_void_p()
    lib.call("ladybugCreateContext", ctypes.byref(context))
    try:
        try:
            lib.call("ladybugLoadConfig", context, str(config).encode())
        except Ladybug5Error as exc:
            raise HeadCalibrationError(f"ladybugLoadConfig cannot load {config}: {exc}") from exc
        return read_head(lib, context, size_px, description or f"configuration file {config}", serial, step_px)
    finally:
        lib.call("ladybugDestroyContext", ctypes.byref(context))


def head_from_pgr(lib: LadybugLibrary, stream: PgrStream, size_px: tuple[int, int] | None = None,
                  step_px: int = DEFAULT_MAP_STEP_PX) -> HeadCalibration:
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
        return head_from_config_file(lib, config, size, description, header.serial or None, step_px)
