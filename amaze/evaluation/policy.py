"""The policy protocol, and running policies in mazes on the batch engine.

Every agent of this project (built-in controllers, evolved networks, SB3
models) is evaluated through one interface, a :class:`Policy`: a callable from
a batch of observations to a batch of actions.

* Observations come in the gymnasium format of ``AMaze-v0``: float32
  ``(n, 8)`` for discrete inputs, uint8 ``(n, 1, v, v)`` images for hybrid and
  continuous robots (so an SB3 model's ``predict`` fits as it is).
* Actions are integers ``(n,)`` in ``0..3`` (E, N, W, S) for discrete outputs,
  floats ``(n, 2)`` (accelerations) for continuous ones.

Optional methods let a policy keep state, look at the maze itself or save work:

* ``reset(n_agents)`` is called before the first step of a run (recurrent or
  random policies start afresh there);
* ``bind(engine)`` hands over the :class:`~amaze.agents.engine.BatchEngine` before the
  first step, for privileged controllers such as the oracle that follows the
  solution. Learned agents never use it;
* ``retire(agents)`` is called by :func:`run_episodes` with the agents whose
  scored (first) episode has just ended: their later actions are ignored, so a
  policy may stop computing them (and return any valid action for them) until
  the next ``reset``. Populations of evolved networks skip them this way.

:func:`run_episodes` plays one episode per agent, all agents together;
:func:`record_episode` plays one episode of one agent and records its trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from amaze.agents.actions import clip_acceleration
from amaze.agents.engine import BatchEngine, EndedEpisodes
from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR
from amaze.agents.robot import Robot
from amaze.agents.simulation import Trajectory
from amaze.errors import ActionError
from amaze.maze.directions import OFFSETS
from amaze.maze.maze import Maze
from amaze.maze.spec import MazeSpec

__all__ = [
    "EpisodeResults",
    "Policy",
    "as_policy_observations",
    "path_positions",
    "record_episode",
    "run_episodes",
]


@runtime_checkable
class Policy(Protocol):
    """A batch of observations in, a batch of actions out (see the module docstring)."""

    def __call__(self, observations: np.ndarray) -> np.ndarray: ...


def as_policy_observations(observations: np.ndarray, robot: Robot) -> np.ndarray:
    """The engine's observations in the policy (gymnasium) format: images get a channel axis."""
    return observations if robot.discrete_inputs else observations[:, None]


def _prepare(policy: Any, engine: BatchEngine) -> None:
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset(engine.n_agents)
    bind = getattr(policy, "bind", None)
    if callable(bind):
        bind(engine)


def _actions(policy: Any, observations: np.ndarray, engine: BatchEngine) -> np.ndarray:
    actions = np.asarray(policy(as_policy_observations(observations, engine.robot)))
    n = engine.n_agents
    if engine.robot.discrete_outputs:
        actions = actions.reshape(-1)
        if actions.shape != (n,):
            raise ActionError(f"the policy returned {actions.shape[0]} actions for {n} agents")
        if not np.issubdtype(actions.dtype, np.integer):
            raise ActionError(f"discrete actions must be integers, the policy gave {actions.dtype}")
    elif actions.shape != (n, 2):
        raise ActionError(f"continuous actions must have shape ({n}, 2), got {actions.shape}")
    return actions


@dataclass(frozen=True)
class EpisodeResults:
    """One finished episode per agent of a run (arrays aligned with the agents).

    :func:`run_episodes` gathers each agent's first episode from the
    :class:`~amaze.agents.engine.EndedEpisodes` of successive engine steps
    (which hold only the episodes that ended in one step); the evaluation
    protocol turns each agent's entry into an
    :class:`~amaze.evaluation.protocol.EpisodeResult`, one episode with its maze.

    ``cumulative_reward`` is the reference's raw return; ``pretty_reward`` its
    normalisation to [-1, 1]; ``normalized_reward`` the paper's R̄ (1 for an optimal run).
    ``path_progress`` (when :func:`run_episodes` was asked for it, else None): how far
    along its maze's solution the agent got, the furthest solution cell it stood in as a
    share of the path (0 at the start cell, 1 on success); see :func:`path_positions`.
    """

    maze_index: np.ndarray
    success: np.ndarray
    steps: np.ndarray
    collisions: np.ndarray
    backsteps: np.ndarray
    path_length: np.ndarray
    cumulative_reward: np.ndarray
    pretty_reward: np.ndarray
    normalized_reward: np.ndarray
    path_progress: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.success.shape[0])


def path_positions(engine: BatchEngine) -> np.ndarray:
    """Per cell of ``engine``'s compiled mazes, its place on its maze's solution (-1 off it).

    float64 over the global cells of :attr:`BatchEngine.tables` (maze ``m``'s cell
    ``(i, j)`` at ``cell_offset[m] + i * height[m] + j``): the solution's ``k``-th
    cell holds ``k / (l - 1)``, so the start holds 0 and the goal 1
    (:meth:`~amaze.maze.maze.Maze.path_positions`, maze by maze).
    """
    tables = engine.tables
    positions = np.full(tables.n_cells, -1.0)
    for m, maze in enumerate(engine.mazes):
        offset = int(tables.cell_offset[m])
        positions[offset : offset + maze.width * maze.height] = maze.path_positions()
    return positions


