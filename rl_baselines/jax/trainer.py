"""A2C and PPO training compiled whole: K rollouts and updates per call, one seed, resumable.

:func:`train_step` plays one rollout (:func:`rl_baselines.jax.rollout.collect_rollout`),
computes SB3's returns and advantages and updates the policy
(:mod:`rl_baselines.jax.update`), all from and to a :class:`TrainState`, a
pytree of arrays; :func:`run_rollouts` runs ``k`` of them in one ``lax.scan``
inside one ``jit``, so Python is visited once per ``k`` rollouts. Everything
random comes from the state's key, itself from one int seed
(:func:`init_state`): at each rollout the key splits into the next key, the
rollout's (one key per step: the actions) and the update's (PPO: one
permutation per epoch). The same seed gives the same training bit for bit on
one machine, and a state written to arrays and read back continues exactly as
if it had not been interrupted.

:class:`JaxTrainer` holds it together for a caller: the algorithm, robot,
hyperparameters (SB3's names, :mod:`rl_baselines.jax.hyperparameters`), seed
and mazes in; :meth:`~JaxTrainer.run` for ``k`` rollouts; the state to and from
numpy arrays; the policy (:meth:`~JaxTrainer.policy`); SB3 zips out and in
(:meth:`~JaxTrainer.export_sb3`, :mod:`rl_baselines.jax.sb3_io`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR
from amaze.agents.robot import as_robot
from amaze.envs.jax import JaxContinuousEnv, JaxMazeEnv, make_batch
from amaze.envs.jax.continuous import compile_continuous_params
from amaze.errors import AmazeError
from amaze.maze.maze import Maze, as_mazes
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer, check_number, check_rollout_size
from rl_baselines import RLConfigError
from rl_baselines.jax.hyperparameters import (
    MAX_CHUNK_STEPS,
    Hyperparameters,
    checked_hyperparameters,
    observation_size,
)
from rl_baselines.jax.networks import (
    Params,
    PolicySpec,
    apply,
    as_numpy,
    deterministic_actions,
    init_params,
)
from rl_baselines.jax.optim import OptState, init_optimizer
from rl_baselines.jax.policy import NumpyPolicy
from rl_baselines.jax.rollout import Env, EnvCarry, EnvParams, collect_rollout, reset_envs
from rl_baselines.jax.spec import network_spec
from rl_baselines.jax.storage import check_state_values
from rl_baselines.jax.update import (
    Batch,
    a2c_update,
    compute_returns_and_advantage,
    flatten_rollout,
    ppo_update,
)

__all__ = [
    "CHUNK_STEPS",
    "MAX_CHUNK_STEPS",
    "JaxTrainer",
    "RolloutStats",
    "Static",
    "TrainState",
    "init_state",
    "load_trainer",
    "run_rollouts",
    "train_step",
]


class TrainState(NamedTuple):
    """Everything a training run carries from one rollout to the next (arrays only).

    ``key``: uint32 key data (``jax.random.key_data``); ``envs``: the
    environments (SB3's ``_last_obs`` and ``_last_episode_starts`` included);
    ``rollouts``: rollouts done (SB3's ``num_timesteps`` is ``rollouts x n_steps x
    n_envs``, computed in Python so that it never overflows int32); ``episodes``
    and ``successes``: episodes ended and won since the start.
    """

    params: Params
    opt_state: OptState
    key: jax.Array
    envs: EnvCarry
    rollouts: jax.Array
    episodes: jax.Array
    successes: jax.Array


class RolloutStats(NamedTuple):
    """One rollout's figures (each an array with one entry per rollout of a call).

    The episodes that ended during the rollout, per environment (``(n_envs,)``
    per rollout): their count, successes and the sums of their R̄, lengths and
    returns; the update's figures as SB3 logs them
    (:class:`rl_baselines.jax.update.UpdateStats`).
    """

    episodes: Any
    successes: Any
    normalized_reward: Any
    length: Any
    reward: Any
    policy_loss: Any
    value_loss: Any
    entropy_loss: Any
    approx_kl: Any
    clip_fraction: Any
    loss: Any
    gradient_steps: Any
    explained_variance: Any


@dataclass(frozen=True)
class Static:
    """What the compiled functions specialise on: environment, policy, hyperparameters."""

    env: Env
    spec: PolicySpec
    hp: Hyperparameters


def init_state(static: Static, maze_params: EnvParams, seed: int) -> TrainState:
    """A fresh run from ``seed``: SB3's initial policy and optimizer, every env reset."""
    key, init_key = jax.random.split(jax.random.key(seed))
    params = init_params(static.spec, init_key)
    rms_prop = static.hp.algo == "a2c" and static.hp.use_rms_prop
    zero = jnp.int32(0)
    return TrainState(
        params=params,
        opt_state=init_optimizer(params, rms_prop),
        key=jax.random.key_data(key),
        envs=reset_envs(static.env, maze_params, static.hp.n_envs),
        rollouts=zero,
        episodes=zero,
        successes=zero,
    )


def _batch(static: Static, rollout: Any, last_values: jax.Array, dones: jax.Array) -> Batch:
    """The rollout with its advantages and returns, flattened as SB3's ``RolloutBuffer.get``."""
    hp = static.hp
    advantages, returns = compute_returns_and_advantage(
        rollout.rewards,
        rollout.values,
        rollout.episode_starts,
        last_values,
        dones,
        hp.gamma,
        hp.gae_lambda,
    )
    return Batch(
        observations=flatten_rollout(rollout.observations),
        actions=flatten_rollout(rollout.actions),
        old_values=flatten_rollout(rollout.values),
        old_log_prob=flatten_rollout(rollout.log_probs),
        advantages=flatten_rollout(advantages),
        returns=flatten_rollout(returns),
    )


def train_step(
    static: Static, maze_params: EnvParams, state: TrainState
) -> tuple[TrainState, RolloutStats]:
    """One rollout and one update (SB3's ``collect_rollouts`` then ``train``)."""
    hp = static.hp
    key, rollout_key, update_key = jax.random.split(jax.random.wrap_key_data(state.key), 3)
    envs, rollout, last_values, sums = collect_rollout(
        static.env, static.spec, hp, state.params, maze_params, state.envs, rollout_key
    )
    batch = _batch(static, rollout, last_values, envs.episode_starts)
    if hp.algo == "ppo":
        size = hp.rollout_size
        keys = jax.random.split(update_key, hp.n_epochs)
        permutations = jax.vmap(lambda k: jax.random.permutation(k, size))(keys)
        params, opt_state, update = ppo_update(
            static.spec, hp, state.params, state.opt_state, batch, permutations
        )
    else:
        params, opt_state, update = a2c_update(
            static.spec, hp, state.params, state.opt_state, batch
        )
    new = TrainState(
        params=params,
        opt_state=opt_state,
        key=jax.random.key_data(key),
        envs=envs,
        rollouts=state.rollouts + 1,
        episodes=state.episodes + jnp.sum(sums.episodes),
        successes=state.successes + jnp.sum(sums.successes),
    )
    return new, RolloutStats(*sums, *update)


@partial(jax.jit, static_argnums=(0, 1))
def run_rollouts(
    static: Static, k: int, maze_params: EnvParams, state: TrainState, count: jax.Array
) -> tuple[TrainState, RolloutStats]:
    """The first ``count`` (<= ``k``) of ``k`` rollouts and updates in one ``lax.scan``.

    The scan has a fixed length ``k`` and skips (``lax.cond``) its steps from
    ``count`` on, so that any number of rollouts runs the one compiled function:
    no recompilation for a remainder, and the same code, hence the same bits,
    however a run is cut into calls. The stats have a leading axis of ``k``,
    zeros after ``count``.
    """

    def step(state: TrainState) -> tuple[TrainState, RolloutStats]:
        return train_step(static, maze_params, state)

    shapes = jax.eval_shape(step, state)[1]

    def skip(state: TrainState) -> tuple[TrainState, RolloutStats]:
        return state, jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)

    def one(state: TrainState, i: jax.Array) -> tuple[TrainState, RolloutStats]:
        return jax.lax.cond(i < count, step, skip, state)

    return jax.lax.scan(one, state, jnp.arange(k, dtype=jnp.int32))


