"""A job's result in the OpenAPI schema: JobOut.result names the calibrate, check and capture shapes with typed
fields (rigd.results). A real check job's result is answered through this schema, as stored, in
test_service_check."""

from __future__ import annotations

import json
from typing import get_args

import jsonschema_rs

from calib.drift import DriftStatus
from rigd.api.models import JobOut
from rigd.results import CheckStatus, VersionStatusName
from rigd.store import VersionStatus

RESULT_SHAPES = ["CalibrateJobResult", "CheckReport", "CaptureJobResult"]
# A calibrate and a capture job's results as rigd.api.calibration_result and POST /capture's work make them.
CALIBRATE = {"version": 3, "status": "candidate", "change": {"against": 2, "rotation_deg": 0.41, "translation_cm": 1.5},
             "auto_activate": {"requested": True, "failed_checks": ["1 pairs, at least 6 needed"]}}
FIRST_CALIBRATE = {"version": 1, "status": "active", "change": None, "auto_activate": {"requested": False}}
JOB = {"id": 1, "kind": "capture", "status": "succeeded", "stage": "done", "fraction": 1.0,
       "created_at": "2026-01-01T00:00:00Z", "started_at": None, "finished_at": None, "params": {},
       "result": None, "result_link": None, "error": None, "log_tail": []}
CAPTURE = {"dataset": "field", "pairs_written": 2, "pairs_in_dataset": 2, "seconds_per_pair": [11.6, 9.25]}


def test_status_names_are_the_drift_and_version_statuses():
    assert set(get_args(CheckStatus)) == {s.value for s in DriftStatus}
    assert set(get_args(VersionStatusName)) == {s.value for s in VersionStatus}


def test_the_schema_types_each_kinds_result():
    schema = JobOut.model_json_schema(ref_template="#/components/schemas/{model}", mode="serialization")
    shapes = schema["$defs"]
    result = schema["properties"]["result"]
    assert result["anyOf"] == [*({"$ref": f"#/components/schemas/{name}"} for name in RESULT_SHAPES),
                               {"type": "null"}]
    calibrate, check, capture = (shapes[name] for name in RESULT_SHAPES)
    assert calibrate["properties"]["version"]["type"] == "integer"
    assert set(calibrate["properties"]["status"]["enum"]) == {s.value for s in VersionStatus}
    assert set(calibrate["required"]) == {"version", "status", "change", "auto_activate"}
    assert set(check["properties"]["status"]["enum"]) == {s.value for s in DriftStatus}
    assert check["properties"]["sigma"] == {"$ref": "#/components/schemas/Sigmas"}
    sigma = shapes["Sigmas"]["properties"]["xyz_cm"]["items"]  # None where the uncertainty is not known
    assert sigma == {"anyOf": [{"type": "number"}, {"type": "null"}]}
    assert check["properties"]["groups"]["additionalProperties"] == {"$ref": "#/components/schemas/GroupYaml"}
    assert {"length", "upper", "threshold", "t2", "t2_limit"} == set(shapes["GroupYaml"]["required"])
    assert check["properties"]["checked"] == check["properties"]["found"] == {
        "$ref": "#/components/schemas/TransformYaml"}
    assert {"groups", "places", "confidence"}.isdisjoint(check["required"])  # checks of earlier releases lack them
    assert capture["properties"]["pairs_written"]["type"] == "integer"

    def fits(name, value):
        root = {"$ref": f"#/components/schemas/{name}", "components": {"schemas": shapes}}
        return jsonschema_rs.validator_for(root).is_valid(value)

    assert fits("CalibrateJobResult", CALIBRATE) and fits("CalibrateJobResult", FIRST_CALIBRATE)
    assert fits("CaptureJobResult", CAPTURE) and not fits("CheckReport", CAPTURE)
    assert not fits("CheckReport", CALIBRATE) and not fits("CaptureJobResult", CALIBRATE)
    for result in (CALIBRATE, FIRST_CALIBRATE, CAPTURE):  # answered as given: same keys, order and values
        out = JobOut.model_validate({**JOB, "result": result}).model_dump(mode="json")["result"]
        assert json.dumps(out) == json.dumps(result)
    assert JobOut.model_validate({**JOB, "result": {**CAPTURE, "from_a_later_release": [1]}}).result is not None
