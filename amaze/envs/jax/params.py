"""The maze tables of the JAX environment: one maze per params, padded into batches.

:class:`MazeParams` holds everything a step of :class:`~amaze.envs.jax.env.JaxMazeEnv`
reads about one maze, built from the batch engine's tables
(:func:`amaze.agents.tables.compile_mazes`), so that both run on the same
precomputed data:

* **positions.** A robot's position is one int32, ``cell << 16 | code``: its
  cell (``i * height + j``, the engine's local cell number) and the *code* of
  what it sees there. ``moves[cell, d]`` is the position reached through side
  ``d`` (-1 behind a wall), so a move and the code of the new cell's
  observation come from one look-up;
* **observation codes.** The engine's per-cell observations (the 8 floats of
  ``discrete_obs``, or the ``v x v`` tile of ``tiles``) repeat: a maze has a
  few dozen distinct ones (a wall configuration and a sign). ``observations``
  holds each distinct one once, the arrival side folded in for ``DD``
  (``observations[code * 5 + arrival]``, arrival 0 at the start, else ``1 +``
  the side leading back), and the tile without the origin marker for image
  robots (the marker is added at observation time). A batch of 4096 mazes thus
  weighs a few tens of megabytes instead of gigabytes;
* **episode constants**: start and goal positions, the deadline in whole steps
  (``ceil`` of ``deadline_factor * l``, as the engine), the reward of the step
  that reaches the goal, ``l``, the reference's ``minimal_reward`` (for
  ``pretty_reward``), width and height.

**Padding.** Mazes of different sizes share one array shape: ``moves`` is padded
to ``max_cells`` rows (of -1, never reached) and ``observations`` to
``max_codes`` codes (of zeros, never read). The padded size of params is
``(max_cells, max_codes)`` (:func:`padded_size`); a jitted function called
with params of the same padded size and batch size never recompiles, whatever
their mazes. By default ``max_cells`` is the largest maze of the batch and
``max_codes`` the smallest power of two that holds every maze's codes, at
least :data:`MIN_CODES`; give both to keep one shape across batches.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from amaze.agents.rewards import (
    BACKWARD_PENALTY,
    COLLISION_PENALTY,
    DEFAULT_DEADLINE_FACTOR,
    TIMESTEP_PENALTY,
    RewardScheme,
)
from amaze.agents.robot import Robot, as_robot, robot_name
from amaze.agents.tables import N_ARRIVALS, MazeTables, compile_mazes
from amaze.errors import OptionError
from amaze.maze.maze import Maze, as_mazes
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer

#: A position is ``cell << POSITION_SHIFT | code``.
POSITION_SHIFT = 16
#: The code part of a position.
CODE_MASK = (1 << POSITION_SHIFT) - 1
#: Cells of a maze must fit the 15 bits above the code (100x100 mazes have 10^4).
MAX_CELLS = (1 << 15) - 1
#: The smallest default ``max_codes``: most mazes have fewer distinct observations.
MIN_CODES = 64

MazeLike = Maze | MazeSpec | str


class MazeParams(NamedTuple):
    """The tables of one maze, or of a batch of mazes with a leading axis (see the module).

    ``moves`` int32 ``(max_cells, 4)``: the position reached through each side
    (-1 behind a wall); ``observations``: float32 ``(max_codes * 5, 8)`` for
    ``DD``, uint8 ``(max_codes, v, v)`` for image robots; ``start``, ``goal``:
    positions; ``deadline``: steps; ``goal_reward``: float32, the reward of the
    step reaching the goal; ``path_length`` (``l``); ``min_reward``: float32,
    the reference's worst return; ``width``, ``height``.
    """

    moves: jax.Array
    observations: jax.Array
    start: jax.Array
    goal: jax.Array
    deadline: jax.Array
    goal_reward: jax.Array
    path_length: jax.Array
    min_reward: jax.Array
    width: jax.Array
    height: jax.Array


def supported_robot(robot: Robot | str) -> Robot:
    """``robot`` as a :class:`Robot` with discrete actions, else :class:`OptionError`.

    A malformed robot string raises :class:`~amaze.agents.robot.RobotStringError`.
    """
    parsed = as_robot(robot)
    if not parsed.discrete_outputs:
        raise OptionError(
            f"robot {robot_name(robot)}: the JAX environment runs robots with discrete"
            " actions only (DD, H5 ... H65); continuous robots run on the batch engine"
            " (amaze.agents.engine.BatchEngine) or AMaze-v0"
        )
    return parsed


def _engine_reward(blocked: int, backward: int, finish: float = 0.0) -> np.float32:
    """The engine's float64 reward of one discrete step (its order of sums), as float32.

    ``amaze.agents.engine._grid_step``: ``(-0.2 * blocked + -1.0) + finish +
    -0.1 * backward`` (a term that does not apply is a signed zero, which
    changes nothing). float32 is what JAX computes in; this is the nearest
    float32 to the engine's reward, so the two differ by at most half a float32
    ulp (about 3e-8 relative), and are equal after rounding.
    """
    reward = COLLISION_PENALTY * blocked + TIMESTEP_PENALTY  # dt = 1 for discrete actions
    reward += finish
    reward += BACKWARD_PENALTY * backward
    return np.float32(reward)


#: Rewards of a step that does not reach the goal: a move, a move back into the
#: cell just left, a collision (the robot stays, so it is never a step back).
REWARD_MOVE = _engine_reward(0, 0)
REWARD_BACKWARD = _engine_reward(0, 1)
REWARD_COLLISION = _engine_reward(1, 0)


def _codes(per_cell: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of ``per_cell`` (one per cell) and each cell's index among them."""
    flat = per_cell.reshape(per_cell.shape[0], -1)
    _, first, codes = np.unique(flat, axis=0, return_index=True, return_inverse=True)
    return first, codes.reshape(-1).astype(np.int64)


