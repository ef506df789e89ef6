"""Fixtures shared by every test package: the one Ray cluster of a test session.

Tests that use Ray take the ``ray_cluster`` fixture and carry the mark
``pytest.mark.xdist_group("ray")``: with ``--dist loadgroup`` (``make test``)
they all run in one xdist worker, so the session starts a single local
cluster (``ray.init(num_cpus=2, include_dashboard=False)``) and shuts it down
at the end. Without Ray installed they are skipped, unless
``AMAZE_REQUIRE_RAY=1`` (CI) makes that a failure.
"""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session")
def ray_cluster():
    """The ``ray`` module, connected to the session's local cluster of 2 CPUs."""
    try:
        import ray
    except ImportError:
        if os.environ.get("AMAZE_REQUIRE_RAY") == "1":
            pytest.fail("Ray is not installed and AMAZE_REQUIRE_RAY=1")
        pytest.skip("Ray is not installed (pip install '.[ray]')")
    ray.init(num_cpus=2, include_dashboard=False, logging_level="warning")
    try:
        yield ray
    finally:
        ray.shutdown()
