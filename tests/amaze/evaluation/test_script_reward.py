"""R̄ as the paper's evaluation script scored it, against a plain reading of its rules.

The reading (c4feded, ``Simulation.step`` and ``infos``): the robot's ``prev_cell`` starts as
its start cell and becomes the cell it left on each move; after every step, standing in the
``prev_cell`` it had before the step is a backward step; the score is
``2 success - steps / (l - 1) - 0.01 backsteps - 0.02 collisions``.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from amaze.agents.simulation import Trajectory
from amaze.errors import AmazeError
from amaze.evaluation.policy import record_episode
from amaze.evaluation.script_reward import script_reward, script_rewards, start_collisions

MAZES = ["M4_5x5_U", "M7_6x6_C1", "M9_7x7_C1_l.25_L.25_t.5_T.5"]


class _Random:
    """Random moves from a seed: the episodes bump, come back and wander."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        return self.rng.integers(0, 4, len(observations))


def _cell(position: tuple[float, float]) -> tuple[int, int]:
    return int(np.floor(position[0])), int(np.floor(position[1]))


def _read_as_the_script(trajectory: Trajectory, success: bool, l: int) -> float:
    cells = [_cell(p) for p in [*trajectory.positions, trajectory.final_position]]
    prev_cell, backsteps, collisions = cells[0], 0, 0
    for before, after in itertools.pairwise(cells):
        prev_prev = prev_cell
        if before == after:
            collisions += 1
        else:
            prev_cell = before
        if prev_prev == after:
            backsteps += 1
    steps = len(trajectory.positions)
    return 2 * success - steps / (l - 1) - 0.01 * backsteps - 0.02 * collisions


@pytest.mark.parametrize("maze", MAZES)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_score_is_the_scripts_reading_of_the_episode(maze: str, seed: int) -> None:
    results, trajectory = record_episode(maze, "DD", _Random(seed))
    expected = _read_as_the_script(
        trajectory, bool(results.success[0]), int(results.path_length[0])
    )
    (scored,) = script_rewards(_Random(seed), "DD", [maze])
    assert scored == pytest.approx(expected, abs=1e-12)


class _Always:
    def __init__(self, action: int) -> None:
        self.action = action

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        return np.full(len(observations), self.action)


def test_collisions_in_the_start_cell_count_as_backward_steps() -> None:
    results, trajectory = record_episode("M4_5x5_U", "DD", _Always(1))  # north: a wall
    steps = int(results.steps[0])
    assert start_collisions(trajectory) == steps == int(results.collisions[0])
    assert int(results.backsteps[0]) == 0  # this project's count: none
    l = int(results.path_length[0])
    expected = -steps / (l - 1) - 0.01 * steps - 0.02 * steps
    assert script_rewards(_Always(1), "DD", ["M4_5x5_U"]) == [pytest.approx(expected)]
    moved = record_episode("M4_5x5_U", "DD", _Always(0))[1]  # east, then a wall
    assert start_collisions(moved) == 0


def test_an_optimal_episode_scores_one_and_bad_input_is_refused() -> None:
    assert script_reward(True, 28, 29, 0, 0) == pytest.approx(1.0)
    assert script_reward(False, 10, 11, 2, 3, 1) == pytest.approx(-1 - 0.04 - 0.04)
    with pytest.raises(AmazeError, match="path length 1"):
        script_reward(True, 1, 1, 0, 0)
    with pytest.raises(AmazeError, match="discrete moves only"):
        script_rewards(_Always(0), "CC15", MAZES[:1])
