"""Continuous robots (``CC5`` ... ``CC65``) as a functional JAX environment.

:class:`JaxContinuousEnv` is to continuous robots what
:class:`~amaze.envs.jax.env.JaxMazeEnv` is to discrete actions: stateless,
gymnax 1.0's ``reset(key, params)`` and ``step(key, state, action, params)``
with auto-reset, every method a pure function of arrays (jit, ``vmap`` over
environments, ``scan`` over steps), no random draw. An action is an
acceleration ``(ax, ay)``, each clipped to [-1, 1] (0 if not finite: JAX cannot
refuse it inside a compiled step); the observation is the ``v x v`` uint8
window centred on the robot (``(1, v, v)``, channel first, as AMaze-v0), with
the origin marker.

Semantics are the batch engine's continuous mode (``amaze.agents.engine``:
``_continuous_move``, ``_continuous_step``, ``_observe_window``; reference
§4.4, §4.5, §5.3), written as the same operations in the same order: the
velocity damped and accelerated, zeroed below the minimal speed, the robot
moved, pushed out of the walls it overlaps and off the wall ends at its
corners (a push is a collision), its cell and previous cell updated (going
back into the previous cell is a backward step), rewards summed in the
engine's order; the goal terminates, ``ceil(deadline)`` steps truncate.

**Floats.** ``dtype`` is the environment's float type. With ``float64``
(``jax.config.update("jax_enable_x64", True)`` first) every step is the
engine's to the bit once XLA's CPU code is kept from fusing a multiply and
an add into one fused multiply-add (``XLA_FLAGS=--xla_cpu_max_isa=AVX`` on
x86: numba rounds the two apart); without that, positions differed from the
engine's by up to 4e-13 over the test's episodes.
``tests/amaze/envs/test_jax_continuous.py`` checks positions, velocities,
rewards and observations over whole episodes that way. With
``float32`` (the default, what learners compute in) positions carry float32
rounding, so a robot grazing a wall may collide in one and not in the other
and trajectories part after a while; agents are scored by the engine (the
evaluation protocol) whatever they trained in. The episode figures of
``info`` come from exact integer counters, as the discrete environment's.

**Params** (:class:`ContinuousParams`): one maze's walls and its rendered
canvas (:func:`amaze.agents.tables.maze_canvas`: the maze drawn at ``v``
pixels a cell with a ``v``-pixel ring, the window's source), padded to the
largest maze of a batch (:func:`compile_continuous_params`); a jitted
function called with params of the same padded size never recompiles.

**Progress reward** (``progress_reward``, default 0: AMaze's reward
alone). A continuous robot far from its goal seldom reaches it by chance, and
standing still is a local optimum of AMaze's rewards. With
``progress_reward = k``, each step that takes the robot into a cell of its
maze's solution further along than any it stood in before adds ``k`` times the
share of the solution gained times the maze's finish reward: an episode gains
``k`` times its path progress (the furthest solution cell reached, as a share
of the path: 1 on success; the quantity
:func:`amaze.evaluation.policy.run_episodes` records and evolution can take as
fitness) times the finish reward, so that a cell gained is worth more than the
time spent driving through it (the finish reward is about ``2 (l - 1)``, a
step costs 0.1) whatever the maze's size. Going back and forth gains nothing. The
episode figures of ``info`` stay the paper's (``path_progress`` is added).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from amaze.agents.rewards import (
    BACKWARD_PENALTY,
    COLLISION_PENALTY,
    DEFAULT_DEADLINE_FACTOR,
    PAPER_BACKWARD,
    PAPER_COLLISION,
    PAPER_FINISH,
    RewardScheme,
)
from amaze.agents.robot import (
    ACCELERATION_SCALE,
    CONTINUOUS_DT,
    INERTIAL_LOSS,
    MIN_SPEED,
    RADIUS,
    Robot,
    as_robot,
    robot_name,
)
from amaze.agents.tables import WHITE, compile_mazes, marker_pixel
from amaze.envs.jax.env import AutoResetSteps, Box
from amaze.envs.jax.params import tile_params
from amaze.errors import OptionError
from amaze.maze.maze import Maze, as_mazes
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer, check_number

__all__ = [
    "ContinuousParams",
    "ContinuousState",
    "JaxContinuousEnv",
    "compile_continuous_params",
    "make_continuous",
]

_DAMPING = 1 - INERTIAL_LOSS * CONTINUOUS_DT
_SQRT2 = float(np.sqrt(2.0))
#: The largest maze side: a canvas of (side + 2) v pixels a side stays under 2^31.
MAX_SIDE = 1000


class ContinuousParams(NamedTuple):
    """The tables of one maze, or of a batch with a leading axis (see the module).

    ``walls`` int32 ``(max_w * max_h,)``: bit ``d`` set when side ``d`` (E, N, W,
    S) of cell ``i * height + j`` is a wall; ``canvas`` uint8
    ``((max_h + 2) v, (max_w + 2) v)``: the maze drawn with its ring, top-left
    aligned; ``start``, ``goal``: int32 ``(2,)`` cells ``(i, j)``; ``deadline``:
    steps; ``finish``: the reward added on reaching the goal; ``path_length``
    (``l``); ``min_reward``: the reference's worst return (``pretty_reward``);
    ``width``, ``height``; ``path_position`` float ``(max_w * max_h,)``: cell
    ``i * height + j``'s place on the solution, ``k / (l - 1)`` for its ``k``-th
    cell, -1 off it (:meth:`amaze.maze.maze.Maze.path_positions`).
    """

    walls: jax.Array
    canvas: jax.Array
    start: jax.Array
    goal: jax.Array
    deadline: jax.Array
    finish: jax.Array
    path_length: jax.Array
    min_reward: jax.Array
    width: jax.Array
    height: jax.Array
    path_position: jax.Array


class ContinuousState(NamedTuple):
    """One robot's episode: scalars (with a leading axis under ``vmap``).

    ``x``, ``y``: position (cell ``(i, j)`` covers ``[i, i + 1) x [j, j + 1)``);
    ``vx``, ``vy``: velocity; ``ci``, ``cj``: the cell it is in; ``pi``,
    ``pj``: the cell it was in before (its start cell at first); ``time``,
    ``collisions``, ``backsteps``: the episode's counters; ``progress``: the
    furthest solution cell it stood in, as a share of the path (0 at the start).
    """

    x: jax.Array
    y: jax.Array
    vx: jax.Array
    vy: jax.Array
    ci: jax.Array
    cj: jax.Array
    pi: jax.Array
    pj: jax.Array
    time: jax.Array
    collisions: jax.Array
    backsteps: jax.Array
    progress: jax.Array


def continuous_robot(robot: Robot | str) -> Robot:
    """``robot`` as a :class:`Robot` with continuous actions, else :class:`OptionError`."""
    parsed = as_robot(robot)
    if parsed.discrete_outputs:
        raise OptionError(
            f"robot {robot_name(robot)}: JaxContinuousEnv runs robots with continuous actions"
            " (CC5 ... CC65); robots with discrete actions run in JaxMazeEnv"
        )
    return parsed


def _cell_index(x: jax.Array, n: jax.Array) -> jax.Array:
    """``int(x)`` clamped to ``0 .. n - 1`` (0 for NaN), as the engine's ``_cell_index``."""
    return jnp.where(x >= n, n - 1, jnp.where(x >= 1.0, x.astype(jnp.int32), 0))


