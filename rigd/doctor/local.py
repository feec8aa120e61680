"""Checks of this machine that touch no network: versions, the rig file, the data directory, the Ladybug5."""

from __future__ import annotations

import importlib
import os
import platform
import shutil
from pathlib import Path

from drivers.errors import DriverError
from drivers.ladybug5.errors import HeadCalibrationError
from drivers.ladybug5.head import HeadSource
from drivers.ladybug5.head_file import load_head
from drivers.ladybug5.sdk import LadybugLibrary, SdkLayout, read_camera_head, sdk_status
from drivers.ladybug5.usb import UsbMatch, find_cameras, health_warnings, read_usbfs_memory_mb
from rigd.capture.config import CONFIG_ENV, RigSettings, find_config, load_settings
from rigd.capture.specs import CameraKind, parse_camera
from rigd.doctor.records import Check, Status
from rigd.errors import RigdError
from rigd.version import software_version

# Display name -> module: the libraries rigd cannot run without (pyproject.toml dependencies).
KEY_LIBRARIES = {
    "numpy": "numpy", "scipy": "scipy", "opencv": "cv2", "pypcd4": "pypcd4", "dpkt": "dpkt", "pyusb": "usb",
    "fastapi": "fastapi", "uvicorn": "uvicorn", "pydantic-settings": "pydantic_settings", "pyyaml": "yaml",
}
GIB = 1 << 30
FAIL_BELOW_BYTES = 1 * GIB  # a 12-pair 2048 x 1024 dataset with its calibration outputs is about 0.1 GB
WARN_BELOW_BYTES = 5 * GIB
INSTALL_FIX = "reinstall rigd with its dependencies: pip install -e . (from the repository) or pip install rigd"
HEAD_CHECK_STEP_PX = 64  # a coarse rectification sample: enough to tell the head is readable, in a moment
EXPORT_FIX = ("export the camera's factory calibration where the SDK works: rigd camera export-head --out "
              "/etc/rigd/ladybug_head.yaml, and set camera.sdk.rig_file to it (docs/ladybug5.md)")


def versions_check() -> Check:
    """rigd, Python and the key libraries; a library that does not import is a failure."""
    found, missing = [], []
    for name, module in KEY_LIBRARIES.items():
        try:
            found.append(f"{name} {getattr(importlib.import_module(module), '__version__', '?')}")
        except ImportError as exc:
            missing.append(f"{name} ({exc})")
    rigd = software_version()
    detail = f"rigd {rigd}, Python {platform.python_version()}, " + ", ".join(found)
    if missing:
        return Check("versions", Status.FAIL, f"{detail}; missing: {', '.join(missing)}", INSTALL_FIX)
    if rigd == "unknown":
        return Check("versions", Status.WARN, f"{detail}; rigd is not installed (no package metadata)", INSTALL_FIX)
    return Check("versions", Status.OK, detail)


def _rig_file_source(explicit: Path | None) -> str:
    if explicit is not None:
        return "--config"
    return f"${CONFIG_ENV}" if os.environ.get(CONFIG_ENV) else "search path ./rig.yaml, /etc/rigd/rig.yaml"


def rig_file_check(explicit: Path | None) -> tuple[Check, RigSettings]:
    """The rig file capture and serve would use, where it was found, and whether it reads; its settings (the
    built-in defaults when there is none or it is broken, so the other checks still run)."""
    fix = "copy deploy/config/rig.yaml to /etc/rigd/rig.yaml and edit it (docs/configuration.md)"
    try:
        path = find_config(explicit)
        settings = load_settings(path)
    except RigdError as exc:
        return Check("rig file", Status.FAIL, str(exc), f"correct or remove it; {fix}"), RigSettings()
    if path is None:
        detail = "none found (--config, $RIGD_CONFIG, ./rig.yaml, /etc/rigd/rig.yaml): built-in defaults in use"
        return Check("rig file", Status.WARN, detail, fix), settings
    detail = (f"{path} (from {_rig_file_source(explicit)}): camera {settings.camera_source}, "
              f"lidar {settings.lidar_source}")
    return Check("rig file", Status.OK, detail), settings


def data_dir_check(data_dir: Path) -> Check:
    """The service's data directory: writable, and free space on its file system."""
    existing = next((p for p in (data_dir, *data_dir.absolute().parents) if p.exists()), Path("/"))
    free = shutil.disk_usage(existing).free
    where = f"{data_dir} ({'exists' if existing == data_dir else 'not created yet'}), {free / GIB:.1f} GiB free"
    if not os.access(existing, os.W_OK):
        return Check("data directory", Status.FAIL, f"{where}; {existing} is not writable",
                     f"give the rigd user write access to {existing} (deploy/tmpfiles.d, deploy/sysusers.d)")
    if free < FAIL_BELOW_BYTES:
        return Check("data directory", Status.FAIL, where, "free space: delete old datasets or job outputs")
    if free < WARN_BELOW_BYTES:
        return Check("data directory", Status.WARN, where, "free space soon: delete old datasets or job outputs")
    return Check("data directory", Status.OK, where)


