"""AMaze as a gymnax ``Environment``, for gymnax's wrappers and PureJaxRL-style code.

:class:`GymnaxMazeEnv` subclasses ``gymnax.environments.environment.Environment``
(gymnax 1.0) around :class:`~amaze.envs.jax.env.JaxMazeEnv`: the same params
(:class:`~amaze.envs.jax.params.MazeParams`, one maze each), the same episodes,
gymnax's spaces (``Discrete(4)``; ``Box(-1, 1, (8,), float32)`` or
``Box(0, 255, (1, v, v), uint8)``) and ``default_params`` (the maze it was made
with). It implements gymnax's hooks (``step_env``, ``reset_env``,
``is_truncated``: the deadline), so gymnax's own ``Environment.step`` runs it,
and overrides ``step`` with :meth:`JaxMazeEnv.step`, which restarts an ended
episode without computing a second observation; both return the same values
and the same ``info`` (gymnax's ``terminated``, ``truncated``,
``final_observation``, plus the episode figures of :mod:`amaze.envs.jax.env`).

Needs gymnax (``pip install "amaze-evo[jax-adapters]"``)::

    from amaze.envs.jax.gymnax_env import make_gymnax
    from gymnax.wrappers.purerl import LogWrapper
    env, params = make_gymnax("M4_10x10_C1", robot="H15")
    env = LogWrapper(env)
"""

from __future__ import annotations

from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
from gymnax.environments import environment, spaces

from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR
from amaze.agents.robot import Robot, as_robot
from amaze.envs.jax.env import JaxMazeEnv, MazeState
from amaze.envs.jax.params import MazeParams, compile_params, unstack
from amaze.errors import AmazeError, OptionError
from amaze.maze.maze import Maze
from amaze.maze.spec import MazeSpec

#: AMaze-v0's default maze, the default params of ``GymnaxMazeEnv()``.
DEFAULT_MAZE = "M0_10x10_C1"


def _refuse_swapped(robot: Any, maze: Any) -> None:
    """A maze string given as the robot (``make`` takes ``(maze, robot)``, gymnax's
    environments the robot first) is refused with the call that was meant."""
    if not isinstance(robot, str) or not isinstance(maze, str):
        return
    try:
        as_robot(robot)
    except AmazeError:
        try:
            MazeSpec.from_string(robot)
            as_robot(maze)
        except AmazeError:
            return
        raise OptionError(
            f"GymnaxMazeEnv({robot!r}, {maze!r}): the robot comes first (make() takes the"
            f" maze first); did you mean GymnaxMazeEnv(robot={maze!r}, maze={robot!r})?"
        ) from None


class GymnaxMazeEnv(environment.Environment):
    """A gymnax environment of one robot; params choose the maze (see the module).

    ``default_params`` are those of ``maze`` (``M0_10x10_C1`` by default, as
    AMaze-v0); any other params of the same robot work, one maze each, stacked
    for ``vmap`` by :func:`~amaze.envs.jax.stack_params`.
    """

    def __init__(
        self,
        robot: Robot | str = "DD",
        maze: Maze | MazeSpec | str = DEFAULT_MAZE,
        *,
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
    ) -> None:
        super().__init__()
        _refuse_swapped(robot, maze)
        self.maze_env = JaxMazeEnv(robot)
        self._default_params = unstack(
            compile_params([maze], self.maze_env.robot, deadline_factor=deadline_factor)
        )

    @property
    def default_params(self) -> MazeParams:
        return self._default_params

    @property
    def name(self) -> str:
        return self.maze_env.name

    @property
    def num_actions(self) -> int:
        return self.maze_env.num_actions

    # -- gymnax's hooks -------------------------------------------------------------

    def step_env(
        self, key: jax.Array, state: MazeState, action: Any, params: MazeParams
    ) -> tuple[jax.Array, MazeState, jax.Array, jax.Array, dict[str, Any]]:
        """One step without restart: ``(obs, state, reward, terminated, info)``."""
        obs, state, reward, terminated, _, info = self.maze_env.step_env(key, state, action, params)
        del info["final_observation"], info["terminated"], info["truncated"]
        return obs, state, reward, terminated, info

    def reset_env(self, key: jax.Array, params: MazeParams) -> tuple[jax.Array, MazeState]:
        return self.maze_env.reset(key, params)

    def is_truncated(self, state: MazeState, params: MazeParams) -> jax.Array:
        """The deadline: ``ceil(deadline_factor * l)`` steps taken."""
        return state.time >= params.deadline

    def is_terminated(self, state: MazeState, params: MazeParams) -> jax.Array:
        """The goal reached."""
        return state.position == params.goal

    def get_obs(self, state: MazeState, params: MazeParams | None = None, key: Any = None) -> Any:
        return self.maze_env.observe(state, self.default_params if params is None else params)

    # -- the fused step -------------------------------------------------------------

    @partial(jax.jit, static_argnames=("self",))
    def step(
        self,
        key: jax.Array,
        state: MazeState,
        action: Any,
        params: MazeParams | None = None,
    ) -> tuple[jax.Array, MazeState, jax.Array, jax.Array, jax.Array, dict[str, Any]]:
        """:meth:`JaxMazeEnv.step`: gymnax's step and auto-reset, one observation per step."""
        return self.maze_env.step(
            key, state, action, self.default_params if params is None else params
        )

    # -- spaces ---------------------------------------------------------------------

    def action_space(self, params: MazeParams | None = None) -> spaces.Discrete:
        """E, N, W, S."""
        return spaces.Discrete(4)

    def observation_space(self, params: MazeParams | None = None) -> spaces.Box:
        """AMaze-v0's observation space."""
        shape = self.maze_env.observation_shape
        if self.maze_env.robot.discrete_inputs:
            return spaces.Box(-1.0, 1.0, shape, jnp.float32)
        return spaces.Box(0, 255, shape, jnp.uint8)


def make_gymnax(
    maze: Maze | MazeSpec | str = DEFAULT_MAZE,
    robot: Robot | str = "DD",
    *,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
) -> tuple[GymnaxMazeEnv, MazeParams]:
    """``(env, env.default_params)``, as ``gymnax.make`` returns them."""
    env = GymnaxMazeEnv(robot, maze, deadline_factor=deadline_factor)
    return env, env.default_params
