"""The batched reward functions give the scalar ones' floats, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from amaze.agents.rewards import (
    RewardScheme,
    paper_reward,
    paper_rewards,
    pretty_reward,
    pretty_rewards,
)
from amaze.errors import OptionError


@pytest.mark.parametrize(("dt", "deadline_factor"), [(1.0, 4.0), (0.1, 4.0), (0.5, 2.5)])
def test_batched_rewards_equal_the_scalar_ones(dt: float, deadline_factor: float) -> None:
    rng = np.random.default_rng(0)
    n = 2000
    length = rng.integers(2, 400, n)
    steps = rng.integers(0, 4000, n)
    collisions, backsteps = rng.integers(0, 500, n), rng.integers(0, 500, n)
    success = rng.random(n) < 0.5
    cumulative = rng.normal(0, 300, n)
    pretty = pretty_rewards(cumulative, length, dt, deadline_factor)
    paper = paper_rewards(success, steps, collisions, backsteps, length, dt)
    for k in range(n):
        scheme = RewardScheme(int(length[k]), dt, deadline_factor)
        assert pretty[k] == pretty_reward(float(cumulative[k]), scheme)
        expected = paper_reward(
            bool(success[k]), int(steps[k]), int(collisions[k]), int(backsteps[k]),
            int(length[k]), dt,
        )  # fmt: skip
        assert paper[k] == expected


def test_batched_rewards_check_their_scheme() -> None:
    with pytest.raises(OptionError, match="dt"):
        pretty_rewards(np.zeros(2), np.full(2, 10), 0.0, 4.0)