def _camera_is_sdk(settings: RigSettings) -> bool:
    try:
        return parse_camera(settings.camera_source).kind is CameraKind.SDK
    except RigdError:
        return True  # the rig file check already says the source is unreadable; assume the real camera


def camera_usb_check(settings: RigSettings) -> Check:
    """A Ladybug5 on USB 3 and the usbfs buffer the SDK needs; only required when the camera source is sdk."""
    if not _camera_is_sdk(settings):
        return Check("Ladybug5 USB", Status.OK, f"not used: camera source is {settings.camera_source}")
    try:
        cameras, _ = find_cameras(UsbMatch())
    except DriverError as exc:
        return Check("Ladybug5 USB", Status.FAIL, str(exc), "install libusb-1.0 (apt install libusb-1.0-0)")
    if not cameras:
        return Check("Ladybug5 USB", Status.FAIL, "no Ladybug camera on USB",
                     "check the USB 3 cable and the 12-24 V power on the GPIO connector; rigd camera info")
    found = ", ".join(f"serial {c.serial or '?'} at {c.location} ({c.speed.label})" for c in cameras)
    warnings = health_warnings(cameras, read_usbfs_memory_mb())
    if warnings:
        return Check("Ladybug5 USB", Status.WARN, f"{found}; " + "; ".join(warnings), "see rigd camera info")
    return Check("Ladybug5 USB", Status.OK, found)


def sdk_check(settings: RigSettings, library: str | None) -> Check:
    """FLIR's Ladybug SDK library loads; only required when the camera source is sdk."""
    library = library or settings.sdk.library
    status = sdk_status(library)
    loads = status == f"{library} loads"
    if loads:
        return Check("Ladybug SDK", Status.OK, status)
    if not _camera_is_sdk(settings):
        return Check("Ladybug SDK", Status.OK, f"not needed (camera source {settings.camera_source}): {status}")
    return Check("Ladybug SDK", Status.FAIL, status,
                 "install FLIR's Ladybug SDK and set camera.sdk.library in the rig file (docs/ladybug5.md)")


def head_check(settings: RigSettings, library: str | None) -> Check:
    """Which Ladybug5 head capture uses: the head file of ``camera.sdk.rig_file``, or the camera's factory
    calibration read through the SDK (tried here, briefly opening the camera); never the nominal head unnoticed."""
    if not _camera_is_sdk(settings):
        return Check("Ladybug5 head", Status.OK, f"not used: camera source is {settings.camera_source}")
    if settings.sdk.rig_file is not None:
        return _head_file_check(settings.sdk.rig_file)
    return _camera_head_check(settings, library or settings.sdk.library)


def _head_file_check(path: Path) -> Check:
    try:
        head = load_head(path)
    except DriverError as exc:
        return Check("Ladybug5 head", Status.FAIL, str(exc), f"correct camera.sdk.rig_file, or {EXPORT_FIX}")
    detail = f"{path} (camera.sdk.rig_file): {head.summary()}"
    if head.source is not HeadSource.FACTORY:
        return Check("Ladybug5 head", Status.WARN, f"{detail}; not the camera's factory calibration", EXPORT_FIX)
    poor = head.poor_sensors()
    if poor:
        return Check("Ladybug5 head", Status.WARN, f"{detail}; lens fit poor for {', '.join(poor)}",
                     "use the rectification maps for those sensors (docs/ladybug5.md)")
    return Check("Ladybug5 head", Status.OK, detail)


def _camera_head_check(settings: RigSettings, library: str) -> Check:
    nominal = "capture refuses the nominal head on a real camera unless --nominal-head"
    status = sdk_status(library)
    if status != f"{library} loads" or not settings.sdk.layout.exists():
        why = status if status != f"{library} loads" else f"no SDK layout file {settings.sdk.layout}"
        return Check("Ladybug5 head", Status.WARN, f"the factory head is read through the SDK, which is not set "
                     f"up ({why}): only rigd's nominal head is available; {nominal}", EXPORT_FIX)
    try:
        head = read_camera_head(LadybugLibrary(SdkLayout.load(settings.sdk.layout), library),
                                step_px=HEAD_CHECK_STEP_PX)
    except HeadCalibrationError as exc:
        return Check("Ladybug5 head", Status.FAIL, f"the camera's factory calibration cannot be read: {exc}; "
                     f"{nominal}", "check the camera's calibration with FLIR's LadybugCapPro; " + EXPORT_FIX)
    except DriverError as exc:  # absent, busy (a running capture holds it), unpowered: say so, do not fail on it
        return Check("Ladybug5 head", Status.WARN, f"could not read the factory head from the camera now: {exc}",
                     f"run rigd doctor again when no capture holds the camera, or {EXPORT_FIX}")
    return Check("Ladybug5 head", Status.OK, f"read from the camera now (capture reads it at start): "
                                             f"{head.summary()}")
