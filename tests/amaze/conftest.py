"""Shared fixtures: the golden data produced by running amaze-benchmarker 1.0."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

DATA = Path(__file__).parent / "data"


def load_reference() -> dict[str, Any]:
    """The reference fixtures (see tests/amaze/data/README.md)."""
    with (DATA / "reference_fixtures.json").open() as stream:
        return json.load(stream)


@pytest.fixture(scope="session")
def reference() -> dict[str, Any]:
    return load_reference()
