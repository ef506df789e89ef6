"""The native vector environment of ``AMaze-v0``, running on the batch engine.

``gymnasium.make_vec("AMaze-v0", num_envs=N, vectorization_mode="vector_entry_point",
maze=STR or [STR, ...], robot=...)`` returns :class:`MazeVectorEnv`: N agents
stepped together in compiled code (not N Python environments). Agent ``k``
plays maze ``k % len(mazes)``. Episodes restart in the same step they end
(gymnasium's ``AutoresetMode.SAME_STEP``): the returned observation is the first
of the new episode, and ``infos["final_obs"]`` / ``infos["final_info"]`` (with
their ``_final_obs`` / ``_final_info`` masks) hold the last observation and the
episode statistics, including both normalised rewards.

Options and actions follow the single environment's contract (see
:mod:`amaze.envs.gym_env`), checked before anything is generated or allocated
(:class:`~amaze.errors.OptionError` naming the value): ``num_envs`` is an
integer from 1 to :func:`~amaze.agents.engine.max_agents` (the engine's arrays
must fit in :data:`~amaze.agents.engine.MAX_ENGINE_BYTES`, 16 GiB),
``deadline_factor`` a finite number in [1, 1000], ``render_mode`` None (this
environment renders nothing) and ``reset`` takes no options (None or an empty
dict). Continuous actions are clipped to [-1, 1] when finite and refused when
they hold a NaN or an infinity (:class:`~amaze.errors.ActionError` naming the
agents), as in the engine. ``parallel`` (None, True or False) is the engine's:
by default it times its serial and multi-threaded kernels and runs the faster,
which changes how fast a step is, never what it returns.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from amaze.agents.engine import BatchEngine, check_n_agents
from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR, check_deadline_factor
from amaze.agents.robot import Robot, as_robot
from amaze.envs.gym_env import DEFAULT_MAZE, action_space, check_reset_options, observation_space
from amaze.errors import OptionError
from amaze.maze.maze import Maze, as_mazes
from amaze.maze.spec import MazeSpec


class MazeVectorEnv(VectorEnv):
    """``num_envs`` agents in one or several mazes, on the batch engine.

    The gymnasium vector environment of ``AMaze-v0`` (``terminated`` /
    ``truncated``, batched ``infos`` with masks); stable-baselines3 gets its own
    adapter over the same engine, ``rl_baselines.vec_env.SB3VecEnv`` (SB3's
    ``VecEnv`` API), which :mod:`amaze` does not import.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "autoreset_mode": AutoresetMode.SAME_STEP,
        "render_modes": [],
    }

    def __init__(
        self,
        num_envs: int,
        maze: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str] = DEFAULT_MAZE,
        robot: Robot | str = "DD",
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
        render_mode: str | None = None,
        parallel: bool | None = None,
    ) -> None:
        if parallel is not None and not isinstance(parallel, bool):
            raise OptionError(f"parallel {parallel!r} is not one of None, True, False")
        if render_mode is not None:
            raise OptionError(
                f"render_mode {render_mode!r}: the vector environment renders nothing"
                " (render modes: None only)"
            )
        self.robot = as_robot(robot)
        num_envs = check_n_agents(num_envs, self.robot, name="num_envs")
        deadline_factor = check_deadline_factor(deadline_factor)
        self.mazes = as_mazes(maze)
        self.num_envs = num_envs
        self.render_mode = None
        self.engine = BatchEngine(
            self.mazes, self.robot, num_envs, deadline_factor=deadline_factor, auto_reset=True,
            parallel=parallel,
        )  # fmt: skip
        self.single_observation_space = observation_space(self.robot)
        self.single_action_space = action_space(self.robot)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._image = not self.robot.discrete_inputs

    def _format(self, observations: np.ndarray) -> np.ndarray:
        return observations[:, None] if self._image else observations

    def reset(
        self, *, seed: int | Sequence[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Restart every agent (the environment itself draws no random numbers).

        There are no options: ``options`` must be None or an empty dict.
        """
        check_reset_options(options, known=())
        super().reset(seed=seed)
        return self._format(self.engine.reset()), {}

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        result = self.engine.step(actions)
        infos: dict[str, Any] = {}
        episodes = result.episodes
        if len(episodes):
            agents = episodes.agents
            ended = np.zeros(self.num_envs, dtype=bool)
            ended[agents] = True
            final_obs = np.empty(self.num_envs, dtype=object)  # None everywhere
            finals = self._format(result.final_observations)
            # one observation per ended agent (an object array of the rows of finals)
            final_obs[agents] = np.fromiter(finals, dtype=object, count=len(agents))
            infos["final_obs"], infos["_final_obs"] = final_obs, ended
            final_info: dict[str, Any] = {}
            for key, values in (
                ("success", episodes.success),
                ("steps", episodes.steps),
                ("collisions", episodes.collisions),
                ("backsteps", episodes.backsteps),
                ("len", episodes.path_length),
                ("cumulative_reward", episodes.cumulative_reward),
                ("pretty_reward", episodes.pretty_rewards()),
                ("normalized_reward", episodes.normalized_rewards()),
            ):
                column = np.zeros(self.num_envs, dtype=np.asarray(values).dtype)
                column[episodes.agents] = values
                final_info[key], final_info[f"_{key}"] = column, ended
            infos["final_info"], infos["_final_info"] = final_info, ended
        return (
            self._format(result.observations),
            result.rewards,
            result.terminated,
            result.truncated,
            infos,
        )
