"""Errors raised by the VLP-16 driver; all derive from :class:`drivers.errors.DriverError`."""

from drivers.errors import DriverError


class Vlp16Error(DriverError):
    """Base of every VLP-16 driver error."""


class CaptureFileError(Vlp16Error):
    """A capture file is missing, is not pcap/pcapng, or uses an unsupported link type."""


class CalibrationFileError(Vlp16Error):
    """A laser calibration file (ROS ``VLP16db.yaml`` style) is missing or malformed."""


class EncodeError(Vlp16Error):
    """Arrays given to the packet encoder have the wrong shape, dtype or values."""


class ReceiverError(Vlp16Error):
    """The UDP receiver could not bind its socket or was used after it was closed."""
