"""schemathesis against the served OpenAPI schema: generated requests, valid and invalid, with and without
the token, get no 5xx."""

from __future__ import annotations

import schemathesis
from api_helpers import Server, perturbed_truth, simulated_dataset, wait_job
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.errors import Unsatisfiable
from schemathesis import GenerationMode

TOKEN = "schemathesis-token-0123456789"
EXAMPLES_PER_OPERATION = 8  # per operation and mode (valid, invalid): about 15 s in all


def test_no_server_error_for_generated_requests(tmp_path):
    data = tmp_path / "data"
    dataset = simulated_dataset(data, "ds", pairs=1)
    server = Server(data, env={"RIGD_TOKEN": TOKEN}).start()
    try:
        seed(server, dataset)
        schema = schemathesis.openapi.from_url(f"{server.url}/openapi.json")
        failures: list[str] = []
        operations = [result.ok() for result in schema.get_all_operations()]
        assert len(operations) >= 11  # every route is in the schema
        for operation in operations:
            for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE):
                failures += exercise(operation, mode, server.url)
    finally:
        server.stop()
    assert not failures, "\n".join(failures)


def seed(server: Server, dataset) -> None:
    """A finished calibration (job 1, version 1 with overlays) so that lookups by small ids find something."""
    with server.client(TOKEN) as client:
        job = client.post("/calibrate", json={"dataset": "ds", "init": perturbed_truth(dataset)}).json()
        assert wait_job(client, job["id"])["status"] == "succeeded"


def exercise(operation, mode: GenerationMode, url: str) -> list[str]:
    failures: list[str] = []

    @given(case=operation.as_strategy(generation_mode=mode), authorised=st.booleans())
    @settings(max_examples=EXAMPLES_PER_OPERATION, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    def run(case, authorised):
        headers = {"Authorization": f"Bearer {TOKEN}"} if authorised else {}
        response = case.call(base_url=url, headers=headers, timeout=30)
        if response.status_code >= 500:
            failures.append(f"{case.method} {case.formatted_path} {case.query} {case.body!r}: "
                            f"{response.status_code} {response.text[:200]}")

    try:
        run()
    except Unsatisfiable:
        assert mode is GenerationMode.NEGATIVE, operation.label  # nothing in it can be made invalid (GET /status)
    return failures
