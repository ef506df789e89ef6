"""An injected kill of the JAX trainer, for the tests of runs killed and resumed.

The ``kill_at`` fixture lives in ``tests/rl_baselines/conftest.py``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest


class Killed(Exception):
    """What the injected kill raises."""


def install_kill(monkeypatch: pytest.MonkeyPatch) -> Callable[[int], None]:
    """``kill_at(n)``: the n-th compiled training call from now raises :class:`Killed`."""
    from rl_baselines.jax.trainer import JaxTrainer

    calls: dict[str, Any] = {"left": None}
    run = JaxTrainer.run

    def killing(self: JaxTrainer, k: int) -> Any:
        if calls["left"] is not None:
            calls["left"] -= 1
            if calls["left"] == 0:
                calls["left"] = None
                raise Killed
        return run(self, k)

    monkeypatch.setattr(JaxTrainer, "run", killing)
    return lambda n: calls.__setitem__("left", n)
