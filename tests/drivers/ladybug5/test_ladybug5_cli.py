"""``rigd camera info`` with no camera, with a mocked one (fake pyusb backend), and without libusb."""

from __future__ import annotations

import pytest
import usb.backend.libusb0
import usb.backend.libusb1
import usb.backend.openusb
from ladybug5_fakes import FakeDevice, FakeUsbBackend, ladybug

import rigd.cli


@pytest.fixture
def usb_devices(monkeypatch):
    """Make pyusb's own backend discovery return a fake backend holding the listed devices."""
    devices: list[FakeDevice] = []
    backend = FakeUsbBackend(devices)
    monkeypatch.setattr(usb.backend.libusb1, "get_backend", lambda *a, **k: backend)
    monkeypatch.setattr(rigd.cli, "COMMAND_MODULES", ("camera",))  # only the command under test
    return devices


def test_info_without_a_camera_says_so(usb_devices, capsys, tmp_path):
    code = rigd.cli.main(["camera", "info", "--sdk-library", str(tmp_path / "libladybug.so")])
    out = capsys.readouterr().out
    assert code == 1
    assert "no Ladybug camera found on USB (vendor 0x1e10" in out
    assert "Ladybug SDK: not available" in out


def test_info_with_a_mocked_camera(usb_devices, capsys, tmp_path):
    usb_devices.append(ladybug("17092345", bus=3, port_numbers=(2,), speed=3))
    code = rigd.cli.main(["camera", "info", "--sdk-library", str(tmp_path / "x.so")])
    out = capsys.readouterr().out
    assert "serial 17092345 at bus 3 port 2" in out and "USB 2 high speed" in out
    assert "warning: camera 17092345" in out
    assert code == 1  # found, but on a USB 2 link


def test_info_reset(usb_devices, capsys):
    device = ladybug()
    usb_devices.append(device)
    rigd.cli.main(["camera", "info", "--reset"])
    assert device.resets == 1 and "reset camera 17092345" in capsys.readouterr().out


def test_info_without_libusb_still_reports_the_rest(monkeypatch, capsys):
    for module in (usb.backend.libusb1, usb.backend.libusb0, usb.backend.openusb):
        monkeypatch.setattr(module, "get_backend", lambda *a, **k: None)
    monkeypatch.setattr(rigd.cli, "COMMAND_MODULES", ("camera",))
    assert rigd.cli.main(["camera", "info"]) == 1
    out = capsys.readouterr().out
    assert "USB: cannot enumerate USB devices: pyusb found no backend" in out
    assert "usbfs memory limit" in out and "Ladybug SDK:" in out


def test_reset_without_a_camera_is_a_clean_error(usb_devices, capsys):
    assert rigd.cli.main(["camera", "info", "--reset"]) == 2
    assert "rigd: error: reset needs exactly one matching camera, found 0" in capsys.readouterr().err
