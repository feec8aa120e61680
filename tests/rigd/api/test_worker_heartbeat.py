"""A calibration stage that reports nothing while it runs (a photometric method's solve, the assessment) still
moves its job's bar, with the time it has run said, and never past its band."""

from __future__ import annotations

import io
import json
import math

import pytest

from rigd.api.worker import BANDS, CREEP_S, HEARTBEAT_S, Reporter
from rigd.calibration.progress import Stage


def lines(out: io.StringIO) -> list[dict]:
    return [json.loads(line) for line in out.getvalue().splitlines()]


def test_a_silent_optimisation_moves_its_bar_with_its_time():
    out = io.StringIO()
    reporter = Reporter(out, BANDS)
    reporter.progress(Stage.OPTIMISING, 0, 1)
    reporter.beat()  # it has just said where it is: nothing more
    assert [m["stage"] for m in lines(out) if m["type"] == "progress"] == ["optimising"]
    reporter.stage_since -= 30.0  # 30 s into the stage, silent for longer than a heartbeat
    reporter.sent_at -= 2 * HEARTBEAT_S
    reporter.beat()
    beat = lines(out)[-1]
    low, high = BANDS[Stage.OPTIMISING]
    assert beat["type"] == "progress" and beat["stage"] == "optimising, 30 s"
    assert beat["fraction"] == pytest.approx(low + (high - low) * (1.0 - math.exp(-30.0 / CREEP_S)), abs=1e-3)
    reporter.stage_since -= 1e6  # however long it runs, the bar stays inside its band
    reporter.sent_at -= 2 * HEARTBEAT_S
    reporter.beat()
    assert beat["fraction"] < lines(out)[-1]["fraction"] <= high
    reporter.ended()
    reporter.sent_at -= 2 * HEARTBEAT_S
    count = len(lines(out))
    reporter.beat()  # after the result: silent
    assert len(lines(out)) == count
