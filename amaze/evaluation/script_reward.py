"""R̄ as the paper's evaluation script computed it: the figures of its Table 3.

At the end of the paper's runs (reference repository, commit c4feded,
``Simulation.infos()``'s ``pretty_reward``) an episode scored

    2 x success - steps / (l - 1) - 0.01 x backsteps - 0.02 x collisions

with the weights of collisions and backward steps the other way round from
the paper's Table 2 (this project's R̄, :func:`amaze.agents.rewards.normalized_reward`:
-0.01 per collision, -0.02 per backward step). And a backward step was
counted whenever the robot stood, after a step, in the cell it had left on
its previous move; a robot that had not left its start yet had "left" the
start, so each collision in the start cell before the first move counted as a
backward step too. :func:`script_reward` is that score from an episode's
counts; :func:`script_rewards` plays a policy on mazes to get them (a slow
path, one recorded episode at a time: the start collisions are read from the
trajectory).

Discrete moves only: with continuous moves the script's counts depend on
its own cell bookkeeping, which this project does not reproduce.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from amaze.agents.robot import Robot, as_robot
from amaze.agents.simulation import Trajectory
from amaze.errors import AmazeError
from amaze.evaluation.policy import record_episode
from amaze.maze.maze import Maze
from amaze.maze.spec import MazeSpec

__all__ = [
    "SCRIPT_BACKWARD",
    "SCRIPT_COLLISION",
    "script_reward",
    "script_rewards",
    "start_collisions",
]

#: The script's weight of a collision and of a backward step (the paper's Table 2 swaps them).
SCRIPT_COLLISION = -0.02
SCRIPT_BACKWARD = -0.01


def script_reward(
    success: bool,
    steps: int,
    path_length: int,
    collisions: int,
    backsteps: int,
    start_collisions: int = 0,
) -> float:
    """The script's R̄ of an episode: its counts, the start collisions counted as backsteps."""
    if path_length < 2:
        raise AmazeError(f"path length {path_length} has no step to take (l >= 2)")
    return (
        2.0 * bool(success)
        - steps / (path_length - 1)
        + SCRIPT_BACKWARD * (backsteps + start_collisions)
        + SCRIPT_COLLISION * collisions
    )


def start_collisions(trajectory: Trajectory) -> int:
    """Steps spent in the start cell before the first move out of it (each one a collision)."""
    positions = [*trajectory.positions, trajectory.final_position]
    start = _cell(positions[0])
    count = 0
    for position in positions[1:]:
        if position is None or _cell(position) != start:
            break
        count += 1
    return count


def _cell(position: tuple[float, float] | None) -> tuple[int, int]:
    assert position is not None
    return int(position[0] // 1), int(position[1] // 1)


def script_rewards(
    policy: Any, robot: Robot | str, mazes: Sequence[Maze | MazeSpec | str]
) -> list[float]:
    """The script's R̄ of ``policy`` in each of ``mazes`` (each played as given), in order."""
    robot = as_robot(robot)
    if not robot.discrete_outputs:
        raise AmazeError(
            f"robot {robot.to_string()}: the script's R̄ is reproduced for discrete moves only"
        )
    rewards = []
    for maze in mazes:
        results, trajectory = record_episode(maze, robot, policy)
        rewards.append(
            script_reward(
                bool(results.success[0]),
                int(results.steps[0]),
                int(results.path_length[0]),
                int(results.collisions[0]),
                int(results.backsteps[0]),
                start_collisions(trajectory),
            )
        )
    return rewards
