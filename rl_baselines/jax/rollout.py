"""One rollout of SB3's ``collect_rollouts``, compiled with the policy: ``lax.scan`` over steps.

Each step (``OnPolicyAlgorithm.collect_rollouts``, ``common/on_policy_algorithm.py``):
the policy gives logits and values of the last observations; actions are drawn
from the categorical distribution (an explicit key per step; a continuous
robot's from its Gaussian, stored as drawn and clipped to [-1, 1] for the
environment, as SB3 clips a ``Box`` action); all environments
step together (``vmap`` of :meth:`amaze.envs.jax.JaxMazeEnv.step`, or
:meth:`amaze.envs.jax.JaxContinuousEnv.step`, which restart an ended episode
in the same step); an episode that ends by its deadline
without success (``TimeLimit.truncated`` in :class:`rl_baselines.vec_env.SB3VecEnv`)
gets SB3's bootstrap ``reward += gamma * V(final observation)`` (SB3 issue #633);
the buffer stores the observations, actions, rewards, ``episode_starts`` (the
previous step's dones, all ones after a reset), values and log-probabilities.

**Mazes.** As :class:`~rl_baselines.vec_env.SB3VecEnv`: environment ``k`` starts
in maze ``k % M``; when there are more mazes than environments (``M > n_envs``),
it plays maze ``(k + e * n_envs) % M`` in its episode ``e``. The ``M`` mazes are
params stacked along a leading axis (:func:`amaze.envs.jax.make_batch`); each
environment's params are gathered once per rollout, and again (under a
``lax.cond``) only at steps where an episode ended and mazes cycle.

The episode figures of every episode that ends (``success``, R̄, length, return)
are summed per rollout and environment (:class:`EpisodeSums`): for logging, and
for co-evolution, where environment ``k`` plays maze ``k`` of a round and its
episodes score that maze.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from amaze.envs.jax import (
    ContinuousParams,
    ContinuousState,
    JaxContinuousEnv,
    JaxMazeEnv,
    MazeParams,
    MazeState,
)
from rl_baselines.jax.hyperparameters import Hyperparameters
from rl_baselines.jax.networks import (
    Params,
    PolicySpec,
    apply,
    predict_values,
    sample_actions,
)

__all__ = ["EnvCarry", "EpisodeSums", "Rollout", "collect_rollout", "reset_envs"]

#: The environments a rollout steps: a discrete robot's or a continuous one's, with
#: their params and states.
Env = JaxMazeEnv | JaxContinuousEnv
EnvParams = MazeParams | ContinuousParams
EnvState = MazeState | ContinuousState


class EnvCarry(NamedTuple):
    """The environments between steps (and rollouts), ``(n_envs, ...)`` arrays.

    ``observations``: the last ones (SB3's ``_last_obs``); ``episode_starts``:
    SB3's ``_last_episode_starts``; ``maze_index``: the maze each one plays;
    ``episodes``: episodes each one has ended since the reset (which maze comes next).
    """

    state: EnvState
    observations: jax.Array
    episode_starts: jax.Array
    maze_index: jax.Array
    episodes: jax.Array


class Rollout(NamedTuple):
    """SB3's ``RolloutBuffer`` content, ``(n_steps, n_envs, ...)``."""

    observations: jax.Array
    actions: jax.Array
    rewards: jax.Array
    episode_starts: jax.Array
    values: jax.Array
    log_probs: jax.Array


class EpisodeSums(NamedTuple):
    """Sums over the episodes that ended in a rollout, per environment (``(n_envs,)`` each):
    count, successes, R̄, length, return."""

    episodes: jax.Array
    successes: jax.Array
    normalized_reward: jax.Array
    length: jax.Array
    reward: jax.Array


def _gather(maze_params: EnvParams, index: jax.Array) -> EnvParams:
    """The params of maze ``index[k]`` for each environment ``k``."""
    return jax.tree.map(lambda table: table[index], maze_params)


def _restart(env: Env, params: EnvParams) -> tuple[EnvState, jax.Array]:
    """The first state and observation of an episode in each environment's maze."""
    state = jax.vmap(env.initial_state)(params)
    return state, jax.vmap(env.observe)(state, params)


def reset_envs(env: Env, maze_params: EnvParams, n_envs: int) -> EnvCarry:
    """Every environment at the start of an episode: env ``k`` in maze ``k % M``.

    As ``SB3VecEnv.reset``.
    """
    n_mazes = maze_params.start.shape[0]
    index = jnp.arange(n_envs, dtype=jnp.int32) % n_mazes
    state, observations = _restart(env, _gather(maze_params, index))
    zeros = jnp.zeros(n_envs, jnp.int32)
    return EnvCarry(state, observations, jnp.ones(n_envs, bool), index, zeros)


def _next_mazes(
    env: Env,
    maze_params: EnvParams,
    params: EnvParams,
    carry: EnvCarry,
    done: jax.Array,
) -> tuple[EnvParams, EnvCarry]:
    """Environments whose episode ended move to their next maze (``SB3VecEnv._next_mazes``).

    ``carry`` holds the state and observations after the step (restarted in the
    old maze) and the episode counts with the ended ones counted; the ended
    environments are restarted in their new maze.
    """
    n_envs = done.shape[0]
    n_mazes = maze_params.start.shape[0]
    following = (jnp.arange(n_envs, dtype=jnp.int32) + carry.episodes * n_envs) % n_mazes
    index = jnp.where(done, following, carry.maze_index)

    def move(_: None) -> tuple[EnvParams, EnvState, jax.Array]:
        new_params = _gather(maze_params, index)
        fresh, observations = _restart(env, new_params)

        def pick(new: jax.Array, old: jax.Array) -> jax.Array:
            return jnp.where(done.reshape(-1, *([1] * (new.ndim - 1))), new, old)

        state = jax.tree.map(pick, fresh, carry.state)
        return new_params, state, pick(observations, carry.observations)

    def stay(_: None) -> tuple[EnvParams, EnvState, jax.Array]:
        return params, carry.state, carry.observations

    params, state, observations = jax.lax.cond(jnp.any(done), move, stay, None)
    return params, carry._replace(state=state, observations=observations, maze_index=index)


def _episode_sums(info: dict[str, jax.Array], done: jax.Array) -> EpisodeSums:
    """The figures of the episodes ending at one step, per environment (zero where none)."""

    def total(x: jax.Array, dtype: jnp.dtype) -> jax.Array:
        return jnp.where(done, x, 0).astype(dtype)

    return EpisodeSums(
        episodes=done.astype(jnp.int32),
        successes=total(info["success"], jnp.int32),
        normalized_reward=total(info["normalized_reward"], jnp.float32),
        length=total(info["steps"], jnp.int32),
        reward=total(info["cumulative_reward"], jnp.float32),
    )


def collect_rollout(
    env: Env,
    spec: PolicySpec,
    hp: Hyperparameters,
    policy: Params,
    maze_params: EnvParams,
    carry: EnvCarry,
    key: jax.Array,
) -> tuple[EnvCarry, Rollout, jax.Array, EpisodeSums]:
    """``n_steps`` steps of every environment with the policy (SB3's ``collect_rollouts``).

    Returns the environments after the rollout, the buffer, the values of the
    last observations (``last_values`` of ``compute_returns_and_advantage``,
    whose ``dones`` are the returned carry's ``episode_starts``) and the ended
    episodes' sums.
    """
    cycling = maze_params.start.shape[0] > hp.n_envs
    step_env = jax.vmap(env.step, in_axes=(None, 0, 0, 0))

    def one_step(
        loop: tuple[EnvCarry, EnvParams, EpisodeSums], step_key: jax.Array
    ) -> tuple[tuple[EnvCarry, EnvParams, EpisodeSums], Rollout]:
        carry, params, sums = loop
        outputs, values = apply(spec, policy, carry.observations)
        actions, log_prob = sample_actions(spec, policy, outputs, step_key)
        moves = jnp.clip(actions, -1.0, 1.0) if spec.continuous else actions
        observations, state, reward, terminated, truncated, info = step_env(
            step_key, carry.state, moves, params
        )
        done = terminated | truncated
        timeout = truncated & ~terminated  # SB3VecEnv's TimeLimit.truncated
        terminal_values = predict_values(spec, policy, info["final_observation"])
        reward = jnp.where(timeout, reward + hp.gamma * terminal_values, reward)
        record = Rollout(
            carry.observations, actions, reward, carry.episode_starts, values, log_prob
        )
        carry = EnvCarry(
            state, observations, done, carry.maze_index, carry.episodes + done.astype(jnp.int32)
        )
        if cycling:
            params, carry = _next_mazes(env, maze_params, params, carry, done)
        sums = jax.tree.map(jnp.add, sums, _episode_sums(info, done))
        return (carry, params, sums), record

    zeros = jnp.zeros(hp.n_envs, jnp.int32), jnp.zeros(hp.n_envs, jnp.float32)
    zero = EpisodeSums(zeros[0], zeros[0], zeros[1], zeros[0], zeros[1])
    params = _gather(maze_params, carry.maze_index)
    keys = jax.random.split(key, hp.n_steps)
    (carry, _, sums), rollout = jax.lax.scan(one_step, (carry, params, zero), keys)
    last_values = predict_values(spec, policy, carry.observations)
    return carry, rollout, last_values, sums
