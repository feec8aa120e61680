"""Ladybug5 presence and USB health through pyusb (no FLIR SDK needed).

FLIR publishes no USB protocol for the Ladybug5, so this module only enumerates: it finds devices with
Point Grey/FLIR's vendor id whose product id is configured or whose product string matches, and reports
serial, bus/port, negotiated speed and the kernel's usbfs buffer limit. Streaming needs the SDK (sdk.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from typing import Any

import usb.core
import usb.util

from drivers.ladybug5.errors import CameraNotFoundError, InterfaceSpeedError, UsbBackendError

POINT_GREY_VENDOR_ID = 0x1E10
USBFS_MEMORY_PATH = Path("/sys/module/usbcore/parameters/usbfs_memory_mb")
# The Ladybug SDK's Linux notes ask for usbcore.usbfs_memory_mb=1000 (the kernel default is 16 MB).
REQUIRED_USBFS_MEMORY_MB = 1000


class UsbSpeed(IntEnum):
    """Negotiated link speed, numbered as libusb (and so pyusb's ``Device.speed``) numbers it."""

    UNKNOWN = 0
    LOW = 1
    FULL = 2
    HIGH = 3
    SUPER = 4
    SUPER_PLUS = 5

    @property
    def label(self) -> str:
        return {
            UsbSpeed.UNKNOWN: "unknown",
            UsbSpeed.LOW: "USB 1 low speed (1.5 Mbit/s)",
            UsbSpeed.FULL: "USB 1 full speed (12 Mbit/s)",
            UsbSpeed.HIGH: "USB 2 high speed (480 Mbit/s)",
            UsbSpeed.SUPER: "USB 3 SuperSpeed (5 Gbit/s)",
            UsbSpeed.SUPER_PLUS: "USB 3 SuperSpeed+ (10 Gbit/s)",
        }[self]


@dataclass(frozen=True)
class UsbMatch:
    """Which USB devices count as a Ladybug.

    Point Grey/FLIR use one vendor id for all their cameras and do not publish the Ladybug's product
    ids, so a device matches when its product id is listed in ``product_ids`` or its product string
    contains one of ``product_substrings`` (case-insensitive); ``serial`` narrows to one head.
    """

    vendor_id: int = POINT_GREY_VENDOR_ID
    product_ids: tuple[int, ...] = ()
    product_substrings: tuple[str, ...] = ("ladybug",)
    serial: str | None = None


@dataclass(frozen=True)
class UsbCamera:
    """One matching device as enumerated; strings are ``None`` when they could not be read."""

    vendor_id: int
    product_id: int
    product: str | None
    serial: str | None
    bus: int | None
    address: int | None
    port_numbers: tuple[int, ...]
    speed: UsbSpeed

    @property
    def location(self) -> str:
        port = ".".join(str(p) for p in self.port_numbers) or "?"
        return f"bus {self.bus if self.bus is not None else '?'} port {port} address {self.address}"


def _read_string(device: Any, attribute: str) -> str | None:
    """A string descriptor, or None when the device refuses it (typically no permission on the node)."""
    try:
        value = getattr(device, attribute)
    except (usb.core.USBError, ValueError):
        return None
    return str(value) if value is not None else None


def _describe(device: Any) -> UsbCamera:
    try:
        speed = UsbSpeed(int(device.speed)) if device.speed is not None else UsbSpeed.UNKNOWN
    except ValueError:  # a speed newer than this table (e.g. USB4 numbering)
        speed = UsbSpeed.UNKNOWN
    return UsbCamera(
        vendor_id=int(device.idVendor),
        product_id=int(device.idProduct),
        product=_read_string(device, "product"),
        serial=_read_string(device, "serial_number"),
        bus=device.bus,
        address=device.address,
        port_numbers=tuple(device.port_numbers or ()),
        speed=speed,
    )


def _matches(camera: UsbCamera, match: UsbMatch) -> bool:
    by_id = camera.product_id in match.product_ids
    product = (camera.product or "").lower()
    by_name = any(s.lower() in product for s in match.product_substrings)
    return (by_id or by_name) and (match.serial is None or camera.serial == match.serial)


def _vendor_devices(match: UsbMatch, backend: Any) -> list[Any]:
    try:
        return list(usb.core.find(find_all=True, idVendor=match.vendor_id, backend=backend))
    except usb.core.NoBackendError as exc:
        raise UsbBackendError(
            "cannot enumerate USB devices: pyusb found no backend (install libusb-1.0, "
            "e.g. apt-get install libusb-1.0-0)"
        ) from exc
    except usb.core.USBError as exc:
        raise UsbBackendError(f"USB enumeration failed: {exc}") from exc


def find_cameras(match: UsbMatch = UsbMatch(), backend: Any = None) -> tuple[list[UsbCamera], list[UsbCamera]]:
    """Matching cameras, and same-vendor devices whose strings could not be read (maybe a Ladybug).

    ``backend`` is a pyusb backend (``usb.backend.IBackend``); ``None`` lets pyusb pick libusb.
    """
    described = [_describe(d) for d in _vendor_devices(match, backend)]
    cameras = [c for c in described if _matches(c, match)]
    unidentified = [c for c in described if c not in cameras and c.product is None and match.serial is None]
    return cameras, unidentified


def read_usbfs_memory_mb(path: Path = USBFS_MEMORY_PATH) -> int | None:
    """The kernel's usbfs buffer limit in MB, or None when the parameter file is absent/unreadable."""
    try:
        return int(path.read_text().strip())
    except (OSError, ValueError):
        return None


def health_warnings(cameras: Sequence[UsbCamera], usbfs_memory_mb: int | None) -> list[str]:
    """Human-readable problems: slow links, a small usbfs buffer."""
    warnings = []
    for cam in cameras:
        if cam.speed < UsbSpeed.SUPER:
            warnings.append(
                f"camera {cam.serial or '?'} at {cam.location} runs at {cam.speed.label}; the Ladybug5 "
                "needs USB 3 SuperSpeed (use a USB 3 port and cable)"
            )
    if usbfs_memory_mb is None:
        warnings.append(f"cannot read {USBFS_MEMORY_PATH}; check usbcore.usbfs_memory_mb by hand")
    elif usbfs_memory_mb != 0 and usbfs_memory_mb < REQUIRED_USBFS_MEMORY_MB:
        # 0 means "no limit" to the kernel.
        warnings.append(
            f"usbcore.usbfs_memory_mb is {usbfs_memory_mb}; the Ladybug SDK needs "
            f"{REQUIRED_USBFS_MEMORY_MB} (boot with usbcore.usbfs_memory_mb={REQUIRED_USBFS_MEMORY_MB} or "
            f"write it to {USBFS_MEMORY_PATH})"
        )
    return warnings


def require_camera(match: UsbMatch = UsbMatch(), backend: Any = None) -> UsbCamera:
    """The one camera to use: raises if none matches, several match, or the link is below SuperSpeed."""
    cameras, _ = find_cameras(match, backend)
    if not cameras:
        raise CameraNotFoundError(
            f"no Ladybug camera on USB (vendor 0x{match.vendor_id:04x}, product ids "
            f"{[hex(p) for p in match.product_ids]}, product strings {list(match.product_substrings)}, "
            f"serial {match.serial or 'any'}); check the cable and, for a Ladybug5+, its 12-24 V supply"
        )
    if len(cameras) > 1:
        serials = ", ".join(c.serial or "?" for c in cameras)
        raise CameraNotFoundError(f"{len(cameras)} Ladybug cameras found ({serials}); choose one by serial")
    camera = cameras[0]
    if camera.speed < UsbSpeed.SUPER:
        raise InterfaceSpeedError(
            f"camera {camera.serial or '?'} at {camera.location} negotiated {camera.speed.label}; "
            "the Ladybug5 needs USB 3 SuperSpeed"
        )
    return camera


def reset_camera(match: UsbMatch = UsbMatch(), backend: Any = None) -> UsbCamera:
    """USB-reset the matching camera (re-enumerates it; clears a wedged stream)."""
    devices = [d for d in _vendor_devices(match, backend) if _matches(_describe(d), match)]
    if len(devices) != 1:
        raise CameraNotFoundError(f"reset needs exactly one matching camera, found {len(devices)}")
    camera = _describe(devices[0])
    try:
        devices[0].reset()
    except usb.core.USBError as exc:
        raise UsbBackendError(f"USB reset of camera {camera.serial or '?'} at {camera.location} failed: {exc}") from exc
    finally:
        usb.util.dispose_resources(devices[0])
    return camera
