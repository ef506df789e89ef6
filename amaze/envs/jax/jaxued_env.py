"""AMaze as a jaxued ``UnderspecifiedEnv``: mazes as levels, for PLR / ACCEL-style curricula.

In jaxued an environment is *underspecified*: ``reset_to_level(rng, level,
params)`` starts an episode in a level given as a pytree, and ``step`` does not
restart ended episodes (jaxued's ``AutoReplayWrapper`` and ``AutoResetWrapper``
do). :class:`UEDMazeEnv` makes a level of AMaze's params: one maze's
:class:`~amaze.envs.jax.params.MazeParams`. Levels of one padded size (made
together by :func:`~amaze.envs.jax.make_batch`, or padded by
:func:`~amaze.envs.jax.stack_params` with a given ``max_cells`` and
``max_codes``) go into jaxued's ``LevelSampler`` as a batch; each env state
carries its level (:class:`UEDState`), since jaxued's step sees only the
env's params (here empty, :class:`UEDParams`).

``step`` returns jaxued's five values, ``(obs, state, reward, done, info)``,
with ``done = terminated | truncated`` and the same ``info`` as
:meth:`~amaze.envs.jax.env.JaxMazeEnv.step_env` (``terminated``, ``truncated``
and the episode figures).

Versions: jaxued 0.0.1 (its only PyPI release, March 2025) calls
``jax.tree_map`` in its ``LevelSampler`` and wrappers, which JAX removed in
0.6, while gymnax 1.0.1, which jaxued imports, needs JAX 0.6 or later. With a
JAX recent enough for gymnax, those jaxued functions need the old name back,
``jax.tree_map = jax.tree.map`` (the same function), before they run; this
module does not patch JAX itself. ``UnderspecifiedEnv`` is unaffected.
"""

from __future__ import annotations

from typing import Any

import jax
from flax import struct
from gymnax.environments import spaces
from jaxued.environments.underspecified_env import EnvParams, UnderspecifiedEnv

from amaze.agents.robot import Robot
from amaze.envs.jax.env import JaxMazeEnv, MazeState
from amaze.envs.jax.params import MazeParams


@struct.dataclass
class UEDParams(EnvParams):
    """jaxued's env params: nothing, since the maze is the level."""


@struct.dataclass
class UEDState:
    """An episode and the level (maze params) it runs in."""

    env_state: MazeState
    level: MazeParams


class UEDMazeEnv(UnderspecifiedEnv):
    """AMaze for one robot with discrete actions, levels being maze params (see the module)."""

    def __init__(self, robot: Robot | str = "DD") -> None:
        self.maze_env = JaxMazeEnv(robot)

    @property
    def default_params(self) -> UEDParams:
        return UEDParams()

    def reset_env_to_level(
        self, rng: jax.Array, level: MazeParams, params: UEDParams
    ) -> tuple[jax.Array, UEDState]:
        """The start of an episode in ``level``."""
        obs, state = self.maze_env.reset(rng, level)
        return obs, UEDState(env_state=state, level=level)

    def step_env(
        self, rng: jax.Array, state: UEDState, action: Any, params: UEDParams
    ) -> tuple[jax.Array, UEDState, jax.Array, jax.Array, dict[str, Any]]:
        """One step, without restart: ``(obs, state, reward, done, info)``."""
        obs, env_state, reward, terminated, truncated, info = self.maze_env.step_env(
            rng, state.env_state, action, state.level
        )
        del info["final_observation"]
        return obs, state.replace(env_state=env_state), reward, terminated | truncated, info

    def action_space(self, params: UEDParams | None = None) -> spaces.Discrete:
        """E, N, W, S (gymnax's space, as jaxued's environments use)."""
        return spaces.Discrete(4)

    def observation_space(self, params: UEDParams | None = None) -> spaces.Box:
        """AMaze-v0's observation space."""
        shape = self.maze_env.observation_shape
        if self.maze_env.robot.discrete_inputs:
            return spaces.Box(-1.0, 1.0, shape, self.maze_env.observation_dtype)
        return spaces.Box(0, 255, shape, self.maze_env.observation_dtype)
