"""Errors of the Ladybug5 adapter; each names the thing that failed and what to do about it."""

from __future__ import annotations

from drivers.errors import DriverError


class Ladybug5Error(DriverError):
    """Base of every Ladybug5 adapter error."""


class LibraryMissingError(Ladybug5Error):
    """FLIR's Ladybug SDK library (libladybug) could not be loaded."""


class UsbBackendError(Ladybug5Error):
    """pyusb has no usable backend (libusb-1.0 missing) or a USB operation failed."""


class CameraNotFoundError(Ladybug5Error):
    """No Ladybug camera matches the configured vendor id, product ids/strings and serial."""


class InterfaceSpeedError(Ladybug5Error):
    """The camera is connected below USB 3 SuperSpeed, which cannot carry its frame rate."""


class MissingPowerError(Ladybug5Error):
    """The Ladybug5+ reports bad voltage: it needs 12-24 V on its GPIO connector."""


class SdkError(Ladybug5Error):
    """A Ladybug SDK call returned an error code."""

    def __init__(self, function: str, code: int, text: str) -> None:
        super().__init__(f"{function} failed with Ladybug error {code} ({text})")
        self.function = function
        self.code = code
        self.text = text


class CorruptFrameError(Ladybug5Error):
    """One frame could not be decoded (bad JPEG, truncated block); sources skip and count these."""


class StreamFormatError(Ladybug5Error):
    """A .pgr stream file or a replay directory does not have the expected layout."""


class RigFileError(Ladybug5Error):
    """A rig camera file (per-camera intrinsics and extrinsics) is missing or malformed."""


class UnsupportedFormatError(Ladybug5Error):
    """A data format rigd does not decode (12-bit JPEG, RAW12, half height, ...): named, never read as corrupt."""


class HeadCalibrationError(Ladybug5Error):
    """The head's calibration (per-sensor intrinsics, poses, rectification) cannot be read or is not usable."""


class RendererError(Ladybug5Error):
    """The SDK's panorama renderer cannot be set up (ladybugConfigureOutputImages, ladybugSetOffScreenImageSize):
    it renders with OpenGL and needs a GPU and an OpenGL context on the rig computer."""
