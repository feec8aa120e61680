"""Errors raised by the numerical core."""


class CalibError(Exception):
    """Base of every error raised by :mod:`calib`."""


class FeaturelessError(CalibError):
    """Too few edge pixels or edge points to calibrate."""


class InitialGuessError(CalibError):
    """The initial guess projects no edge point into the image."""


class GeometryError(CalibError):
    """Invalid geometric input (non-rotation matrix, bad shape, ...)."""
