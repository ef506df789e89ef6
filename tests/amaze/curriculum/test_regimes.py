"""The paper's regimes as stage lists, and how a budget is shared between stages."""

from __future__ import annotations

import pytest

from amaze.curriculum.interpolation import curriculum
from amaze.curriculum.regimes import regime_stages, stage_end
from amaze.errors import AmazeError
from amaze.evaluation.suite import PAPER_EVALUATION_MAZE, PAPER_TRAINING_MAZE
from amaze.maze import MazeSpec, rotations


def test_direct_regime_trains_on_the_paper_maze_and_evaluates_on_the_other() -> None:
    (stage,) = regime_stages("direct")
    assert stage.training == tuple(rotations(PAPER_TRAINING_MAZE))
    assert stage.evaluation == tuple(rotations(PAPER_EVALUATION_MAZE))


def test_interpolation_regime_is_the_curriculum_in_rotations() -> None:
    stages = regime_stages("interpolation")
    targets = curriculum(PAPER_TRAINING_MAZE)
    assert len(stages) == len(targets) == 10
    for stage, target in zip(stages, targets, strict=True):
        assert stage.training == stage.evaluation == tuple(rotations(target))
    last = MazeSpec.from_string(stages[-1].training[2])  # SW: the target itself
    assert last == MazeSpec.from_string(PAPER_TRAINING_MAZE)


def test_unknown_regime_is_named() -> None:
    with pytest.raises(AmazeError, match="'edhucat'"):
        regime_stages("edhucat")


def test_stage_shares_hand_unused_budget_on() -> None:
    assert stage_end(1000, 0, 10) == 100
    # stage 1 converged after 20 steps: the 9 stages left share the other 980
    assert stage_end(1000, 20, 9) == 20 + 980 // 9
    assert stage_end(1000, 950, 1) == 1000
