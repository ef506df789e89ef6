"""The functional AMaze environment in JAX: gymnax 1.0's interface, the engine's episodes.

:class:`JaxMazeEnv` is stateless: ``reset(key, params) -> (obs, state)`` and
``step(key, state, action, params) -> (obs, state, reward, terminated,
truncated, info)``, with the maze in ``params``
(:class:`~amaze.envs.jax.params.MazeParams`) and the robot in the env. Every
method is a pure function of arrays, with no Python control flow on traced
values, so it can be jitted, vmapped over environments (and over params, one
maze per environment) and scanned over steps. The environment draws no random
number: keys are taken for the interface and ignored. A step is a few table
look-ups (:mod:`amaze.envs.jax.params`) and int32 arithmetic on the state
(:class:`MazeState`).

Semantics are the batch engine's (``amaze.agents.engine``; reference §4.3-4.6,
§5.1-5.2): a move into a wall is a collision (the robot stays); moving back
into the cell just left is a backward step; the episode terminates at the goal
and is truncated after ``ceil(deadline_factor * l)`` steps (both can hold);
rewards are the reference's per-step rewards; actions are 0..3 (E, N, W, S).
JAX cannot raise inside a compiled step, so an action outside 0..3 is taken
modulo 4 (its two low bits) instead of being refused.

``step`` restarts an ended episode in the same step, as gymnax does: the
observation returned is the new episode's first, and ``info`` holds the ending
step's figures, valid where ``terminated | truncated``:
``final_observation``, ``terminated``, ``truncated``, and the episode
statistics of the engine's ``EndedEpisodes`` and the vector env's
``final_info``: ``success``, ``steps``, ``collisions``, ``backsteps``, ``len``
(``l``), ``cumulative_reward``, ``pretty_reward`` and ``normalized_reward``
(the paper's R̄). ``step_env`` is the same step without the restart.

Floats are float32 (the engine's are float64): rewards are the float32 nearest
the engine's; the episode counters are exact integers, and the return and R̄
are computed from them as exact rationals rounded once, so they agree with the
engine's (which carry float64 rounding errors) within one float32 ulp of its
value; ``pretty_reward`` (rounded to 3 decimals) is the engine's but at
near-ties of that rounding, where it may differ by 0.001. These bounds are
checked on hundreds of mazes by ``tests/amaze/envs/test_jax_vs_engine.py``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cache, partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from amaze.agents.rewards import BACKWARD_PENALTY, COLLISION_PENALTY, PAPER_BACKWARD
from amaze.agents.robot import Robot
from amaze.agents.tables import N_ARRIVALS, WHITE, marker_pixel
from amaze.envs.jax.params import (
    CODE_MASK,
    POSITION_SHIFT,
    REWARD_BACKWARD,
    REWARD_COLLISION,
    REWARD_MOVE,
    MazeParams,
    supported_robot,
)
from amaze.errors import OptionError

# Integer forms of the reward constants, for exact returns and R̄ from counters:
# tenths of the per-step rewards (time -1, collision -0.2, backward -0.1) and
# hundredths of R̄'s penalties (-0.01 per collision, -0.02 per backward step).
_COLLISION_TENTHS = round(-COLLISION_PENALTY * 10)
_BACKWARD_TENTHS = round(-BACKWARD_PENALTY * 10)
_BACKWARD_HUNDREDTHS = round(-PAPER_BACKWARD * 100)


class MazeState(NamedTuple):
    """One robot's episode: int32 scalars (arrays with a leading axis under ``vmap``).

    ``position``: ``cell << 16 | code`` (see :mod:`amaze.envs.jax.params`);
    ``arrival``: 0 at the start, else ``1 +`` the side leading back to the
    previous cell; ``time``: steps taken; ``collisions``, ``backsteps``: the
    episode's counters.
    """

    position: jax.Array
    arrival: jax.Array
    time: jax.Array
    collisions: jax.Array
    backsteps: jax.Array


def _divide(numerator: jax.Array, denominator: jax.Array | float) -> jax.Array:
    """``numerator / denominator``, correctly rounded, whatever the shapes.

    XLA rewrites a division by a constant or by one scalar broadcast over a batch
    (shared params under ``vmap``) into a multiplication by its reciprocal,
    which can be off by an ulp. Adding ``0 * numerator`` makes the divisor an
    elementwise value that XLA cannot see through (it does not simplify
    ``0 * x`` for floats, because of NaN and infinities), so the division stays
    an IEEE division; the value of the divisor is unchanged.
    """
    return numerator / (denominator + 0 * numerator)


@dataclass(frozen=True)
class Discrete:
    """gymnax's ``Discrete`` space, without gymnax: ``n`` int32 actions ``0 .. n - 1``."""

    n: int
    shape: tuple[int, ...] = ()
    dtype: Any = jnp.int32

    def sample(self, key: jax.Array) -> jax.Array:
        return jax.random.randint(key, self.shape, 0, self.n, dtype=self.dtype)

    def contains(self, x: jax.Array) -> jax.Array:
        return (x >= 0) & (x < self.n)


