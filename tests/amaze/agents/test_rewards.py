"""The batched reward functions give the scalar ones' floats, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from amaze.agents.rewards import (
    RewardScheme,
    normalized_reward,
    normalized_rewards,
    pretty_reward,
    pretty_rewards,
    round_like_python,
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
    paper = normalized_rewards(success, steps, collisions, backsteps, length, dt)
    for k in range(n):
        scheme = RewardScheme(int(length[k]), dt, deadline_factor)
        assert pretty[k] == pretty_reward(float(cumulative[k]), scheme)
        expected = normalized_reward(
            bool(success[k]), int(steps[k]), int(collisions[k]), int(backsteps[k]),
            int(length[k]), dt,
        )  # fmt: skip
        assert paper[k] == expected


def test_batched_rewards_check_their_scheme() -> None:
    with pytest.raises(OptionError, match="dt"):
        pretty_rewards(np.zeros(2), np.full(2, 10), 0.0, 4.0)


def test_rounding_in_array_code_equals_pythons_round() -> None:
    """Pretty rewards are rounded to 3 decimals as ``round`` does, near half-way points too."""
    rng = np.random.default_rng(1)
    ties = (np.arange(-3000, 3000) + 0.5) / 1000  # the floats nearest the half-way points
    near = np.concatenate([ties, np.nextafter(ties, np.inf), np.nextafter(ties, -np.inf)])
    for _ in range(3):
        near = np.concatenate([near, np.nextafter(near, np.inf), np.nextafter(near, -np.inf)])
    values = np.concatenate([
        near,
        rng.uniform(-1.5, 1.5, 20000),
        rng.normal(0, 1e6, 2000),
        [0.0, -0.0, -0.0004, 0.0004, 1e300, -1e300, 2.0**60 + 0.5, np.inf, -np.inf, np.nan],
        [5e-324, -5e-324, 1e-310],
    ])  # fmt: skip
    rounded = round_like_python(values, 3)
    expected = np.array([round(float(v), 3) for v in values])
    np.testing.assert_array_equal(rounded, expected)
    assert np.array_equal(np.signbit(rounded), np.signbit(expected))
    assert not np.array_equal(np.round(values, 3), expected)  # what numpy alone gets wrong
    for decimals in (0, 1, 2, 5):
        expected = np.array([round(float(v), decimals) for v in values])
        np.testing.assert_array_equal(round_like_python(values, decimals), expected)
