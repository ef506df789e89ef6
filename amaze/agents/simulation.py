"""One agent in one maze: the readable definition of the reference semantics (§4).

:class:`Simulation` is deliberately plain Python: it is the specification that
the fast batch engine is tested against. It follows amaze-benchmarker 1.0's
``Simulation`` step for step (moves, collisions, continuous physics, rewards,
deadline, statistics), with these fixes of its bugs:

* stepping after the episode ended raises :class:`EpisodeEndedError` (the
  reference added the finish bonus a second time);
* :meth:`Simulation.reset` keeps the ``deadline_factor`` (the reference reset it to 4);
* every observation returned is a fresh array (the reference handed out one
  live buffer, which it then overwrote);
* continuous actions follow :mod:`amaze.agents.actions`: finite accelerations
  are clipped to the action space [-1, 1] (the reference applied any value and
  crashed when the robot left the maze), a NaN or an infinity raises
  :class:`~amaze.errors.ActionError`; the trajectory records the clipped
  acceleration, the one applied;
* the cell the continuous physics looks at is clamped to the maze: a robot
  pushed at full speed against the east or north border for long enough lands
  exactly on the border line (``4.9 + 0.0999999999999999 == 5.0``), where the
  reference indexed outside the maze (``IndexError``); here the border wall
  stops it, as any other wall;
* the ``deadline_factor`` is checked (:func:`~amaze.agents.rewards.check_deadline_factor`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from amaze.agents.actions import continuous_action
from amaze.agents.observations import cell_image, continuous_observation, discrete_observation
from amaze.agents.rewards import (
    DEFAULT_DEADLINE_FACTOR,
    RewardScheme,
    check_deadline_factor,
    normalized_reward,
    pretty_reward,
)
from amaze.agents.robot import ACCELERATION_SCALE, INERTIAL_LOSS, RADIUS, Robot, as_robot
from amaze.errors import EpisodeEndedError
from amaze.maze.directions import OFFSETS, direction_between, discrete_action
from amaze.maze.maze import Maze, as_maze
from amaze.maze.spec import MazeSpec


@dataclass
class EpisodeCounters:
    """The running counters of the episode in progress of one :class:`Simulation`.

    They change at every step (``Simulation.stats``) and restart with the
    episode; finished episodes are held elsewhere: those that ended in one
    batch-engine step in :class:`~amaze.agents.engine.EndedEpisodes`, one per
    agent of a whole run in :class:`~amaze.evaluation.policy.EpisodeResults`.

    ``sign_moves[kind] = [correct, wrong]`` counts the moves made from a cell
    holding a sign of that kind (clue, lure, trap), for discrete actions: a move
    is wrong when its direction is not the correct one there.
    """

    steps: int = 0
    collisions: int = 0
    backsteps: int = 0
    sign_moves: dict[str, list[int]] = field(
        default_factory=lambda: {"clue": [0, 0], "lure": [0, 0], "trap": [0, 0]}
    )

    def sign_errors(self) -> dict[str, float]:
        """Percentage of wrong moves per sign kind (0 where no move was made), as the reference."""
        return {
            kind: (100 * wrong / (correct + wrong) if correct + wrong else 0)
            for kind, (correct, wrong) in self.sign_moves.items()
        }


@dataclass
class Trajectory:
    """Positions (before each step), actions and rewards of an episode.

    ``final_position`` is where the robot stands after the last step recorded.
    Discrete actions are recorded as their unit offsets (E = (1, 0), ...).
    """

    positions: list[tuple[float, float]] = field(default_factory=list)
    actions: list[tuple[float, float]] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    final_position: tuple[float, float] | None = None

    def as_arrays(self) -> dict[str, np.ndarray]:
        """``positions`` (n, 2), ``actions`` (n, 2) and ``rewards`` (n,) as float arrays."""
        return {
            "positions": np.array(self.positions, dtype=float).reshape(-1, 2),
            "actions": np.array(self.actions, dtype=float).reshape(-1, 2),
            "rewards": np.array(self.rewards, dtype=float),
        }


class Simulation:
    """One robot in one maze, stepped by discrete actions (0..3 = E, N, W, S) or accelerations."""

    def __init__(
        self,
        maze: Maze | MazeSpec | str,
        robot: Robot | str = "DD",
        *,
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
        record_trajectory: bool = False,
    ) -> None:
        self.deadline_factor = check_deadline_factor(deadline_factor)
        self.record_trajectory = record_trajectory
        self.reset(maze, robot)

    # -- episode --------------------------------------------------------------

    def reset(
        self, maze: Maze | MazeSpec | str | None = None, robot: Robot | str | None = None
    ) -> None:
        """Start a new episode, optionally in another maze or with another robot."""
        if maze is not None:
            self.maze = as_maze(maze)
        if robot is not None:
            self.robot = as_robot(robot)
        self.dt = 1.0 if self.robot.discrete_outputs else 0.1
        self.rewards = RewardScheme(self.maze.path_length, self.dt, self.deadline_factor)
        self.position = (self.maze.start[0] + 0.5, self.maze.start[1] + 0.5)
        self.velocity = (0.0, 0.0)
        self.previous_cell = self.maze.start
        self.timestep = 0
        self.cumulative_reward = 0.0
        self.stats = EpisodeCounters()
        self.trajectory = Trajectory() if self.record_trajectory else None

    @property
    def cell(self) -> tuple[int, int]:
        return int(self.position[0]), int(self.position[1])

    def success(self) -> bool:
        """The robot is in the goal cell."""
        return self.cell == self.maze.end

    def failure(self) -> bool:
        """The deadline has passed."""
        return self.timestep >= self.rewards.deadline

    def done(self) -> bool:
        return self.success() or self.failure()

    # -- observations ---------------------------------------------------------

    def _arrival(self) -> int | None:
        if self.previous_cell == self.cell:
            return None
        return int(direction_between(self.cell, self.previous_cell))

    def observe(self) -> np.ndarray:
        """The current observation (a fresh float32 array)."""
        arrival = self._arrival()
        if self.robot.discrete_inputs:
            return discrete_observation(self.maze, self.cell, arrival)
        if self.robot.discrete_outputs:
            return cell_image(self.maze, self.cell, self.robot.vision, arrival)
        return continuous_observation(self.maze, self.position, self.robot.vision, arrival)

    # -- dynamics -------------------------------------------------------------

    def step(self, action: Any) -> float:
        """Apply an action; returns the step's reward (reference §4.5).

        A discrete action is an integer 0..3, a continuous one two real numbers
        (clipped to [-1, 1]); anything else, a NaN or an infinity included,
        raises :class:`~amaze.errors.ActionError` and changes nothing.
        """
        if self.done():
            raise EpisodeEndedError(
                "the episode has ended (goal or deadline reached); call reset() first"
            )
        reward = 0.0
        before_previous = self.previous_cell
        start_position = self.position
        start_cell = self.cell
        if self.robot.discrete_outputs:
            collision, recorded_action = self._move_discrete(action)
        else:
            collision, recorded_action = self._move_continuous(action)
        if collision:
            reward += self.rewards.collision
            self.stats.collisions += 1
        if self.cell != start_cell:
            self.previous_cell = start_cell
        reward += self.rewards.timestep
        self.stats.steps += 1
        if self.done():
            reward += self.rewards.finish
        if before_previous != self.previous_cell and before_previous == self.cell:
            reward += self.rewards.backward
            self.stats.backsteps += 1
        self.cumulative_reward += reward
        self.timestep += 1
        if self.trajectory is not None:
            self.trajectory.positions.append(start_position)
            self.trajectory.actions.append(recorded_action)
            self.trajectory.rewards.append(reward)
            self.trajectory.final_position = self.position
        return reward

    def _count_sign_move(self, cell: tuple[int, int], direction: int) -> None:
        placed = self.maze.sign_at(cell)
        if placed is not None:
            self.stats.sign_moves[placed.kind.value][int(direction != placed.truth)] += 1

    def _move_discrete(self, action: Any) -> tuple[bool, tuple[float, float]]:
        direction = discrete_action(action)
        i, j = self.cell
        self._count_sign_move((i, j), direction)
        offset = OFFSETS[direction]
        if self.maze.walls[i, j, direction]:
            return True, (float(offset[0]), float(offset[1]))
        self.position = (self.position[0] + offset[0], self.position[1] + offset[1])
        return False, (float(offset[0]), float(offset[1]))

    def _move_continuous(self, action: Any) -> tuple[bool, tuple[float, float]]:
        ax, ay = continuous_action(action)  # checked, clipped to [-1, 1]
        dt = self.dt
        damping = 1.0 - INERTIAL_LOSS * dt
        vx = damping * self.velocity[0] + dt * ACCELERATION_SCALE * ax
        vy = damping * self.velocity[1] + dt * ACCELERATION_SCALE * ay
        if (vx * vx + vy * vy) ** 0.5 < min(0.01, ACCELERATION_SCALE / 2):
            vx, vy = 0.0, 0.0
        self.velocity = (vx, vy)
        x, y = self.position[0] + dt * vx, self.position[1] + dt * vy
        walls, w, h = self.maze.walls, self.maze.width, self.maze.height
        # The cell, clamped to the maze: at full speed against the east or north
        # border, x + dt * vx can round to exactly w (or y to h).
        i, j = min(max(int(x), 0), w - 1), min(max(int(y), 0), h - 1)
        r = RADIUS
        near_w, near_e = x - i <= r, i + 1 - x <= r
        near_s, near_n = y - j <= r, j + 1 - y <= r
        # Stay inside the cell's own walls.
        new_x, new_y = x, y
        if near_w:
            if walls[i, j, 2]:
                new_x = i + r
        elif near_e and walls[i, j, 0]:
            new_x = i + 1 - r
        if near_s:
            if walls[i, j, 3]:
                new_y = j + r
        elif near_n and walls[i, j, 1]:
            new_y = j + 1 - r
        # Wall ends at the corners (first matching case only).
        corner = None
        if near_w and near_s and i > 0 and j > 0:
            corner = (walls[i - 1, j, 3] or walls[i, j - 1, 2], (i, j))
        elif near_w and near_n and i > 0 and j < h - 1:
            corner = (walls[i - 1, j, 1] or walls[i, j + 1, 2], (i, j + 1))
        elif near_e and near_s and i < w - 1 and j > 0:
            corner = (walls[i + 1, j, 3] or walls[i, j - 1, 0], (i + 1, j))
        elif near_e and near_n and i < w - 1 and j < h - 1:
            corner = (walls[i + 1, j, 1] or walls[i, j + 1, 0], (i + 1, j + 1))
        if corner is not None and corner[0]:
            cx, cy = corner[1]
            dx, dy = cx - x, cy - y
            distance = (dx * dx + dy * dy) ** 0.5
            if distance < r:
                if distance > 0:
                    ux, uy = dx / distance, dy / distance
                else:  # exactly on the wall end (the reference divides by zero):
                    # pushed away from it towards the cell's centre
                    ux, uy = (cx - i - 0.5) * math.sqrt(2), (cy - j - 0.5) * math.sqrt(2)
                new_x -= ux * (r - distance)
                new_y -= uy * (r - distance)
        self.position = (new_x, new_y)
        return (new_x != x or new_y != y), (ax, ay)

    def run(self, controller, max_steps: int | None = None) -> dict[str, Any]:
        """Step ``controller(observation) -> action`` until the episode ends; return the infos."""
        steps = 0
        while not self.done() and (max_steps is None or steps < max_steps):
            self.step(controller(self.observe()))
            steps += 1
        return self.infos()

    # -- scores ---------------------------------------------------------------

    def pretty_reward(self) -> float:
        """The reference's normalised reward (linear rescale of R to [-1, 1])."""
        return pretty_reward(self.cumulative_reward, self.rewards)

    def normalized_reward(self) -> float:
        """The paper's R̄ (Table 2; 1 for an optimal run)."""
        return normalized_reward(
            self.success(),
            self.stats.steps,
            self.stats.collisions,
            self.stats.backsteps,
            self.maze.path_length,
            self.dt,
        )

    def infos(self) -> dict[str, Any]:
        """Episode statistics, with the reference's keys plus ``normalized_reward``."""
        return {
            "time": self.timestep,
            "success": self.success(),
            "failure": self.failure(),
            "done": self.done(),
            "pretty_reward": self.pretty_reward(),
            "normalized_reward": self.normalized_reward(),
            "len": self.maze.path_length,
            "steps": self.stats.steps,
            "collisions": self.stats.collisions,
            "backsteps": self.stats.backsteps,
            "errors": self.stats.sign_errors(),
        }