@dataclass(frozen=True)
class Box:
    """gymnax's ``Box`` space, without gymnax: arrays of ``shape`` and ``dtype`` in [low, high]."""

    low: float
    high: float
    shape: tuple[int, ...]
    dtype: Any

    def sample(self, key: jax.Array) -> jax.Array:
        values = jax.random.uniform(key, self.shape, minval=self.low, maxval=self.high)
        return values.astype(self.dtype)

    def contains(self, x: jax.Array) -> jax.Array:
        return jnp.all((x >= self.low) & (x <= self.high))


@cache
def _marker_pixels(vision: int) -> np.ndarray:
    """int32 ``(5,)``: the flat index of the origin marker per arrival code (0: none, unused)."""
    pixels = [0] + [r * vision + c for r, c in (marker_pixel(side, vision) for side in range(4))]
    return np.array(pixels, dtype=np.int32)


class AutoResetSteps:
    """gymnax's ``step_env`` and ``step`` (auto-reset) of a functional environment.

    A subclass (a frozen dataclass, so that jit can hash it) defines
    ``check_params``, ``initial_state(params)``, ``observe(state, params)``,
    ``transition(state, action, params) -> (state, reward, terminated,
    truncated)`` and ``episode_info(state, terminated, params)``.
    """

    @partial(jax.jit, static_argnums=0)
    def step_env(
        self, key: jax.Array, state: Any, action: jax.Array, params: Any
    ) -> tuple[jax.Array, Any, jax.Array, jax.Array, jax.Array, dict[str, Any]]:
        """One step without restart (``key`` is not used); ``info`` as in :meth:`step`."""
        del key
        self.check_params(params)
        new, reward, terminated, truncated = self.transition(state, action, params)
        obs = self.observe(new, params)
        info = self.episode_info(new, terminated, params)
        info.update(terminated=terminated, truncated=truncated, final_observation=obs)
        return obs, new, reward, terminated, truncated, info

    @partial(jax.jit, static_argnums=0)
    def step(
        self, key: jax.Array, state: Any, action: jax.Array, params: Any
    ) -> tuple[jax.Array, Any, jax.Array, jax.Array, jax.Array, dict[str, Any]]:
        """One step, restarting an ended episode in the same step (gymnax's auto-reset).

        Returns ``(obs, state, reward, terminated, truncated, info)``; after an
        ending step, ``obs`` and ``state`` are the new episode's first, and
        ``info`` holds the ending step's ``final_observation``, ``terminated``,
        ``truncated`` and episode figures (the subclass's ``episode_info``).
        ``key`` is not used: the environment is deterministic.
        """
        del key
        self.check_params(params)
        ended, reward, terminated, truncated = self.transition(state, action, params)
        done = terminated | truncated
        fresh = self.initial_state(params)
        state = jax.tree.map(lambda new, old: jnp.where(done, new, old), fresh, ended)
        info = self.episode_info(ended, terminated, params)
        info.update(
            terminated=terminated,
            truncated=truncated,
            final_observation=self.observe(ended, params),
        )
        return self.observe(state, params), state, reward, terminated, truncated, info


