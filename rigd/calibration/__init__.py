"""Calibrating a dataset: load pairs, run calib's Algorithm 1, write extrinsics, overlays and PLYs."""

from rigd.calibration.service import CalibrationOutcome, CalibrationRequest, run_calibration

__all__ = ["CalibrationOutcome", "CalibrationRequest", "run_calibration"]
