"""How far along its maze's solution an episode got: ``run_episodes(..., path_progress=True)``."""

from __future__ import annotations

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.evaluation.controllers import OracleController
from amaze.evaluation.policy import path_positions, run_episodes
from amaze.maze import as_maze

MAZES = ["M4_6x6_C1", "M7_8x8_C1_l.25_L.25", "M3_5x5_U"]


class TurnsBack:
    """The oracle's action for ``k`` steps, then the opposite of what it says, for ever.

    After ``k`` steps on the solution the robot stands on its ``k``-th cell; from
    then on it never gets nearer the goal (away from the oracle's next cell it
    bumps a wall, steps back or goes down a side branch).
    """

    def __init__(self, robot: str, k: int) -> None:
        self.oracle, self.k, self.calls = OracleController(robot), k, 0

    def bind(self, engine: BatchEngine) -> None:
        self.oracle.bind(engine)

    def reset(self, n_agents: int) -> None:
        self.calls = 0

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        actions = self.oracle(observations)
        self.calls += 1
        return actions if self.calls <= self.k else (actions + 2) % 4


def test_path_positions_place_every_solution_cell() -> None:
    engine = BatchEngine(MAZES, "DD", 3)
    positions = path_positions(engine)
    tables = engine.tables
    for m, string in enumerate(MAZES):
        solution = as_maze(string).solution
        first = tables.cell_offset[m]
        own = positions[first : first + tables.width[m] * tables.height[m]]
        for k, (i, j) in enumerate(solution):
            assert own[i * tables.height[m] + j] == pytest.approx(k / (len(solution) - 1))
        assert (own == -1).sum() == len(own) - len(solution)


@pytest.mark.parametrize("k", [0, 1, 3])
def test_progress_is_the_furthest_solution_cell_reached(k: int) -> None:
    engine = BatchEngine(MAZES, "DD", 6)
    results = run_episodes(engine, TurnsBack("DD", k), path_progress=True)
    lengths = np.array([len(as_maze(m).solution) for m in MAZES * 2])
    assert not results.success.any()
    np.testing.assert_allclose(results.path_progress, k / (lengths - 1))


def test_success_is_progress_one_and_standing_still_zero() -> None:
    engine = BatchEngine(MAZES, "CC15", 3)
    reached = run_episodes(engine, OracleController("CC15", gain=2, damping=0), path_progress=True)
    assert reached.success.all()
    np.testing.assert_array_equal(reached.path_progress, 1.0)
    still = run_episodes(engine, lambda o: np.zeros((len(o), 2)), path_progress=True)
    np.testing.assert_array_equal(still.path_progress, 0.0)


def test_progress_is_recorded_only_when_asked() -> None:
    engine = BatchEngine(MAZES, "DD", 3)
    plain = run_episodes(engine, TurnsBack("DD", 2))
    tracked = run_episodes(engine, TurnsBack("DD", 2), path_progress=True)
    assert plain.path_progress is None
    np.testing.assert_array_equal(plain.steps, tracked.steps)
    np.testing.assert_array_equal(plain.normalized_reward, tracked.normalized_reward)