def state_arrays(state: TrainState) -> dict[str, np.ndarray]:
    """The state as named numpy arrays (``params/action_net/bias``, ``envs/state/time``...)."""
    leaves = jax.tree_util.tree_flatten_with_path(state)[0]
    return {
        jax.tree_util.keystr(path, simple=True, separator="/"): np.asarray(leaf)
        for path, leaf in leaves
    }


def state_from_arrays(template: TrainState, arrays: Mapping[str, Any]) -> TrainState:
    """The state of :func:`state_arrays`, each array checked against ``template``'s.

    Missing, extra or misshapen arrays raise :class:`RLConfigError` naming them.
    """
    leaves, treedef = jax.tree_util.tree_flatten_with_path(template)
    names = [jax.tree_util.keystr(path, simple=True, separator="/") for path, _ in leaves]
    extra = sorted(set(arrays) - set(names))
    if extra:
        raise RLConfigError(f"training state: unknown arrays {extra}")
    restored = []
    for name, (_, leaf) in zip(names, leaves, strict=True):
        if name not in arrays:
            raise RLConfigError(f"training state: array {name!r} is missing")
        value = np.asarray(arrays[name])
        if value.shape != leaf.shape or value.dtype != leaf.dtype:
            raise RLConfigError(
                f"training state: array {name!r} is {value.dtype}{list(value.shape)},"
                f" not {leaf.dtype}{list(leaf.shape)}"
            )
        restored.append(jnp.asarray(value))
    return jax.tree_util.tree_unflatten(treedef, restored)


