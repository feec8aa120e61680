"""USB presence and health, against a fake pyusb backend (the code under test runs unmodified)."""

from __future__ import annotations

from pathlib import Path

import pytest
import usb.backend.libusb0
import usb.backend.libusb1
import usb.backend.openusb
from ladybug5_fakes import FakeDevice, FakeUsbBackend, ladybug

from drivers.errors import DriverError
from drivers.ladybug5 import usb as lb_usb
from drivers.ladybug5.errors import CameraNotFoundError, InterfaceSpeedError, UsbBackendError


def test_finds_ladybug_by_product_string_and_reports_location_and_speed():
    other_vendor = FakeDevice(0x046D, 0x0825, "Webcam", "X1")
    flea = FakeDevice(0x1E10, 0x2000, "Flea3 FL3-U3", "111")  # same vendor, not a Ladybug
    backend = FakeUsbBackend([other_vendor, flea, ladybug("17092345", bus=4, port_numbers=(2, 1))])
    cameras, unidentified = lb_usb.find_cameras(backend=backend)
    assert [c.serial for c in cameras] == ["17092345"]
    cam = cameras[0]
    assert (cam.bus, cam.port_numbers, cam.speed) == (4, (2, 1), lb_usb.UsbSpeed.SUPER)
    assert cam.location == "bus 4 port 2.1 address 5"
    assert unidentified == []


def test_product_id_from_configuration_matches_without_a_product_string():
    backend = FakeUsbBackend([FakeDevice(0x1E10, 0x3301, "LD5P", "99")])
    assert lb_usb.find_cameras(backend=backend)[0] == []
    match = lb_usb.UsbMatch(product_ids=(0x3301,))
    assert [c.serial for c in lb_usb.find_cameras(match, backend=backend)[0]] == ["99"]


def test_unreadable_strings_are_reported_as_unidentified_not_dropped():
    backend = FakeUsbBackend([ladybug(strings_readable=False)])
    cameras, unidentified = lb_usb.find_cameras(backend=backend)
    assert cameras == []
    assert [(u.product, u.serial) for u in unidentified] == [(None, None)]


def test_serial_selects_one_camera():
    backend = FakeUsbBackend([ladybug("1"), ladybug("2", address=6)])
    with pytest.raises(CameraNotFoundError, match="2 Ladybug cameras"):
        lb_usb.require_camera(backend=backend)
    assert lb_usb.require_camera(lb_usb.UsbMatch(serial="2"), backend=backend).address == 6


def test_high_speed_link_warns_and_is_refused_by_require_camera():
    backend = FakeUsbBackend([ladybug(speed=3)])
    cameras, _ = lb_usb.find_cameras(backend=backend)
    warnings = lb_usb.health_warnings(cameras, lb_usb.read_usbfs_memory_mb(Path("/nonexistent/usbfs_memory_mb")))
    assert any("USB 2 high speed" in w for w in warnings)
    assert any("cannot read" in w for w in warnings)
    with pytest.raises(InterfaceSpeedError, match="SuperSpeed"):
        lb_usb.require_camera(backend=backend)


def test_absent_camera_is_a_named_driver_error():
    with pytest.raises(CameraNotFoundError, match="no Ladybug camera") as info:
        lb_usb.require_camera(backend=FakeUsbBackend([]))
    assert isinstance(info.value, DriverError)


@pytest.mark.parametrize(("value", "warns"), [("16\n", True), ("1000\n", False), ("0\n", False)])
def test_usbfs_memory_check(tmp_path, value, warns):
    path = tmp_path / "usbfs_memory_mb"
    path.write_text(value)
    usbfs = lb_usb.read_usbfs_memory_mb(path)
    assert usbfs == int(value)
    assert any("usbfs_memory_mb" in w for w in lb_usb.health_warnings([], usbfs)) == warns


def test_reset_goes_through_the_backend():
    device = ladybug()
    camera = lb_usb.reset_camera(backend=FakeUsbBackend([device]))
    assert (device.resets, camera.serial) == (1, "17092345")


def test_missing_libusb_is_a_clear_error(monkeypatch):
    for module in (usb.backend.libusb1, usb.backend.libusb0, usb.backend.openusb):
        monkeypatch.setattr(module, "get_backend", lambda *args, **kwargs: None)
    with pytest.raises(UsbBackendError, match="libusb"):
        lb_usb.find_cameras()


def test_unknown_link_speed_is_reported_as_unknown_and_warned():
    cameras, _ = lb_usb.find_cameras(backend=FakeUsbBackend([ladybug(speed=9)]))
    assert cameras[0].speed is lb_usb.UsbSpeed.UNKNOWN
    assert any("unknown" in w for w in lb_usb.health_warnings(cameras, 1000))
