"""Test doubles for the Ladybug5 tests: a pyusb backend (usb.backend.IBackend) serving fake devices."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import usb.backend
import usb.core

GET_DESCRIPTOR = 0x06
STRING_DESCRIPTOR = 0x03
LANGID_EN_US = 0x0409


@dataclass
class FakeDevice:
    vendor_id: int
    product_id: int
    product: str | None
    serial: str | None
    bus: int = 2
    address: int = 5
    port_numbers: tuple[int, ...] = (1, 3)
    speed: int = 4  # libusb SuperSpeed
    strings_readable: bool = True
    resets: int = 0
    strings: dict[int, str] = field(default_factory=dict)

    def descriptor(self) -> SimpleNamespace:
        self.strings = {i: s for i, s in ((2, self.product), (3, self.serial)) if s is not None}
        return SimpleNamespace(
            bLength=18,
            bDescriptorType=1,
            bcdUSB=0x0300,
            bDeviceClass=0,
            bDeviceSubClass=0,
            bDeviceProtocol=0,
            bMaxPacketSize0=9,
            idVendor=self.vendor_id,
            idProduct=self.product_id,
            bcdDevice=0x0100,
            iManufacturer=0,
            iProduct=2 if self.product else 0,
            iSerialNumber=3 if self.serial else 0,
            bNumConfigurations=1,
            address=self.address,
            bus=self.bus,
            port_number=self.port_numbers[-1],
            port_numbers=self.port_numbers,
            speed=self.speed,
        )


class FakeUsbBackend(usb.backend.IBackend):
    """Answers enumeration, string-descriptor control transfers and resets like libusb would."""

    def __init__(self, devices: list[FakeDevice]) -> None:
        self.devices = devices

    def enumerate_devices(self):
        yield from self.devices

    def get_device_descriptor(self, dev: FakeDevice):
        return dev.descriptor()

    def get_parent(self, dev):
        return None

    def open_device(self, dev: FakeDevice):
        return dev

    def close_device(self, dev_handle) -> None:
        pass

    def reset_device(self, dev_handle: FakeDevice) -> None:
        dev_handle.resets += 1

    def ctrl_transfer(self, dev_handle: FakeDevice, bmRequestType, bRequest, wValue, wIndex, data, timeout):
        if bRequest != GET_DESCRIPTOR or wValue >> 8 != STRING_DESCRIPTOR:
            raise usb.core.USBError("request not supported by the fake", errno=32)
        if not dev_handle.strings_readable:
            raise usb.core.USBError("Access denied (insufficient permissions)", errno=13)
        index = wValue & 0xFF
        if index == 0:
            payload = LANGID_EN_US.to_bytes(2, "little")
        else:
            payload = dev_handle.strings[index].encode("utf-16-le")
        desc = bytes([2 + len(payload), STRING_DESCRIPTOR]) + payload
        n = min(len(desc), len(data))
        data[:n] = type(data)("B", desc[:n])
        return n


def ladybug(serial: str = "17092345", **kwargs) -> FakeDevice:
    return FakeDevice(0x1E10, 0x3300, "Ladybug5", serial, **kwargs)
