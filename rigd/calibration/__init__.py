"""Calibrating a dataset: one request (request.py), one job (job.py) that loads the pairs, solves with calib and
writes the extrinsics, overlays and PLYs."""

from rigd.calibration.job import CalibrationOutcome, run_calibration
from rigd.calibration.request import CalibrationRequest, Options, Start, TransformIn

__all__ = ["CalibrationOutcome", "CalibrationRequest", "Options", "Start", "TransformIn", "run_calibration"]
