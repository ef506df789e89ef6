"""Fixtures shared by every test package: the one Ray cluster of a test session, and
JAX's persistent compilation cache.

JAX compiles each configuration's functions in every test worker and in every
subprocess a test starts; with ``JAX_COMPILATION_CACHE_DIR`` set (here, before
any test imports JAX, so the subprocesses inherit it) compiled programs are
kept in ``.jax-cache/`` of the checkout and later runs load them. A cache hit
gives the same program, so results do not change.

Tests that use Ray take the ``ray_cluster`` fixture and carry the mark
``pytest.mark.xdist_group("ray")``: with ``--dist loadgroup`` (``make test``)
they all run in one xdist worker, so the session starts a single local
cluster (``ray.init(num_cpus=2, include_dashboard=False)``) and shuts it down
at the end. Without Ray installed they are skipped, unless
``AMAZE_REQUIRE_RAY=1`` (CI) makes that a failure.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault(
    "JAX_COMPILATION_CACHE_DIR", str(Path(__file__).resolve().parents[1] / ".jax-cache")
)
# cache every compilation: the tests compile many small programs
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")


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
