"""An SB3 ``VecEnv`` over the batch engine: all environments stepped together.

SB3's own vectorisation (``DummyVecEnv``) loops over N Python environments;
:class:`SB3VecEnv` instead drives one :class:`~amaze.agents.engine.BatchEngine` with
N agents, so a step of all environments is one call into compiled code.
Environment ``k`` starts in ``mazes[k % len(mazes)]``; with more mazes than
environments, each goes on to the next of its own in every episode
(``mazes[(k + e * n_envs) % len(mazes)]`` in its episode ``e``), so every maze is
played: a batch of a maze's 4 rotations with ``n_envs`` 4 keeps each
environment on one rotation, moving to the next maze's same rotation.

SB3 semantics: :meth:`SB3VecEnv.step_wait` returns ``(obs, rewards float32,
dones, infos)``; an environment whose episode ended is reset in the same step
(the returned observation is the first of the new episode) and its info holds
``terminal_observation``, ``TimeLimit.truncated`` (deadline reached without
reaching the goal), ``episode`` (``r``, ``l``, ``t``: what SB3's ``Monitor``
would give, so that SB3 logs episode returns), and the episode's ``success``,
``pretty_reward`` and ``normalized_reward``.

Observations are those of ``AMaze-v0``: float32 ``(8,)`` for discrete inputs,
uint8 ``(1, v, v)`` channel-first images otherwise (too small for SB3's
``CnnPolicy``; see :mod:`rl_baselines.networks`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvStepReturn,
)

from amaze.agents.engine import BatchEngine
from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR
from amaze.agents.robot import Robot, as_robot
from amaze.envs.gym_env import action_space, observation_space
from amaze.evaluation.policy import as_policy_observations
from amaze.maze.maze import Maze, as_mazes
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer
from rl_baselines import RLConfigError

__all__ = ["SB3VecEnv"]


class SB3VecEnv(VecEnv):
    """``n_envs`` SB3 environments in ``mazes`` for ``robot``, on one batch engine.

    The stable-baselines3 adapter (SB3's ``VecEnv`` API: ``step_async`` /
    ``step_wait``, ``dones`` and per-environment ``infos``); the gymnasium
    vector environment over the same engine is
    :class:`amaze.envs.vector_env.MazeVectorEnv` (``terminated`` /
    ``truncated`` and gymnasium's batched infos).

    ``seed`` is accepted for SB3's interface; the mazes and the simulation are
    deterministic, so the environment itself draws no random numbers.
    """

    def __init__(
        self,
        mazes: Sequence[Maze | MazeSpec | str] | str,
        robot: Robot | str = "DD",
        n_envs: int = 4,
        seed: int | None = None,
        *,
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
    ) -> None:
        n_envs = check_integer("n_envs", n_envs, minimum=1, error=RLConfigError)
        self.mazes = as_mazes(mazes)
        self.robot = as_robot(robot)
        self.engine = BatchEngine(
            self.mazes, self.robot, n_envs, deadline_factor=deadline_factor, auto_reset=True
        )
        self.render_mode = None
        super().__init__(n_envs, observation_space(self.robot), action_space(self.robot))
        self._seed = seed
        self._actions: np.ndarray | None = None
        self._start = np.full(n_envs, time.time())
        #: Episodes each environment has ended (which maze it plays next, with many mazes).
        self._episodes = np.zeros(n_envs, dtype=np.int64)

    def _format(self, observations: np.ndarray) -> np.ndarray:
        return as_policy_observations(observations, self.robot)

    def reset(self) -> np.ndarray:
        """Restart every environment and return the first observations."""
        self._reset_seeds()
        self._reset_options()
        self._start[:] = time.time()
        self._episodes[:] = 0
        agents = np.arange(self.num_envs)
        return self._format(self.engine.reset(agents, agents % len(self.mazes)))

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        if self.robot.discrete_outputs:
            actions = actions.reshape(self.num_envs).astype(np.int64, copy=False)
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait called without step_async")
        result = self.engine.step(self._actions)
        self._actions = None
        dones = result.terminated | result.truncated
        observations = result.observations
        if len(self.mazes) > self.num_envs and dones.any():
            observations = self._next_mazes(np.flatnonzero(dones))
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        episodes = result.episodes
        if len(episodes):
            now = time.time()
            finals = self._format(result.final_observations)
            pretty = episodes.pretty_rewards()
            paper = episodes.normalized_rewards()
            for index, agent in enumerate(episodes.agents.tolist()):
                info = infos[agent]
                info["terminal_observation"] = finals[index]
                info["TimeLimit.truncated"] = bool(
                    result.truncated[agent] and not result.terminated[agent]
                )
                info["success"] = bool(episodes.success[index])
                info["pretty_reward"] = float(pretty[index])
                info["normalized_reward"] = float(paper[index])
                info["episode"] = {
                    "r": float(episodes.cumulative_reward[index]),
                    "l": int(episodes.steps[index]),
                    "t": round(now - self._start[agent], 6),
                }
                self._start[agent] = now
        return (
            self._format(observations),
            result.rewards.astype(np.float32),
            dones,
            infos,
        )

    def _next_mazes(self, ended: np.ndarray) -> np.ndarray:
        """Move the environments whose episode ended to their next maze; all observations."""
        self._episodes[ended] += 1
        assignment = (ended + self._episodes[ended] * self.num_envs) % len(self.mazes)
        return self.engine.reset(ended, assignment)

    def close(self) -> None:
        """Nothing to release (the engine holds only arrays)."""

    def seed(self, seed: int | None = None) -> list[int | None]:
        """Record ``seed`` (the environment is deterministic and draws nothing)."""
        self._seed = seed
        return [seed for _ in range(self.num_envs)]

    def _indices(self, indices: VecEnvIndices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, int):
            return [indices]
        return list(indices)

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The adapter's own attribute, once per environment (they share it)."""
        value = getattr(self, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self, attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        method = getattr(self, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._indices(indices)]

    def env_is_wrapped(
        self, wrapper_class: type[gymnasium.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """No gymnasium wrappers here (episode statistics come with ``infos``)."""
        return [False for _ in self._indices(indices)]
