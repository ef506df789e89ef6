"""Fixtures of the RL tests."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.rl_baselines.jax_kill import install_kill


@pytest.fixture
def kill_at(monkeypatch: pytest.MonkeyPatch) -> Callable[[int], None]:
    """``kill_at(n)``: the n-th compiled JAX training call from now raises ``Killed``."""
    pytest.importorskip("jax")
    return install_kill(monkeypatch)
