"""SB3's side of the equivalence tests: a model whose rollout buffer is filled with known data.

:func:`filled_model` builds the SB3 model of ``amaze-train``
(:func:`rl_baselines.learner.new_sb3_model`) and fills its ``RolloutBuffer`` as
``collect_rollouts`` would, with real observations of a vector env, random
actions and rewards, episode starts mid-rollout, the policy's values and
(perturbed, so that PPO's ratios move away from 1) log-probabilities, then
lets SB3 compute returns and advantages. :func:`jax_batch` is the same data as
the JAX update takes it; :func:`sb3_permutations` fixes numpy's permutations
so that SB3's ``train()`` and the JAX update see the same minibatches.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.logger import configure

from amaze.agents.robot import as_robot
from rl_baselines.jax.hyperparameters import Hyperparameters, checked_hyperparameters
from rl_baselines.jax.spec import PolicySpec
from rl_baselines.jax.update import Batch, flatten_rollout
from rl_baselines.learner import new_sb3_model
from rl_baselines.vec_env import SB3VecEnv

#: float32 agreement of parameters and optimizer moments after an update (several steps):
#: relative, and absolute as a fraction of each array's largest magnitude.
PARAMS_RTOL, PARAMS_ATOL = 2e-5, 5e-5
#: float32 agreement of one gradient (same) and of the logged losses (relative).
GRAD_RTOL, GRAD_ATOL = 1e-4, 1e-5


MAZES = ["M1_5x5_C1", "M2_6x6_C1_l.25_L.25", "M3_7x5_C1_t.5_T.5"]

torch.set_num_threads(1)


def spec_and_hp(
    algo: str, robot: str, hyperparameters: dict[str, Any], n_envs: int
) -> tuple[PolicySpec, Hyperparameters]:
    """The JAX trainer's policy spec and hyperparameters for an SB3 configuration."""
    images = not as_robot(robot).discrete_inputs
    hp = checked_hyperparameters(algo, hyperparameters, robot_images=images, n_envs=n_envs)
    return PolicySpec(as_robot(robot).to_string(), hp.net_pi, hp.net_vf, hp.features_dim), hp


def filled_model(
    algo: str, robot: str, hyperparameters: dict[str, Any], seed: int = 0, n_envs: int = 4
) -> BaseAlgorithm:
    """An SB3 model whose rollout buffer holds a full rollout with returns and advantages."""
    env = SB3VecEnv(MAZES, robot, n_envs, seed=seed)
    model = new_sb3_model(algo, robot, env, seed, hyperparameters)
    model.set_logger(configure(None, [""]))
    rng = np.random.default_rng(seed)
    buffer = model.rollout_buffer
    buffer.reset()
    obs = env.reset()
    for step in range(model.n_steps):
        actions = rng.integers(0, 4, n_envs)
        with torch.no_grad():
            values, log_prob, _ = model.policy.evaluate_actions(
                torch.as_tensor(obs), torch.as_tensor(actions)
            )
        noisy = log_prob + torch.as_tensor(rng.normal(0, 0.3, n_envs), dtype=torch.float32)
        rewards = rng.normal(0, 1, n_envs).astype(np.float32)
        starts = np.ones(n_envs) if step == 0 else rng.random(n_envs) < 0.2
        buffer.add(obs, actions, rewards, starts, values, noisy)
        obs, _, _, _ = env.step(actions)
    with torch.no_grad():
        last_values = model.policy.predict_values(torch.as_tensor(obs))
    buffer.compute_returns_and_advantage(last_values=last_values, dones=rng.random(n_envs) < 0.3)
    return model


def jax_batch(model: BaseAlgorithm) -> Batch:
    """The filled buffer's data flattened in SB3's order, as the JAX update takes it."""
    b = model.rollout_buffer
    return Batch(
        observations=flatten_rollout(jnp.asarray(b.observations)),
        actions=flatten_rollout(jnp.asarray(b.actions[..., 0].astype(np.int32))),
        old_values=flatten_rollout(jnp.asarray(b.values)),
        old_log_prob=flatten_rollout(jnp.asarray(b.log_probs)),
        advantages=flatten_rollout(jnp.asarray(b.advantages)),
        returns=flatten_rollout(jnp.asarray(b.returns)),
    )


def sb3_permutations(model: BaseAlgorithm, epochs: int, seed: int) -> np.ndarray:
    """The permutations SB3's next ``train()`` draws after ``np.random.seed(seed)`` (reseeded)."""
    size = model.rollout_buffer.buffer_size * model.rollout_buffer.n_envs
    np.random.seed(seed)  # noqa: NPY002 (SB3 draws from the legacy global generator)
    permutations = np.stack(
        [
            np.random.permutation(size)  # noqa: NPY002
            for _ in range(epochs)
        ]
    )
    np.random.seed(seed)  # noqa: NPY002 (SB3 draws from the legacy global generator)
    return permutations.astype(np.int32)


def assert_trees_close(actual: Any, expected: Any, rtol: float, atol: float) -> None:
    """Leaf by leaf: within ``rtol`` of each value or ``atol`` x the leaf's largest magnitude.

    The absolute part scales with the array, as float32 rounding does: a moment that
    cancels to nearly zero carries the rounding of its larger terms.
    """
    for path, value in jax.tree_util.tree_flatten_with_path(expected)[0]:
        got = actual
        for key in path:
            got = got[key.key] if hasattr(key, "key") else getattr(got, key.name)
        value = np.asarray(value)
        scale = float(np.max(np.abs(value))) if value.size else 0.0
        np.testing.assert_allclose(
            np.asarray(got), value, rtol=rtol, atol=atol * scale, err_msg=str(path)
        )
