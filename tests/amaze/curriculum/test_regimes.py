"""The regimes' names, and how a curriculum's budget is shared between stages and branches."""

from __future__ import annotations

import pytest

from amaze.curriculum.regimes import CURRICULUM_REGIMES, REGIMES, branch_allowance


def test_the_curriculum_regimes_are_regimes() -> None:
    assert set(CURRICULUM_REGIMES) < set(REGIMES) and "direct" not in CURRICULUM_REGIMES


def test_branch_allowance_is_the_papers_split_with_hand_on() -> None:
    assert branch_allowance(3_000_000, 0, 0, 10, 3) == 100_000
    # stage 0 trained one agent for 100 k: the 9 stages left share the other 2.9 M
    assert branch_allowance(3_000_000, 100_000, 1, 10, 3) == 2_900_000 // 27
    assert branch_allowance(1000, 950, 9, 10, 2) == 25
    assert branch_allowance(1000, 2000, 9, 10, 2) == 0
    with pytest.raises(ValueError, match="stage 10"):
        branch_allowance(1000, 0, 10, 10, 2)