MazesLike = Sequence[Maze | MazeSpec | str]

#: Env steps that one compiled call covers at most, by default (see :class:`JaxTrainer`).
CHUNK_STEPS = 65_536


def _maze_strings(mazes: MazesLike | str) -> list[str]:
    """The mazes as strings (what a saved trainer records), errors as :class:`RLConfigError`."""
    try:
        return [m.to_string() for m in as_mazes(mazes)]
    except AmazeError as error:
        raise RLConfigError(f"mazes: {error}") from None


class JaxTrainer:
    """A2C or PPO of SB3, for ``robot`` in ``mazes``, compiled with JAX.

    ``hyperparameters`` are SB3's keyword arguments (defaults SB3's; see
    :func:`~rl_baselines.jax.hyperparameters.checked_hyperparameters`);
    ``n_envs`` environments (environment ``k`` in ``mazes[k % M]``, cycling
    through them when ``M > n_envs``, as :class:`rl_baselines.vec_env.SB3VecEnv`);
    ``seed`` seeds everything. ``max_cells`` / ``max_codes`` pad the mazes'
    tables (:mod:`amaze.envs.jax.params`) so that later mazes of other sizes
    (:meth:`set_mazes`) reuse the compiled code; a continuous robot's mazes
    (:class:`~amaze.envs.jax.JaxContinuousEnv`) are padded to a square of
    ``isqrt(max_cells)`` cells a side, and ``max_codes`` is refused. ``chunk_steps``:
    env steps one compiled call covers at most (a power of two of rollouts, at
    least one): Python is visited once per chunk. ``network``: a network spec
    (:func:`~rl_baselines.jax.spec.network_spec`: evolution's ``hidden``,
    ``activation``, ``pool``, ``symmetry``) instead of SB3's policy (a
    continuous robot's policy needs one: a Gaussian over evolution's
    accelerations). ``progress_reward`` (continuous robots only): the reward for
    reaching further along each maze's solution
    (:class:`~amaze.envs.jax.JaxContinuousEnv`; 0, AMaze's reward alone).
    Bad values raise :class:`RLConfigError`.
    """

    def __init__(
        self,
        algo: str,
        robot: str,
        mazes: MazesLike | str,
        hyperparameters: Mapping[str, Any] | None = None,
        seed: int = 0,
        *,
        n_envs: int = 4,
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
        max_cells: int | None = None,
        max_codes: int | None = None,
        chunk_steps: int = CHUNK_STEPS,
        network: Mapping[str, Any] | None = None,
        progress_reward: float = 0.0,
    ) -> None:
        try:
            parsed = as_robot(robot)
        except AmazeError as error:
            raise RLConfigError(f"robot {robot!r}: {error}") from None
        progress_reward = check_number(
            "progress_reward", progress_reward, minimum=0.0, error=RLConfigError
        )
        if parsed.discrete_outputs:
            if progress_reward:
                raise RLConfigError(
                    f"progress_reward {progress_reward!r} has no effect with robot {parsed}:"
                    " it rewards continuous robots (CC...) only"
                )
            env: JaxMazeEnv | JaxContinuousEnv = JaxMazeEnv(parsed)
        else:
            env = JaxContinuousEnv(parsed, progress_reward=progress_reward)
        if not parsed.discrete_outputs and max_codes is not None:
            raise RLConfigError(
                f"max_codes {max_codes!r} has no effect with robot {parsed}: a continuous"
                " robot's mazes are padded to a square side (max_cells gives its area)"
            )
        hp = checked_hyperparameters(
            algo, hyperparameters or {}, robot_images=not parsed.discrete_inputs, n_envs=n_envs
        )
        check_rollout_size(hp.n_steps, hp.n_envs, observation_size(parsed), error=RLConfigError)
        if network is None:
            spec = PolicySpec(parsed.to_string(), hp.net_pi, hp.net_vf, hp.features_dim)
        else:
            if (hyperparameters or {}).get("policy_kwargs"):
                raise RLConfigError(
                    "hyperparameter 'policy_kwargs' with a network: the network gives the"
                    " policy's layers (give one of them)"
                )
            spec = network_spec(parsed.to_string(), network)
        #: The ``network`` spec as given (``None``: SB3's policy), for :meth:`settings`.
        self.network = None if network is None else dict(network)
        self.static = Static(env, spec, hp)
        self.seed = check_integer("seed", seed, minimum=0, maximum=2**32 - 1, error=RLConfigError)
        self._padding = {
            "deadline_factor": deadline_factor,
            "max_cells": max_cells,
            "max_codes": max_codes,
        }
        chunk_steps = check_integer(
            "chunk_steps", chunk_steps, minimum=1, maximum=MAX_CHUNK_STEPS, error=RLConfigError
        )
        per_call = max(1, chunk_steps // hp.rollout_size)
        #: Rollouts per compiled call (the scan's fixed length).
        self.chunk = 1 << (per_call.bit_length() - 1)
        self.mazes: list[str] = []
        self.maze_params = self._compile(mazes)
        self.state = init_state(self.static, self.maze_params, self.seed)

    # -- set-up -----------------------------------------------------------------------

    def _compile(self, mazes: MazesLike | str) -> EnvParams:
        """The stacked params of ``mazes`` (one per maze); records them as strings."""
        strings = _maze_strings(mazes)
        robot = self.static.env.robot
        try:
            if robot.discrete_outputs:
                _, params = make_batch(strings, robot, **self._padding)
            else:
                max_cells = self._padding["max_cells"]
                if max_cells is not None:
                    max_cells = check_integer(
                        "max_cells", max_cells, minimum=1, error=RLConfigError
                    )
                params = compile_continuous_params(
                    strings,
                    robot,
                    deadline_factor=self._padding["deadline_factor"],
                    max_side=None if max_cells is None else math.isqrt(max_cells),
                )
        except AmazeError as error:
            raise RLConfigError(f"mazes: {error}") from None
        self.mazes = strings
        return params

    def set_mazes(self, mazes: MazesLike | str) -> None:
        """Train on ``mazes`` from now on: every environment reset into its new maze.

        As SB3's ``set_env`` with a new :class:`~rl_baselines.vec_env.SB3VecEnv` and
        ``learn``: the policy and optimizer go on, the environments start afresh.
        """
        self.maze_params = self._compile(mazes)
        envs = reset_envs(self.static.env, self.maze_params, self.static.hp.n_envs)
        self.state = self.state._replace(envs=envs)

    def reseed(self, seed: int) -> None:
        """Draw from ``seed`` from now on (SB3's ``set_random_seed``): the state's key only.

        The key is ``fold_in(key(seed), 1)``, a stream apart from the one
        :func:`init_state` drew the initial parameters from with the same seed.
        Parameters, optimizer and environments go on.
        """
        seed = check_integer("seed", seed, minimum=0, maximum=2**32 - 1, error=RLConfigError)
        key = jax.random.fold_in(jax.random.key(seed), 1)
        self.state = self.state._replace(key=jax.random.key_data(key))

    # -- training ------------------------------------------------------------------------

    @property
    def hyperparameters(self) -> Hyperparameters:
        return self.static.hp

    @property
    def num_timesteps(self) -> int:
        """Env steps trained on (SB3's ``num_timesteps``): rollouts x ``n_steps`` x ``n_envs``."""
        return int(self.state.rollouts) * self.static.hp.rollout_size

    def run(self, k: int) -> RolloutStats:
        """Play and learn from ``k`` rollouts; their figures (one entry per rollout), as numpy.

        They run in compiled calls of :attr:`chunk` rollouts (the last one
        partly skipped), so any ``k`` reuses the one compiled function and
        gives the same result however a run is cut into calls.
        """
        k = check_integer("k", k, minimum=1, error=RLConfigError)
        parts: list[RolloutStats] = []
        while k > 0:
            count = min(k, self.chunk)
            self.state, stats = run_rollouts(
                self.static, self.chunk, self.maze_params, self.state, jnp.int32(count)
            )
            parts.append(RolloutStats(*(np.asarray(value)[:count] for value in stats)))
            k -= count
        return RolloutStats(*(np.concatenate(values) for values in zip(*parts, strict=True)))

    def learn(self, n_steps: int) -> RolloutStats:
        """Learn from at least ``n_steps`` more env steps, in whole rollouts (SB3's ``learn``).

        As SB3's ``learn(total_timesteps=n_steps, reset_num_timesteps=False)``:
        rollouts of ``n_steps x n_envs`` steps until ``n_steps`` are done (the
        last one may go past). Call it again to go on (between calls, evaluate
        :meth:`policy` or :meth:`save`): the result is the same, bit for bit,
        as one call. Returns each rollout's figures.
        """
        n_steps = check_integer("n_steps", n_steps, minimum=1, error=RLConfigError)
        return self.run(-(-n_steps // self.static.hp.rollout_size))

    # -- state ------------------------------------------------------------------------------

    def state_arrays(self) -> dict[str, np.ndarray]:
        """The whole training state as named numpy arrays (see :func:`state_arrays`)."""
        return state_arrays(self.state)

    def load_state_arrays(self, arrays: Mapping[str, Any]) -> None:
        """Continue from arrays of :meth:`state_arrays` (same algorithm, robot, hyperparameters,
        ``n_envs`` and number of mazes), each checked: every float array (parameters,
        optimizer moments, observations) finite, second moments not negative."""
        state = state_from_arrays(self.state, arrays)
        for name, value in arrays.items():
            check_state_values(name, np.asarray(value))
        n_mazes = int(self.maze_params.start.shape[0])
        index = np.asarray(state.envs.maze_index)
        if index.min() < 0 or index.max() >= n_mazes:
            raise RLConfigError(
                f"training state: maze indices {index.tolist()} do not fit {n_mazes} mazes"
            )
        self.state = state

    def settings(self) -> dict[str, Any]:
        """What rebuilds this trainer (JSON): algorithm, robot, mazes, hyperparameters, seed..."""
        hp = self.static.hp
        return {
            "algo": hp.algo,
            "robot": self.static.spec.robot,
            "mazes": list(self.mazes),
            "hyperparameters": hp.sb3_kwargs(policy=self.network is None),
            "seed": self.seed,
            "n_envs": hp.n_envs,
            **self._padding,
            "chunk_steps": self.chunk * hp.rollout_size,
            "network": self.network,
            "progress_reward": getattr(self.static.env, "progress_reward", 0.0),
        }

    def check_settings(self, expected: Mapping[str, Any], source: str) -> None:
        """Refuse (:class:`RLConfigError` naming ``source``) a trainer whose
        :meth:`settings` differ from ``expected`` in any of its keys."""
        settings = self.settings()
        for key, value in expected.items():
            if settings[key] != value:
                raise RLConfigError(
                    f"{source}: its trainer's {key} {settings[key]!r} is not {value!r}"
                )

    def save(self, folder: str | os.PathLike) -> Path:
        """Write the trainer into ``folder`` (see :mod:`rl_baselines.jax.storage`); its path."""
        from rl_baselines.jax.storage import save_trainer

        return save_trainer(self, folder)

    @classmethod
    def load(cls, folder: str | os.PathLike) -> JaxTrainer:
        """The trainer saved in ``folder``: it goes on exactly as the saved one would."""
        return load_trainer(folder)

    # -- the policy --------------------------------------------------------------------------

    def params(self) -> dict[str, dict[str, np.ndarray]]:
        """The policy's parameters as numpy arrays (SB3's state_dict names, torch layout)."""
        return as_numpy(self.state.params)

    def policy(self) -> NumpyPolicy:
        """The policy acting deterministically (argmax, or the Gaussian's mean), in numpy,
        for the evaluation protocol."""
        return NumpyPolicy(self.static.spec, self.params())

    def jax_policy(self) -> Callable[[jax.Array], jax.Array]:
        """The current policy as a jitted JAX function: observations ``(n, ...)`` to
        deterministic actions (int32 ``(n,)``; a continuous robot's mean accelerations,
        float32 ``(n, 2)``), for evaluation inside JAX."""
        spec, params = self.static.spec, self.state.params

        @jax.jit
        def act(observations: jax.Array) -> jax.Array:
            outputs, _ = apply(spec, params, observations)
            if spec.continuous:  # the Gaussian's mean, in [-1, 1]
                return outputs
            return deterministic_actions(outputs).astype(jnp.int32)

        return act

    def export_sb3(self, path: Any, seed: int | None = None) -> Any:
        """Write the policy (and optimizer state) as an SB3 zip that ``SB3Agent.load`` reads.

        Returns the zip's path (see :func:`rl_baselines.jax.sb3_io.export_sb3`).
        """
        from rl_baselines.jax.sb3_io import export_sb3

        return export_sb3(self, path, seed=self.seed if seed is None else seed)


def load_trainer(folder: str | os.PathLike) -> JaxTrainer:
    """The trainer saved in ``folder`` (:mod:`rl_baselines.jax.storage`), every part checked.

    A missing or malformed file, other settings or arrays that do not fit raise
    :class:`RLConfigError`.
    """
    from rl_baselines.jax.storage import SETTINGS_FILE, STATE_FILE, read_settings, read_state

    path, settings = read_settings(folder)
    try:
        trainer = JaxTrainer(**settings)
    except (TypeError, RLConfigError) as error:
        raise RLConfigError(f"{path / SETTINGS_FILE}: {error}") from None
    arrays = read_state(path, trainer.state_arrays())
    try:
        trainer.load_state_arrays(arrays)
    except RLConfigError as error:
        raise RLConfigError(f"{path / STATE_FILE}: {error}") from None
    return trainer
