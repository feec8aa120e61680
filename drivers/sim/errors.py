"""Errors raised by the simulated rig."""

from drivers.errors import DriverError


class SimError(DriverError):
    """Bad simulator input (scene kind, sizes, poses) or a scene where the rig cannot be placed."""