def _window_shift(f: jax.Array, v: int) -> jax.Array:
    """``int(f)`` clamped to ``[-v, v]`` (0 for NaN), as the engine's ``_window_shift``."""
    inside = jnp.where(f > -v, f.astype(jnp.int32), jnp.where(f <= -v, -v, 0))
    return jnp.where(f >= v, v, inside)


def _arrival_side(ci: jax.Array, cj: jax.Array, pi: jax.Array, pj: jax.Array) -> jax.Array:
    """Side (0..3) of the cell leading back to the previous cell, -1 if none."""
    dx, dy = pi - ci, pj - cj
    side = jnp.where(dx == 1, 0, jnp.where(dx == -1, 2, -1))
    side = jnp.where(dy == 0, side, -1)
    side_y = jnp.where(dy == 1, 1, jnp.where(dy == -1, 3, -1))
    return jnp.where(dx == 0, side_y, side)


@dataclass(frozen=True)
class JaxContinuousEnv(AutoResetSteps):
    """AMaze for one continuous robot, as a functional JAX environment (see the module).

    ``step`` and ``step_env`` are :class:`~amaze.envs.jax.env.AutoResetSteps`'s:
    ``info`` holds the ending step's ``final_observation``, ``terminated``,
    ``truncated`` and the figures of :meth:`episode_info`.

    ``progress_reward``: the reward for reaching further along the solution (see
    the module; 0, the default, is AMaze's reward alone). Equal robots, dtypes
    and progress rewards give equal (and equally hashed) environments, so jitted
    functions taking the env as a static argument compile once.
    """

    robot: Robot
    dtype: Any
    progress_reward: float

    def __init__(
        self, robot: Robot | str = "CC15", dtype: Any = jnp.float32, progress_reward: float = 0.0
    ) -> None:
        object.__setattr__(self, "robot", continuous_robot(robot))
        reward = check_number("progress_reward", progress_reward, minimum=0.0, error=OptionError)
        object.__setattr__(self, "progress_reward", reward)
        kind = jnp.dtype(dtype)
        if kind not in (jnp.dtype(jnp.float32), jnp.dtype(jnp.float64)):
            raise OptionError(f"dtype {dtype!r}: give float32 or float64")
        if kind == jnp.float64 and not jax.config.read("jax_enable_x64"):
            raise OptionError(
                "dtype float64 needs JAX's 64-bit mode:"
                ' jax.config.update("jax_enable_x64", True) first'
            )
        object.__setattr__(self, "dtype", kind)

    # -- description ------------------------------------------------------------

    @property
    def name(self) -> str:
        return f"AMaze-{self.robot.to_string()}"

    @property
    def observation_shape(self) -> tuple[int, ...]:
        """``(1, v, v)``: the window, channel first, as AMaze-v0."""
        return (1, self.robot.vision, self.robot.vision)

    def action_space(self, params: ContinuousParams | None = None) -> Box:
        """``Box(-1, 1, (2,))``: the acceleration (x east, y north)."""
        return Box(-1.0, 1.0, (2,), self.dtype)

    def observation_space(self, params: ContinuousParams | None = None) -> Box:
        """``Box(0, 255, (1, v, v), uint8)``."""
        return Box(0.0, 255.0, self.observation_shape, jnp.uint8)

    def check_params(self, params: ContinuousParams) -> None:
        """Refuse a batch of params or params of another vision (shapes only: at trace time)."""
        if params.walls.ndim != 1:
            raise OptionError(
                f"params of {params.walls.shape[0]} mazes (walls {list(params.walls.shape)}):"
                " a batch is stepped with jax.vmap(env.step), one maze per environment"
            )
        v = self.robot.vision
        rows, cols = params.canvas.shape
        side = math.isqrt(params.walls.shape[0])  # walls: max_side x max_side cells
        if rows != (side + 2) * v or cols != rows or params.canvas.dtype != jnp.uint8:
            raise OptionError(
                f"params with a canvas {params.canvas.dtype}{[rows, cols]} are not made for"
                f" robot {self.robot}: make them with the same robot"
            )

    # -- the functional API ---------------------------------------------------------

    def initial_state(self, params: ContinuousParams) -> ContinuousState:
        """The robot at the centre of the start cell, at rest."""
        self.check_params(params)
        i, j = params.start[..., 0], params.start[..., 1]
        half = jnp.asarray(0.5, self.dtype)
        zero_f = jnp.zeros_like(half)
        zero = jnp.zeros_like(i)
        return ContinuousState(
            i.astype(self.dtype) + half, j.astype(self.dtype) + half, zero_f, zero_f,
            i, j, i, j, zero, zero, zero, zero_f,
        )  # fmt: skip

    @partial(jax.jit, static_argnums=0)
    def reset(self, key: jax.Array, params: ContinuousParams) -> tuple[jax.Array, ContinuousState]:
        """The first observation and state of an episode (``key`` is not used)."""
        del key
        state = self.initial_state(params)
        return self.observe(state, params), state

    def observe(self, state: ContinuousState, params: ContinuousParams) -> jax.Array:
        """uint8 ``(1, v, v)``: the window on the canvas, shifted with the robot in its cell."""
        v = self.robot.vision
        ci = _cell_index(state.x, params.width)
        cj = _cell_index(state.y, params.height)
        dpx = _window_shift((state.x - ci - 0.5) * v, v)
        dpy = _window_shift((state.y - cj - 0.5) * v, v)
        r0 = (params.height - cj) * v - dpy
        c0 = (ci + 1) * v + dpx
        window = jax.lax.dynamic_slice(params.canvas, (r0, c0), (v, v))
        side = _arrival_side(ci, cj, state.pi, state.pj)
        markers = np.array([marker_pixel(s, v) for s in range(4)], dtype=np.int32)
        mr, mc = jnp.asarray(markers)[jnp.maximum(side, 0)].T
        r, c = mr + dpy, mc - dpx
        shown = (side >= 0) & (r >= 0) & (r < v) & (c >= 0) & (c < v)
        rc, cc = jnp.clip(r, 0, v - 1), jnp.clip(c, 0, v - 1)
        window = window.at[rc, cc].set(jnp.where(shown, jnp.uint8(WHITE), window[rc, cc]))
        return window[None]

    def _wall(self, params: ContinuousParams, i: jax.Array, j: jax.Array, d: int) -> jax.Array:
        cell = jnp.clip(i * params.height + j, 0, params.walls.shape[-1] - 1)
        return ((params.walls[cell] >> d) & 1) == 1

    def move(
        self, state: ContinuousState, action: jax.Array, params: ContinuousParams
    ) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array, jax.Array]:
        """The physics of one step (§4.4): ``(x, y, vx, vy, collided)`` (the engine's
        ``_continuous_move``)."""
        f = self.dtype
        a = jnp.asarray(action, f)
        a = jnp.clip(jnp.where(jnp.isfinite(a), a, 0.0), -1.0, 1.0)
        dt = jnp.asarray(CONTINUOUS_DT, f)
        vx = _DAMPING * state.vx + dt * (ACCELERATION_SCALE * a[..., 0])
        vy = _DAMPING * state.vy + dt * (ACCELERATION_SCALE * a[..., 1])
        still = jnp.sqrt(vx**2 + vy**2) < MIN_SPEED
        vx = jnp.where(still, 0.0, vx).astype(f)
        vy = jnp.where(still, 0.0, vy).astype(f)
        x = state.x + dt * vx
        y = state.y + dt * vy
        w, h = params.width, params.height
        i, j = _cell_index(x, w), _cell_index(y, h)
        fi, fj = i.astype(f), j.astype(f)
        r = RADIUS
        o_w, o_e = x - fi <= r, fi + 1 - x <= r
        o_s, o_n = y - fj <= r, fj + 1 - y <= r
        wall = partial(self._wall, params)
        x_ = jnp.where(
            o_w & wall(i, j, 2), fi + r, jnp.where(~o_w & o_e & wall(i, j, 0), fi + 1 - r, x)
        )
        y_ = jnp.where(
            o_s & wall(i, j, 3), fj + r, jnp.where(~o_s & o_n & wall(i, j, 1), fj + 1 - r, y)
        )
        # the wall ends at the corner the robot overlaps (the first that applies, as the
        # engine's elif chain)
        cases = [
            (o_w & o_s & (i > 0) & (j > 0), wall(i - 1, j, 3) | wall(i, j - 1, 2), 0, 0),
            (o_w & o_n & (i > 0) & (j < h - 1), wall(i - 1, j, 1) | wall(i, j + 1, 2), 0, 1),
            (o_e & o_s & (i < w - 1) & (j > 0), wall(i + 1, j, 3) | wall(i, j - 1, 0), 1, 0),
            (o_e & o_n & (i < w - 1) & (j < h - 1), wall(i + 1, j, 1) | wall(i, j + 1, 0), 1, 1),
        ]
        corner = jnp.zeros_like(o_w)
        cx, cy = jnp.zeros_like(x), jnp.zeros_like(y)
        taken = jnp.zeros_like(o_w)
        for applies, walled, di, dj in cases:
            first = applies & ~taken
            corner = jnp.where(first, walled, corner)
            cx = jnp.where(first, fi + di, cx)
            cy = jnp.where(first, fj + dj, cy)
            taken = taken | applies
        dvx, dvy = cx - x, cy - y
        d = jnp.sqrt(dvx**2 + dvy**2)
        pen = r - d
        safe = jnp.where(d > 0.0, d, 1.0)
        ux = jnp.where(d > 0.0, dvx / safe, (cx - fi - 0.5) * _SQRT2)
        uy = jnp.where(d > 0.0, dvy / safe, (cy - fj - 0.5) * _SQRT2)
        pushed = corner & (d < r)
        x_ = jnp.where(pushed, x_ - ux * pen, x_)
        y_ = jnp.where(pushed, y_ - uy * pen, y_)
        return x_, y_, vx, vy, (x != x_) | (y != y_)

    def transition(
        self, state: ContinuousState, action: jax.Array, params: ContinuousParams
    ) -> tuple[ContinuousState, jax.Array, jax.Array, jax.Array]:
        """One step without restart: the new state, reward, terminated and truncated."""
        f = self.dtype
        x, y, vx, vy, collided = self.move(state, action, params)
        ni, nj = _cell_index(x, params.width), _cell_index(y, params.height)
        moved = (ni != state.ci) | (nj != state.cj)
        pi = jnp.where(moved, state.ci, state.pi)
        pj = jnp.where(moved, state.cj, state.pj)
        success = (ni == params.goal[..., 0]) & (nj == params.goal[..., 1])
        backward = ((state.pi != pi) | (state.pj != pj)) & (state.pi == ni) & (state.pj == nj)
        zero = jnp.zeros((), f)
        reward = zero + jnp.where(collided, jnp.asarray(COLLISION_PENALTY, f), zero)
        reward = reward + jnp.asarray(-CONTINUOUS_DT, f)
        finish = success | (state.time >= params.deadline)
        reward = reward + jnp.where(finish, params.finish.astype(f), zero)
        reward = reward + jnp.where(backward, jnp.asarray(BACKWARD_PENALTY, f), zero)
        position = params.path_position[ni * params.height + nj].astype(f)
        progress = jnp.maximum(state.progress, position)
        if self.progress_reward:
            gain = params.finish.astype(f) * (progress - state.progress)
            reward = reward + jnp.asarray(self.progress_reward, f) * gain
        time = state.time + 1
        new = ContinuousState(
            x, y, vx, vy, ni, nj, pi, pj, time,
            state.collisions + collided.astype(jnp.int32),
            state.backsteps + backward.astype(jnp.int32), progress,
        )  # fmt: skip
        return new, reward, success, time >= params.deadline

    def episode_info(
        self, state: ContinuousState, terminated: jax.Array, params: ContinuousParams
    ) -> dict[str, jax.Array]:
        """The episode figures of ``state`` (after its last step), from its counters.

        The return is ``-dt t - 0.2 c - 0.1 b`` plus the finish reward on
        success, R̄ the paper's ``2 s - dt t / (l - 1) - 0.01 c - 0.02 b``,
        ``pretty_reward`` the reference's rescale of the return to [-1, 1],
        rounded to 3 decimals; each computed once in ``dtype`` (the engine sums
        the return step by step in float64, so they agree to rounding). The return
        is the paper's, without the progress reward; ``path_progress`` is the
        furthest share of the solution reached (1 on success).
        """
        f = self.dtype
        steps, c, b = (v.astype(f) for v in (state.time, state.collisions, state.backsteps))
        success = terminated.astype(f)
        length = params.path_length.astype(f)
        ret = (
            -CONTINUOUS_DT * steps + COLLISION_PENALTY * c + BACKWARD_PENALTY * b
            + params.finish.astype(f) * success
        )  # fmt: skip
        normalized = (
            PAPER_FINISH * success - CONTINUOUS_DT * steps / (length - 1)
            + PAPER_COLLISION * c + PAPER_BACKWARD * b
        )  # fmt: skip
        r_min = params.min_reward.astype(f)
        pretty = jnp.round((2.0 * (ret - r_min) / (length - r_min) - 1.0) * 1000) / 1000
        return {
            "success": terminated,
            "steps": state.time,
            "collisions": state.collisions,
            "backsteps": state.backsteps,
            "len": params.path_length,
            "cumulative_reward": ret,
            "pretty_reward": pretty,
            "normalized_reward": normalized,
            "path_progress": state.progress,
        }


