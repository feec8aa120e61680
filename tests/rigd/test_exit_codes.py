"""rigd.cli.exit_codes: every verdict of calib has its exit code, found by the member's name, and no error shares
a verdict's code."""

from calib.assess import Status
from calib.drift import DriftStatus
from rigd.cli import exit_codes
from rigd.cli.exit_codes import Calibrate, Check


def test_every_verdict_has_an_exit_code():
    assert {c.name for c in Calibrate} == {s.name for s in Status}
    assert {c.name for c in Check} == {s.name for s in DriftStatus}


def test_the_documented_codes():
    # docs/reliability.md's table (the README, docs/trust.md and docs/check.md link to it).
    assert {s.value: int(Calibrate[s.name]) for s in Status} == {"trusted": 0, "weak": 3, "failed": 4,
                                                                 "not_assessed": 5}
    assert {s.value: int(Check[s.name]) for s in DriftStatus} == {"ok": 0, "drifted": 1, "unknown": 2}
    errors = {exit_codes.USAGE, exit_codes.ERROR, exit_codes.SOFTWARE, exit_codes.OS_ERROR, exit_codes.CANT_CREATE,
              exit_codes.IO_ERROR}
    assert errors == {64, 65, 70, 71, 73, 74}
    verdicts = {int(c) for c in (*Calibrate, *Check)} | {exit_codes.UNHEALTHY, exit_codes.NOT_STARTED}
    assert not errors & verdicts