def _agent_cells(engine: BatchEngine) -> np.ndarray:
    """Every agent's cell as a global cell index of the engine's tables."""
    tables, maze = engine.tables, engine.assignment
    cells = engine.cells
    return tables.cell_offset[maze] + cells[:, 0] * tables.height[maze] + cells[:, 1]


def run_episodes(
    engine: BatchEngine,
    policy: Any,
    max_steps: int | None = None,
    *,
    path_progress: bool = False,
) -> EpisodeResults:
    """Reset ``engine`` and play until every agent has finished one episode.

    The engine must auto-reset (its default): agents that finish early go on
    in new episodes whose results are ignored, so that the whole batch keeps
    stepping together. ``max_steps`` caps the number of batch steps (an
    episode cannot outlast its deadline anyway); agents still running then
    raise an error rather than being silently scored. A policy's ``retire``
    hook, if any, hears of each agent whose scored episode has ended.

    ``path_progress=True`` also records how far along its maze's solution each
    agent got (:attr:`EpisodeResults.path_progress`): its cell is looked up after
    every step, a cost the other figures do not pay. The cell an agent reaches
    in the step that ends its episode is not looked up (the engine has already
    put it back at the start), except that success counts as the goal: 1.
    """
    if not engine.auto_reset:
        raise ValueError("run_episodes needs an engine built with auto_reset=True")
    n = engine.n_agents
    observations = engine.reset()
    _prepare(policy, engine)
    retire = getattr(policy, "retire", None)
    if not callable(retire):
        retire = None
    finished = np.zeros(n, dtype=bool)
    fields = {
        key: np.zeros(n, dtype=dtype)
        for key, dtype in (
            ("success", bool),
            ("steps", np.int64),
            ("collisions", np.int64),
            ("backsteps", np.int64),
            ("path_length", np.int64),
            ("cumulative_reward", np.float64),
        )
    }
    progress = np.zeros(n) if path_progress else None
    positions = path_positions(engine) if path_progress else None
    steps = 0
    while not finished.all():
        if max_steps is not None and steps >= max_steps:
            raise RuntimeError(f"{int((~finished).sum())} agents still running after {steps} steps")
        result = engine.step(_actions(policy, observations, engine))
        observations = result.observations
        steps += 1
        if progress is not None:  # an agent whose episode ended stands at its start: 0
            reached = np.maximum(positions[_agent_cells(engine)], 0.0)
            np.maximum(progress, np.where(finished, 0.0, reached), out=progress)
        episodes = result.episodes
        if len(episodes):
            first = ~finished[episodes.agents]
            if first.any():
                agents = episodes.agents[first]
                fields["success"][agents] = episodes.success[first]
                fields["steps"][agents] = episodes.steps[first]
                fields["collisions"][agents] = episodes.collisions[first]
                fields["backsteps"][agents] = episodes.backsteps[first]
                fields["path_length"][agents] = episodes.path_length[first]
                fields["cumulative_reward"][agents] = episodes.cumulative_reward[first]
                finished[agents] = True
                if retire is not None:
                    retire(agents)
    # the normalised rewards of the scored episodes only, computed once
    scored = EndedEpisodes(
        agents=np.arange(n),
        dt=engine.dt,
        deadline_factor=engine.deadline_factor,
        **fields,
    )
    if progress is not None:
        progress[fields["success"]] = 1.0
    return EpisodeResults(
        maze_index=engine.assignment,
        pretty_reward=scored.pretty_rewards(),
        normalized_reward=scored.normalized_rewards(),
        path_progress=progress,
        **fields,
    )


def record_episode(
    maze: Maze | MazeSpec | str,
    robot: Robot | str,
    policy: Any,
    *,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
) -> tuple[EpisodeResults, Trajectory]:
    """Play one episode of one agent and record its trajectory.

    The trajectory holds the position before each step, the action applied
    (an acceleration clipped to [-1, 1], as :class:`~amaze.agents.simulation.Simulation`
    records it) and the reward; ``Trajectory.final_position`` is where the robot ended.
    """
    engine = BatchEngine([maze], robot, 1, deadline_factor=deadline_factor, auto_reset=False)
    observations = engine.reset()
    _prepare(policy, engine)
    trajectory = Trajectory()
    while True:
        position = engine.positions[0]
        actions = _actions(policy, observations, engine)
        result = engine.step(actions)
        observations = result.observations
        if engine.robot.discrete_outputs:
            dx, dy = OFFSETS[int(actions[0])]
            action = (float(dx), float(dy))
        else:
            action = (
                clip_acceleration(float(actions[0, 0])),
                clip_acceleration(float(actions[0, 1])),
            )
        trajectory.positions.append((float(position[0]), float(position[1])))
        trajectory.actions.append(action)
        trajectory.rewards.append(float(result.rewards[0]))
        if result.done[0]:
            final = engine.positions[0]
            trajectory.final_position = (float(final[0]), float(final[1]))
            episodes = result.episodes
            return (
                EpisodeResults(
                    maze_index=np.zeros(1, dtype=np.int64),
                    success=episodes.success.copy(),
                    steps=episodes.steps.copy(),
                    collisions=episodes.collisions.copy(),
                    backsteps=episodes.backsteps.copy(),
                    path_length=episodes.path_length.copy(),
                    cumulative_reward=episodes.cumulative_reward.copy(),
                    pretty_reward=episodes.pretty_rewards(),
                    normalized_reward=episodes.normalized_rewards(),
                ),
                trajectory,
            )
