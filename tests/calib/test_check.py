"""calib.check: the drift verdict per axis, and a search from a drifted and from the true pose."""

import dataclasses

import numpy as np
import pytest

from calib.check import DriftOptions, DriftStatus, check_drift, drift_verdict
from calib.geometry import Transform
from calib.gmm import Evaluator, GmmOptions
from calib.pipeline import CalibParams
from tests.calib.synthetic import TRUTH, make_pair

PARAMS = dataclasses.replace(CalibParams(), gmm=dataclasses.replace(GmmOptions(), evaluator=Evaluator.FIELD),
                             min_boundary_points=0)


@pytest.fixture(scope="module")
def pairs():
    return [make_pair(1), make_pair(2)]


def test_drift_verdict_rules():
    opts = DriftOptions()
    small = np.array([0.05] * 3 + [0.3] * 3)
    assert drift_verdict(np.zeros(6), small / 10, opts)[0] is DriftStatus.OK
    status, axes, reasons = drift_verdict(np.array([0, 0.5, 0, 0, 0, 0]), small / 10, opts)
    assert status is DriftStatus.DRIFTED and axes == ("pitch",) and "pitch moved +0.5" in reasons[0]
    # beyond the threshold but within 3 sigma: not evidence of drift, and not known to be fine either
    status, axes, _ = drift_verdict(np.array([0, 0, 0, 0, 0, 2.5]), np.array([0.01] * 3 + [1.0] * 3), opts)
    assert status is DriftStatus.UNKNOWN and axes == ("x", "y", "z")
    assert drift_verdict(np.zeros(6), np.array([0.01] * 3 + [1.0] * 3),
                         DriftOptions(threshold_trans_cm=5.0))[0] is DriftStatus.OK


def test_a_diagonal_drift_counts_by_its_length():
    opts = DriftOptions()
    diagonal = np.array([0, 0, 0, 1.73, -1.73, 1.73])  # 3 cm, no axis over the 2 cm threshold
    sigma = np.array([0.01] * 3 + [0.2] * 3)
    status, axes, reasons = drift_verdict(diagonal, sigma, opts)
    assert status is DriftStatus.DRIFTED and axes == ("x", "y", "z") and "translation moved 3" in reasons[0]
    # the same length, but the pairs know it only to 2 cm along that direction: not evidence
    loose = np.diag(sigma**2)
    d = diagonal[3:] / np.linalg.norm(diagonal[3:])
    loose[3:, 3:] += 4.0 * np.outer(d, d)
    assert drift_verdict(diagonal, sigma, opts, loose)[0] is DriftStatus.UNKNOWN
    assert drift_verdict(diagonal * 0.6, sigma, opts)[0] is not DriftStatus.DRIFTED  # 1.8 cm: under it


def test_check_finds_injected_drift_and_passes_the_truth(pairs):
    opts = DriftOptions(threshold_rot_deg=0.3, threshold_trans_cm=3.0)
    at_truth = check_drift(pairs, TRUTH, PARAMS, opts)
    assert at_truth.status is DriftStatus.OK, at_truth.reasons
    assert np.all(np.abs(at_truth.change) < [0.05] * 3 + [0.5] * 3)
    moved = Transform.from_rpy_xyz(TRUTH.rpy_deg + [0.0, 1.0, 0.0], TRUTH.translation_m + [0.0, 0.0, 0.05])
    drifted = check_drift(pairs, moved, PARAMS, opts)
    assert drifted.status is DriftStatus.DRIFTED and "z" in drifted.axes
    # the search lands back near the truth: the change is the injected error, reversed
    assert np.linalg.norm(drifted.found.translation_m - TRUTH.translation_m) < 0.01
