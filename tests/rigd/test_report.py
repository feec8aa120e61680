"""The calibration report's typed records (rigd/report.py): the values they name, the stored quality they make,
and the API schema they give."""

from __future__ import annotations

from typing import get_args

from pydantic import TypeAdapter

from calib.assess import Status
from rigd.api.models import VersionOut
from rigd.report import StatusName, StoredQuality, VersionQuality, stored_quality, uncertainty_of, verdict_of

VERDICT = {"status": "weak", "weak_axes": ["z"], "reasons": ["z is not known within 2 cm"], "next_steps": []}
UNCERTAINTY = {"rpy_deg": [0.1, 0.1, 0.1], "xyz_cm": [1.0, 1.0, 3.0], "covariance": None, "weakest": "z"}
QUALITY = {"final_cost": -1.5, "converged": True, "levels": [], "pairs": [{"edge_pixels": 10, "edge_points": 5}],
           "wall_time_s": 2.0}
REPORT = {"T_camera_lidar": {}, "quality": QUALITY, "change_from_initial": {"rotation_deg": 1.0, "translation_cm": 2.0},
          "dataset": "ds", "error_vs_ground_truth": {"rotation_deg": 0.1}, "uncertainty": UNCERTAINTY,
          "verdict": VERDICT, "method": {"name": "gmm", "why": "asked for"},
          "start": {"source": "given", "choice": "the transform given", "why": "asked for"},
          "tolerance": {"rotation_deg": 0.2, "translation_cm": 2.0}}


def test_status_names_are_calib_statuses():
    assert set(get_args(StatusName)) == {s.value for s in Status}


def test_stored_quality_is_the_reports_with_what_the_service_shows():
    quality = stored_quality(REPORT, 6)  # type: ignore[arg-type]
    assert list(quality) == [*QUALITY, "pairs_used", "error_vs_ground_truth", "uncertainty", "verdict", "method",
                             "start"]  # the method and the start, each with why: the page shows them
    assert verdict_of(quality) == VERDICT and uncertainty_of(quality) == UNCERTAINTY
    assert verdict_of({}) is None and uncertainty_of({}) is None  # a version stored by hand


def test_a_stored_version_keeps_keys_the_records_do_not_name():
    adapter = TypeAdapter(VersionQuality)
    stored = {**QUALITY, "pairs_used": 6, "verdict": {**VERDICT, "from_a_later_release": 1}, "other": [1]}
    assert adapter.dump_python(adapter.validate_python(stored), mode="json") == stored
    assert adapter.validate_python({}) == {}


def test_the_version_schema_names_verdict_uncertainty_and_quality():
    schema = VersionOut.model_json_schema(mode="serialization")
    defs = schema["$defs"]

    def target(prop: str) -> dict:
        options = schema["properties"][prop].get("anyOf", [schema["properties"][prop]])
        return defs[next(o["$ref"] for o in options if "$ref" in o).rsplit("/", 1)[1]]

    verdict = target("verdict")
    assert set(verdict["properties"]["status"]["enum"]) == {s.value for s in Status}
    assert {"weak_axes", "reasons", "next_steps"} <= set(verdict["properties"])
    assert {"rpy_deg", "xyz_cm", "covariance", "weakest", "laplace"} <= set(target("uncertainty")["properties"])
    quality = defs[StoredQuality.__name__]["properties"]
    assert {"final_cost", "levels", "pairs_used", "error_vs_ground_truth", "verdict"} <= set(quality)