def _maze_arrays(tables: MazeTables, m: int) -> dict[str, np.ndarray]:
    """The unpadded numpy arrays of maze ``m`` of ``tables`` (fields of :class:`MazeParams`)."""
    w, h = int(tables.width[m]), int(tables.height[m])
    offset, n = int(tables.cell_offset[m]), w * h
    cells = slice(offset, offset + n)
    if tables.robot.discrete_inputs:
        first, codes = _codes(tables.discrete_obs[cells, 0])
        observations = tables.discrete_obs[cells][first].reshape(-1, 8)
    else:
        first, codes = _codes(tables.tiles[cells])
        observations = tables.tiles[cells][first]
    local = tables.neighbours[cells].astype(np.int64)
    local = np.where(local < 0, -1, local - offset)
    positions = (np.arange(n, dtype=np.int64) << POSITION_SHIFT) | codes
    moves = np.where(local < 0, -1, positions[np.maximum(local, 0)])
    scheme = RewardScheme(int(tables.path_length[m]), tables.dt, tables.deadline_factor)
    return {
        "moves": moves.astype(np.int32),
        "observations": observations,
        "start": positions[int(tables.start[m]) - offset],
        "goal": positions[int(tables.end[m]) - offset],
        "deadline": int(np.ceil(tables.deadline[m])),
        "goal_reward": _engine_reward(0, 0, float(tables.finish[m])),
        "path_length": int(tables.path_length[m]),
        "min_reward": np.float32(scheme.minimal_reward),
        "width": w,
        "height": h,
    }


def _n_codes(observations: np.ndarray, robot: Robot) -> int:
    """How many observation codes an observation table holds (``DD``: 5 rows a code)."""
    if robot.discrete_inputs:
        return int(observations.shape[0]) // N_ARRIVALS
    return int(observations.shape[0])


def _default_codes(needed: int) -> int:
    """The smallest power of two at least ``needed`` and :data:`MIN_CODES`."""
    return max(MIN_CODES, 1 << max(needed - 1, 0).bit_length())


def _pad(arrays: dict[str, np.ndarray], robot: Robot, cells: int, codes: int) -> dict:
    """``arrays`` of one maze padded to ``cells`` rows of moves and ``codes`` codes."""
    moves = np.full((cells, 4), -1, dtype=np.int32)
    moves[: arrays["moves"].shape[0]] = arrays["moves"]
    table = np.asarray(arrays["observations"])
    rows = codes * (N_ARRIVALS if robot.discrete_inputs else 1)
    observations = np.zeros((rows, *table.shape[1:]), dtype=table.dtype)
    observations[: table.shape[0]] = table
    return {**arrays, "moves": moves, "observations": observations}


def _padded_sizes(
    sizes: Sequence[tuple[int, int]], max_cells: int | None, max_codes: int | None
) -> tuple[int, int]:
    """``(max_cells, max_codes)`` for mazes of ``(cells, codes)`` sizes, checked."""
    cells_needed = max(c for c, _ in sizes)
    codes_needed = max(k for _, k in sizes)
    if max_cells is None:
        max_cells = cells_needed
    max_cells = check_integer("max_cells", max_cells, minimum=1, error=OptionError)
    if max_cells < cells_needed or max_cells > MAX_CELLS:
        raise OptionError(
            f"max_cells {max_cells} must hold the largest maze ({cells_needed} cells)"
            f" and be at most {MAX_CELLS}"
        )
    if max_codes is None:
        max_codes = _default_codes(codes_needed)
    max_codes = check_integer("max_codes", max_codes, minimum=1, error=OptionError)
    if max_codes < codes_needed or max_codes > CODE_MASK + 1:
        raise OptionError(
            f"max_codes {max_codes} must hold the maze with the most distinct observations"
            f" ({codes_needed}) and be at most {CODE_MASK + 1}"
        )
    return max_cells, max_codes


