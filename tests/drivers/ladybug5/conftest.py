"""Fixtures of the Ladybug5 SDK tests: the fake libladybug (fake_sdk/), built once per module, and a private copy
of it per test (its globals start fresh)."""

from __future__ import annotations

import pytest
from fake_ladybug_sdk import Fake, build, private_copy


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(library path, probed layout) of the fake with the real enum values; one build per module."""
    return build(tmp_path_factory.mktemp("fake_sdk"))


@pytest.fixture
def fake(built, tmp_path) -> Fake:
    return private_copy(built, tmp_path)
