"""rigd.cli.exit_codes: every verdict of calib has its exit code, found by the member's name."""

from calib.assess import Status
from calib.check import DriftStatus
from rigd.cli.exit_codes import ERROR, Calibrate, Check


def test_every_verdict_has_an_exit_code():
    assert {c.name for c in Calibrate} == {s.name for s in Status}
    assert {c.name for c in Check} == {s.name for s in DriftStatus}


def test_the_documented_codes():
    # The README's command table and docs/trust.md, docs/check.md.
    assert {s.value: int(Calibrate[s.name]) for s in Status} == {"trusted": 0, "weak": 3, "failed": 4,
                                                                 "not_assessed": 5}
    assert {s.value: int(Check[s.name]) for s in DriftStatus} == {"ok": 0, "drifted": 1, "unknown": 2}
    assert ERROR == 2