def _stack(padded: Sequence[dict]) -> MazeParams:
    """One :class:`MazeParams` with a leading axis from padded per-maze arrays."""
    dtypes = {
        "moves": np.int32,
        "start": np.int32,
        "goal": np.int32,
        "deadline": np.int32,
        "goal_reward": np.float32,
        "path_length": np.int32,
        "min_reward": np.float32,
        "width": np.int32,
        "height": np.int32,
    }
    fields = {}
    for name in MazeParams._fields:
        column = np.stack([np.asarray(p[name]) for p in padded])
        fields[name] = jnp.asarray(column.astype(dtypes.get(name, column.dtype), copy=False))
    return MazeParams(**fields)


def compile_params(
    mazes: MazeLike | Sequence[MazeLike],
    robot: Robot | str = "DD",
    *,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
    max_cells: int | None = None,
    max_codes: int | None = None,
) -> MazeParams:
    """The params of ``mazes`` (mazes, specs or strings), stacked along a leading axis.

    One :func:`~amaze.agents.tables.compile_mazes` call builds the engine's
    tables of all mazes; each maze's part is then encoded (see the module) and
    padded to ``(max_cells, max_codes)``. Raises the project's errors for a bad
    maze string (:class:`~amaze.errors.MazeStringError`), robot
    (:class:`~amaze.agents.robot.RobotStringError`; continuous robots:
    :class:`~amaze.errors.OptionError`), deadline factor or padded size
    (:class:`~amaze.errors.OptionError`).
    """
    robot = supported_robot(robot)
    if not isinstance(mazes, Maze | MazeSpec | str) and not list(mazes):
        raise OptionError("mazes: give at least one maze")
    maze_list = as_mazes(mazes)
    for maze in maze_list:
        if maze.width * maze.height > MAX_CELLS:
            raise OptionError(f"maze {maze.to_string()} has more than {MAX_CELLS} cells")
    tables = compile_mazes(maze_list, robot, deadline_factor)
    arrays = [_maze_arrays(tables, m) for m in range(len(maze_list))]
    sizes = [(a["moves"].shape[0], _n_codes(a["observations"], robot)) for a in arrays]
    cells, codes = _padded_sizes(sizes, max_cells, max_codes)
    return _stack([_pad(a, robot, cells, codes) for a in arrays])


def padded_size(params: MazeParams) -> tuple[int, int]:
    """``(max_cells, max_codes)`` of params (one maze or a batch)."""
    cells = int(params.moves.shape[-2])
    table = params.observations
    if table.ndim - params.moves.ndim == 0:  # DD: (codes * 5, 8)
        return cells, int(table.shape[-2]) // N_ARRIVALS
    return cells, int(table.shape[-3])


def _robot_of(params: MazeParams) -> Robot:
    """The robot kind a params' observation table is for (``DD`` or ``H<v>``)."""
    table = params.observations
    if table.dtype == jnp.float32:
        return Robot()
    return Robot.from_string(f"H{int(table.shape[-1])}")


def stack_params(
    params: Sequence[MazeParams],
    *,
    max_cells: int | None = None,
    max_codes: int | None = None,
) -> MazeParams:
    """Pad params of one maze each (or batches) to one size and stack them, for ``vmap``.

    Each item is the params of one maze (from :func:`~amaze.envs.jax.make`) or a
    batch (leading axis); the result concatenates them in order, padded to
    ``(max_cells, max_codes)`` (by default the largest of the items). Params of
    different robots cannot be stacked (:class:`~amaze.errors.OptionError`).
    """
    items = list(params)
    if not items:
        raise OptionError("stack_params: give at least one params")
    robots = {_robot_of(p) for p in items}
    if len(robots) > 1:
        names = sorted(r.to_string() for r in robots)
        raise OptionError(f"stack_params: params of different robots {names} cannot be stacked")
    robot = robots.pop()
    rows = []
    for item in items:
        host = {name: np.asarray(value) for name, value in item._asdict().items()}
        if host["moves"].ndim == 2:
            rows.append(host)
        else:
            rows.extend({k: v[b] for k, v in host.items()} for b in range(host["moves"].shape[0]))
    sizes = [padded_size(MazeParams(**row)) for row in rows]
    cells, codes = _padded_sizes(sizes, max_cells, max_codes)
    return _stack([_pad(row, robot, cells, codes) for row in rows])


def tile_params(params: Any, num_envs: int | None) -> Any:
    """Params of ``num_envs`` environments from a batch of ``M`` mazes: env ``k`` gets maze
    ``k % M`` (``None``: one environment per maze). Any params NamedTuple with a leading axis."""
    n_mazes = int(params.start.shape[0])
    if num_envs is None:
        return params
    num_envs = check_integer("num_envs", num_envs, minimum=1, error=OptionError)
    if num_envs == n_mazes:
        return params
    index = jnp.arange(num_envs) % n_mazes
    return type(params)(*(value[index] for value in params))


def unstack(params: MazeParams) -> MazeParams:
    """The params of one maze from a batch of one (the leading axis dropped)."""
    return MazeParams(*(value[0] for value in params))
