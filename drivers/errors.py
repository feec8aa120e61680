"""Errors raised by the sensor adapters."""


class DriverError(Exception):
    """Base of every error raised by :mod:`drivers`."""