def compile_continuous_params(
    mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str],
    robot: Robot | str = "CC15",
    *,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
    max_side: int | None = None,
    dtype: Any = jnp.float32,
) -> ContinuousParams:
    """The params of ``mazes``, padded to ``max_side`` cells a side and stacked.

    ``max_side`` (default: the largest side of the mazes) keeps one shape
    across batches, so that a jitted step does not recompile. Raises
    :class:`~amaze.errors.OptionError` for a robot with discrete actions, no
    maze, or a ``max_side`` too small for a maze.
    """
    robot = continuous_robot(robot)
    if not isinstance(mazes, Maze | MazeSpec | str) and not list(mazes):
        raise OptionError("mazes: give at least one maze")
    maze_list = as_mazes(mazes)
    needed = max(max(m.width, m.height) for m in maze_list)
    side = needed if max_side is None else max_side
    side = check_integer("max_side", side, minimum=1, maximum=MAX_SIDE, error=OptionError)
    if side < needed:
        raise OptionError(f"max_side {side} must hold the largest maze ({needed} cells a side)")
    tables = compile_mazes(maze_list, robot, deadline_factor)
    v = int(robot.vision)
    rows = []
    for m, maze in enumerate(maze_list):
        w, h = maze.width, maze.height
        walls = np.zeros(side * side, dtype=np.int32)
        offset = int(tables.cell_offset[m])
        walls[: w * h] = tables.walls[offset : offset + w * h]
        canvas = np.zeros(((side + 2) * v, (side + 2) * v), dtype=np.uint8)
        start = int(tables.canvas_offset[m])
        drawn = tables.canvas[start : start + (h + 2) * v * (w + 2) * v]
        canvas[: (h + 2) * v, : (w + 2) * v] = drawn.reshape((h + 2) * v, (w + 2) * v)
        length = int(tables.path_length[m])
        scheme = RewardScheme(length, CONTINUOUS_DT, deadline_factor)
        position = np.full(side * side, -1.0, dtype=dtype)
        position[: w * h] = maze.path_positions()
        rows.append({
            "walls": walls, "canvas": canvas,
            "start": tables.start_ij[m].astype(np.int32), "goal": tables.end_ij[m].astype(np.int32),
            "deadline": np.int32(np.ceil(tables.deadline[m])),
            "finish": np.asarray(tables.finish[m], dtype=dtype),
            "path_length": np.int32(length),
            "min_reward": np.asarray(scheme.minimal_reward, dtype=dtype),
            "width": np.int32(w), "height": np.int32(h), "path_position": position,
        })  # fmt: skip
    return ContinuousParams(
        **{
            name: jnp.asarray(np.stack([r[name] for r in rows]))
            for name in ContinuousParams._fields
        }
    )


def make_continuous(
    mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str],
    robot: Robot | str = "CC15",
    *,
    num_envs: int | None = None,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
    max_side: int | None = None,
    dtype: Any = jnp.float32,
    progress_reward: float = 0.0,
) -> tuple[JaxContinuousEnv, ContinuousParams]:
    """``(env, params)`` of ``num_envs`` environments (default: one per maze), for ``vmap``.

    Environment ``k`` plays maze ``k % len(mazes)``; the params have a leading
    axis. Index them (``jax.tree.map(lambda a: a[0], params)``) for one maze.
    ``progress_reward``: see :class:`JaxContinuousEnv`.
    """
    env = JaxContinuousEnv(robot, dtype, progress_reward)
    params = compile_continuous_params(
        mazes, env.robot, deadline_factor=deadline_factor, max_side=max_side, dtype=env.dtype
    )
    return env, tile_params(params, num_envs)