@dataclass(frozen=True)
class JaxMazeEnv(AutoResetSteps):
    """AMaze for one robot with discrete actions, as a functional JAX environment.

    Made by :func:`~amaze.envs.jax.make` or :func:`~amaze.envs.jax.make_batch`
    with its params; ``JaxMazeEnv("H15")`` works too. Equal robots give equal
    (and equally hashed) environments, so jitted functions taking the env as a
    static argument compile once per robot.
    """

    robot: Robot

    def __init__(self, robot: Robot | str = "DD") -> None:
        object.__setattr__(self, "robot", supported_robot(robot))

    # -- description ------------------------------------------------------------

    @property
    def name(self) -> str:
        return f"AMaze-{self.robot.to_string()}"

    @property
    def num_actions(self) -> int:
        """Four moves: E, N, W, S."""
        return 4

    @property
    def observation_shape(self) -> tuple[int, ...]:
        """``(8,)`` for ``DD``, ``(1, v, v)`` images (channel first) otherwise, as AMaze-v0."""
        if self.robot.discrete_inputs:
            return (8,)
        return (1, self.robot.vision, self.robot.vision)

    @property
    def observation_dtype(self) -> jnp.dtype:
        return jnp.dtype(jnp.float32 if self.robot.discrete_inputs else jnp.uint8)

    def action_space(self, params: MazeParams | None = None) -> Discrete:
        """``Discrete(4)``: E, N, W, S (the same for every maze)."""
        return Discrete(4)

    def observation_space(self, params: MazeParams | None = None) -> Box:
        """AMaze-v0's: ``Box(-1, 1, (8,), float32)`` or ``Box(0, 255, (1, v, v), uint8)``."""
        high = 1.0 if self.robot.discrete_inputs else 255.0
        low = -1.0 if self.robot.discrete_inputs else 0.0
        return Box(low, high, self.observation_shape, self.observation_dtype)

    def check_params(self, params: MazeParams) -> None:
        """Refuse a batch of params, or params made for another robot (:class:`OptionError`).

        Only shapes and dtypes are read: it runs while tracing, so a mismatch is
        reported once, before anything runs.
        """
        if params.moves.ndim != 2:
            raise OptionError(
                f"params of {params.moves.shape[0]} mazes (moves {list(params.moves.shape)}):"
                " a batch is stepped with jax.vmap(env.step), one maze per environment"
            )
        table = params.observations
        if self.robot.discrete_inputs:
            fits = table.dtype == jnp.float32 and table.shape[-1] == 8
        else:
            v = self.robot.vision
            fits = table.dtype == jnp.uint8 and tuple(table.shape[-2:]) == (v, v)
        if not fits:
            raise OptionError(
                f"params with observations {table.dtype}{list(table.shape)} are not made for"
                f" robot {self.robot}: make them with the same robot"
            )

    # -- the functional API ---------------------------------------------------------

    @partial(jax.jit, static_argnums=0)
    def reset(self, key: jax.Array, params: MazeParams) -> tuple[jax.Array, MazeState]:
        """The first observation and state of an episode (``key`` is not used)."""
        del key
        state = self.initial_state(params)
        return self.observe(state, params), state

    def initial_state(self, params: MazeParams) -> MazeState:
        """The state at the start of an episode."""
        self.check_params(params)
        zero = jnp.zeros_like(params.start)
        return MazeState(params.start, zero, zero, zero, zero)

    def observe(self, state: MazeState, params: MazeParams) -> jax.Array:
        """The observation of a state: float32 ``(8,)`` or uint8 ``(1, v, v)``."""
        code = state.position & CODE_MASK
        if self.robot.discrete_inputs:
            return params.observations[code * N_ARRIVALS + state.arrival]
        v = self.robot.vision
        tile = params.observations[code].reshape(v * v)
        # the origin marker: one pixel written (with its own value at the start),
        # cheaper than a second v x v image combined with the tile
        pixel = jnp.asarray(_marker_pixels(v))[state.arrival]
        value = jnp.where(state.arrival > 0, jnp.uint8(WHITE), tile[pixel])
        return tile.at[pixel].set(value).reshape(1, v, v)

    def transition(
        self, state: MazeState, action: jax.Array, params: MazeParams
    ) -> tuple[MazeState, jax.Array, jax.Array, jax.Array]:
        """One move without restart: the new state, reward, terminated and truncated.

        As the engine's ``_grid_step``: a wall leaves the robot (and its arrival
        side) in place; stepping through the side that leads back is a
        backward step; the goal terminates, the deadline truncates.
        """
        a = jnp.asarray(action, jnp.int32) & 3
        target = params.moves[state.position >> POSITION_SHIFT, a]
        blocked = target < 0
        backward = (state.arrival == a + 1) & ~blocked
        position = jnp.where(blocked, state.position, target)
        arrival = jnp.where(blocked, state.arrival, ((a + 2) & 3) + 1)
        time = state.time + 1
        terminated = position == params.goal
        truncated = time >= params.deadline
        step_reward = jnp.where(
            blocked, REWARD_COLLISION, jnp.where(backward, REWARD_BACKWARD, REWARD_MOVE)
        )
        reward = jnp.where(terminated, params.goal_reward, step_reward)
        new = MazeState(
            position,
            arrival,
            time,
            state.collisions + blocked.astype(jnp.int32),
            state.backsteps + backward.astype(jnp.int32),
        )
        return new, reward, terminated, truncated

    def episode_info(
        self, state: MazeState, terminated: jax.Array, params: MazeParams
    ) -> dict[str, jax.Array]:
        """The episode figures of ``state`` (after its last step), as the engine reports them.

        Integer counters are exact. ``cumulative_reward`` is ``10 R`` (an integer:
        every reward is a multiple of 0.1) divided by 10: the float32 nearest the
        exact return. R̄ is ``(200 s (l-1) - 100 t - (c + 2 b)(l-1)) / (100 (l-1))``,
        exact integers (below 2^24 in float32) divided once: the float32 nearest
        the exact R̄. ``pretty_reward`` is the reference's rescale of the return,
        rounded half to even to 3 decimals (``k / 1000``, correctly rounded).
        """
        steps = state.time
        length = params.path_length
        success = terminated.astype(jnp.int32)
        tenths = (
            -10 * steps
            - _COLLISION_TENTHS * state.collisions
            - _BACKWARD_TENTHS * state.backsteps
            + 10 * (2 * length - 1) * success
        )
        ret = _divide(tenths.astype(jnp.float32), 10.0)
        span = (length - 1).astype(jnp.float32)
        numerator = (200 * (length - 1) * success - 100 * steps).astype(jnp.float32) - (
            state.collisions + _BACKWARD_HUNDREDTHS * state.backsteps
        ).astype(jnp.float32) * span
        normalized = _divide(numerator, 100 * span)
        r_max = length.astype(jnp.float32)
        scaled = _divide(2 * (ret - params.min_reward), r_max - params.min_reward) - 1
        pretty = _divide(jnp.round(scaled * 1000), 1000.0)
        return {
            "success": terminated,
            "steps": steps,
            "collisions": state.collisions,
            "backsteps": state.backsteps,
            "len": length,
            "cumulative_reward": ret,
            "pretty_reward": pretty,
            "normalized_reward": normalized,
        }

    # -- host-side helpers ------------------------------------------------------------

    def cells(self, state: MazeState, params: MazeParams) -> jax.Array:
        """int32 ``(..., 2)``: the robot's cell ``(i, j)`` (``i`` east, ``j`` north)."""
        cell = state.position >> POSITION_SHIFT
        return jnp.stack([cell // params.height, cell % params.height], axis=-1)


def _renamed_maze_env(module: str) -> type[JaxMazeEnv]:
    """:class:`JaxMazeEnv` asked for by its old name in ``module``, with a DeprecationWarning."""
    warnings.warn(
        f"{module}.MazeEnv is renamed JaxMazeEnv (MazeEnv is the gymnasium env's name);"
        " the old name goes in the next release",
        DeprecationWarning,
        stacklevel=3,  # the caller of the module's __getattr__
    )
    return JaxMazeEnv


def __getattr__(name: str) -> Any:
    """``MazeEnv``, the old name of :class:`JaxMazeEnv`, until the next release."""
    if name == "MazeEnv":
        return _renamed_maze_env(__name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
