"""schemathesis against the served OpenAPI schema: generated requests, valid and invalid, with and without
the token, get no 5xx. The routes' behaviour, so rigd's app in this process (schemathesis's ASGI transport): a
route that raises would fail the test as a 500 would."""

from __future__ import annotations

from typing import Any

import pytest
import schemathesis
from api_helpers import App, perturbed_truth, simulated_dataset, wait_job
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.errors import Unsatisfiable
from schemathesis import GenerationMode

TOKEN = "schemathesis-token-0123456789"
EXAMPLES_PER_OPERATION = 8  # per operation and mode (valid, invalid): ~230 requests, about 3.5 s in this process


@pytest.fixture(scope="module")
def operations(tmp_path_factory):
    """Every operation of the served schema, on one seeded app for both modes."""
    data = tmp_path_factory.mktemp("schema") / "data"
    dataset = simulated_dataset(data, "ds", pairs=1)
    server = App(data, env={"RIGD_TOKEN": TOKEN}).start()
    try:
        seed(server, dataset)
        schema = schemathesis.openapi.from_asgi("/openapi.json", without_lifespan(server.app))
        yield [result.ok() for result in schema.get_all_operations()]
    finally:
        server.stop()


@pytest.mark.parametrize("mode", [GenerationMode.POSITIVE, GenerationMode.NEGATIVE], ids=["valid", "invalid"])
def test_no_server_error_for_generated_requests(operations, mode):
    assert len(operations) >= 11  # every route is in the schema
    failures = [failure for operation in operations for failure in exercise(operation, mode)]
    assert not failures, "\n".join(failures)


def without_lifespan(app: Any) -> Any:
    """``app`` as schemathesis is to call it: it would start a lifespan of its own (a second service on the data
    directory, kept until the process exits); refusing the lifespan scope before any message tells it the app
    has none, and App runs the one lifespan."""
    async def served(scope: dict[str, Any], receive: Any, send: Any) -> None:
        if scope["type"] == "lifespan":
            raise RuntimeError("the test's App runs the lifespan")
        await app(scope, receive, send)

    return served


def seed(server: App, dataset) -> None:
    """A finished calibration (job 1, version 1 with overlays) so that lookups by small ids find something."""
    with server.client(TOKEN) as client:
        job = client.post("/calibrate", json={"dataset": "ds", "init": perturbed_truth(dataset)}).json()
        assert wait_job(client, job["id"])["status"] == "succeeded"


def exercise(operation, mode: GenerationMode) -> list[str]:
    failures: list[str] = []

    @given(case=operation.as_strategy(generation_mode=mode), authorised=st.booleans())
    @settings(max_examples=EXAMPLES_PER_OPERATION, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    def run(case, authorised):
        headers = {"Authorization": f"Bearer {TOKEN}"} if authorised else {}
        response = case.call(headers=headers)
        if response.status_code >= 500:
            failures.append(f"{case.method} {case.formatted_path} {case.query} {case.body!r}: "
                            f"{response.status_code} {response.text[:200]}")

    try:
        run()
    except Unsatisfiable:
        assert mode is GenerationMode.NEGATIVE, operation.label  # nothing in it can be made invalid (GET /status)
    return failures
