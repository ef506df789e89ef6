"""AMaze as a JAX environment: jit, vmap and scan over thousands of mazes.

The one part of :mod:`amaze` that imports JAX (``import amaze`` never loads
it; an import-linter contract in ``pyproject.toml`` keeps it so)::

    from amaze.envs.jax import make, make_batch
    env, params = make("M4_10x10_C1", robot="DD")        # one maze
    obs, state = env.reset(key, params)
    obs, state, reward, terminated, truncated, info = env.step(key, state, action, params)

:class:`~amaze.envs.jax.env.JaxMazeEnv` has gymnax 1.0's functional interface
and auto-reset, and reproduces the batch engine's episodes. Its params
(:class:`~amaze.envs.jax.params.MazeParams`) are one maze's tables. Mazes of
different sizes are padded to one shape: :func:`make_batch` gives the params
of many mazes with a leading axis, agent ``k`` playing maze ``k % len(mazes)``
as in the vector env, and :func:`stack_params` pads and stacks params made
apart; ``jax.vmap(env.step)`` then steps them all, and a new batch of the same
padded size runs without recompiling. ``docs/jax.md`` has a PureJaxRL-style
rollout of 1024 environments over mixed-size mazes.

Adapters, loaded on first use: :class:`GymnaxMazeEnv` (``amaze.envs.jax.gymnax_env``),
a gymnax ``Environment``, and :class:`UEDMazeEnv` (``amaze.envs.jax.jaxued_env``),
jaxued's ``UnderspecifiedEnv`` whose levels are params.

**Scope.** :class:`JaxMazeEnv` runs robots with discrete actions: ``DD`` (8
floats) and the hybrid robots ``H5`` ... ``H65`` (``(1, v, v)`` uint8 images,
channel first, as AMaze-v0); asking it for a continuous robot raises
:class:`~amaze.errors.OptionError`. Continuous robots (``CC5`` ... ``CC65``)
run in :class:`~amaze.envs.jax.continuous.JaxContinuousEnv`
(:func:`make_continuous`), the same interface with accelerations for actions.

**Installing.** ``pip install "amaze-evo[jax]"`` (JAX's CPU wheels), and
``"amaze-evo[jax-adapters]"`` for gymnax (1.0.1) and jaxued (0.0.1). For an
NVIDIA GPU, install JAX's CUDA build at the version of the ``jax`` installed:
``pip install "jax[cuda12]==<that version>"``; the same code runs on either.
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib import import_module
from typing import Any

from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR
from amaze.agents.robot import Robot
from amaze.envs.jax.continuous import (
    ContinuousParams,
    ContinuousState,
    JaxContinuousEnv,
    make_continuous,
)
from amaze.envs.jax.env import JaxMazeEnv, MazeState, _renamed_maze_env
from amaze.envs.jax.params import (
    MazeLike,
    MazeParams,
    compile_params,
    padded_size,
    stack_params,
    tile_params,
    unstack,
)
from amaze.errors import OptionError
from amaze.maze.maze import Maze
from amaze.maze.spec import MazeSpec

__all__ = [
    "ContinuousParams",
    "ContinuousState",
    "GymnaxMazeEnv",
    "JaxContinuousEnv",
    "JaxMazeEnv",
    "MazeParams",
    "MazeState",
    "UEDMazeEnv",
    "make",
    "make_batch",
    "make_continuous",
    "padded_size",
    "stack_params",
]

_LAZY = {
    "GymnaxMazeEnv": "amaze.envs.jax.gymnax_env",
    "UEDMazeEnv": "amaze.envs.jax.jaxued_env",
}


def make(
    maze: Maze | MazeSpec | str,
    robot: Robot | str = "DD",
    *,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
    max_cells: int | None = None,
    max_codes: int | None = None,
) -> tuple[JaxMazeEnv, MazeParams]:
    """``(env, params)`` of one maze, as ``gymnax.make`` gives them.

    The reward is AMaze-v0's (the reference's per-step reward) and the deadline
    ``ceil(deadline_factor * l)`` steps.

    Args:
        maze: the maze (a string such as ``"M4_10x10_C1"``, a spec or a maze).
        robot: the robot (``DD`` or a hybrid one such as ``H15``).
        deadline_factor: episodes end after ``ceil(deadline_factor * l)`` steps.
        max_cells: pad the params to this many cells (see :mod:`amaze.envs.jax.params`),
            so that they stack with other mazes' params.
        max_codes: pad the params' sign codes likewise.

    Returns:
        The environment (``reset``/``step``, jit- and vmap-able) and the maze's params.
    """
    if isinstance(maze, Sequence) and not isinstance(maze, str):
        raise OptionError(f"make takes one maze, not {type(maze).__name__}: use make_batch")
    env = JaxMazeEnv(robot)
    params = compile_params(
        [maze],
        env.robot,
        deadline_factor=deadline_factor,
        max_cells=max_cells,
        max_codes=max_codes,
    )
    return env, unstack(params)


def make_batch(
    mazes: MazeLike | Sequence[MazeLike],
    robot: Robot | str = "DD",
    *,
    num_envs: int | None = None,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
    max_cells: int | None = None,
    max_codes: int | None = None,
) -> tuple[JaxMazeEnv, MazeParams]:
    """``(env, params)`` of ``num_envs`` environments (default: one per maze), for ``vmap``.

    Environment ``k`` plays maze ``k % len(mazes)`` (as AMaze-v0's vector env);
    the params have a leading axis of ``num_envs``, padded to one size.
    """
    env = JaxMazeEnv(robot)
    params = compile_params(
        mazes, env.robot, deadline_factor=deadline_factor, max_cells=max_cells, max_codes=max_codes
    )
    return env, tile_params(params, num_envs)


def __getattr__(name: str) -> Any:
    """The adapters, imported on first use (they need gymnax and jaxued), and ``MazeEnv``.

    ``MazeEnv`` is the old name of :class:`JaxMazeEnv`, given with a
    :class:`DeprecationWarning` until the next release.
    """
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    if name == "MazeEnv":
        return _renamed_maze_env(__name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
