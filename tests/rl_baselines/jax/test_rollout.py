"""The compiled rollout and SB3's returns/advantages against SB3's own code.

1. :func:`compute_returns_and_advantage` against SB3's
   ``RolloutBuffer.compute_returns_and_advantage`` on random data (episode
   starts anywhere, some last ``dones``), for PPO's and A2C's ``gae_lambda``.
2. A whole rollout: the JAX rollout (:func:`collect_rollout`) is played with
   the JAX policy on the JAX environment; then SB3's ``collect_rollouts`` runs
   on :class:`~rl_baselines.vec_env.SB3VecEnv` over the same mazes with the
   same parameters, its policy made to take the JAX rollout's actions (its
   values and log-probabilities SB3's own). The buffers must agree: the
   observations, actions, episode starts, rewards (with SB3's bootstrap of
   truncated episodes by the value of their terminal observation), values,
   log-probabilities, and the returns and advantages each side computes.
   The deadline is short so that episodes get truncated, and there are more
   mazes than environments so that environments cycle through mazes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

jax = pytest.importorskip("jax")
torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

import jax.numpy as jnp  # noqa: E402
from gymnasium import spaces  # noqa: E402
from stable_baselines3.common.buffers import RolloutBuffer  # noqa: E402
from stable_baselines3.common.logger import configure  # noqa: E402

from rl_baselines.jax.rollout import collect_rollout  # noqa: E402
from rl_baselines.jax.sb3_io import sb3_state_dict  # noqa: E402
from rl_baselines.jax.trainer import JaxTrainer  # noqa: E402
from rl_baselines.jax.update import compute_returns_and_advantage  # noqa: E402
from rl_baselines.learner import new_sb3_model  # noqa: E402
from rl_baselines.vec_env import SB3VecEnv  # noqa: E402

MAZES = ["M1_5x5_C1", "M2_6x6_C1", "M3_5x5_C1_l.25_L.25", "M4_6x5_C1", "M5_5x6_C1", "M6_5x5_C1"]


@pytest.mark.parametrize("gae_lambda", [0.95, 1.0])
def test_gae_equals_rollout_buffer(gae_lambda: float) -> None:
    n_steps, n_envs, gamma = 24, 3, 0.99
    rng = np.random.default_rng(int(gae_lambda * 100))
    buffer = RolloutBuffer(
        n_steps, spaces.Box(-1, 1, (2,)), spaces.Discrete(4), "cpu", gae_lambda, gamma, n_envs
    )
    rewards = rng.normal(0, 1, (n_steps, n_envs)).astype(np.float32)
    values = rng.normal(0, 1, (n_steps, n_envs)).astype(np.float32)
    starts = rng.random((n_steps, n_envs)) < 0.2
    starts[0] = True
    for t in range(n_steps):
        buffer.add(
            np.zeros((n_envs, 2), np.float32),
            np.zeros(n_envs),
            rewards[t],
            starts[t],
            torch.as_tensor(values[t]),
            torch.zeros(n_envs),
        )
    last_values = rng.normal(0, 1, n_envs).astype(np.float32)
    dones = np.array([True, False, True])
    buffer.compute_returns_and_advantage(torch.as_tensor(last_values), dones)
    advantages, returns = compute_returns_and_advantage(
        jnp.asarray(rewards),
        jnp.asarray(values),
        jnp.asarray(starts),
        jnp.asarray(last_values),
        jnp.asarray(dones),
        gamma,
        gae_lambda,
    )
    np.testing.assert_allclose(np.asarray(advantages), buffer.advantages, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(returns), buffer.returns, rtol=1e-5, atol=1e-6)


class _CountingEnv(SB3VecEnv):
    """SB3VecEnv counting ended and truncated episodes (the test's preconditions)."""

    ended = 0
    truncated = 0

    def step_wait(self) -> Any:
        result = super().step_wait()
        for info in result[3]:
            self.ended += "episode" in info
            self.truncated += bool(info.get("TimeLimit.truncated", False))
        return result


def _sb3_rollout(trainer: JaxTrainer, actions: np.ndarray, deadline: float) -> tuple[Any, Any]:
    """SB3's ``collect_rollouts`` with the trainer's parameters, taking ``actions``."""
    hp, spec = trainer.static.hp, trainer.static.spec
    env = _CountingEnv(MAZES, spec.robot, hp.n_envs, seed=0, deadline_factor=deadline)
    model = new_sb3_model(hp.algo, spec.robot, env, 0, hp.sb3_kwargs())
    model.set_logger(configure(None, [""]))
    model.policy.load_state_dict(sb3_state_dict(spec, trainer.state.params))
    forced = iter(actions)

    def forward(obs: torch.Tensor, deterministic: bool = False) -> tuple:
        chosen = torch.tensor(np.array(next(forced)), dtype=torch.int64)
        values, log_prob, _ = model.policy.evaluate_actions(obs, chosen)
        return chosen, values, log_prob

    model.policy.forward = forward  # type: ignore[method-assign]
    _, callback = model._setup_learn(hp.rollout_size, None)
    callback.on_training_start(locals(), globals())
    assert model.collect_rollouts(env, callback, model.rollout_buffer, hp.n_steps)
    return model.rollout_buffer, env


@pytest.mark.parametrize(
    ("algo", "hps"),
    [("ppo", {"n_steps": 48, "gae_lambda": 0.9}), ("a2c", {"n_steps": 48})],
)
def test_rollout_equals_sb3_collect_rollouts(algo: str, hps: dict[str, Any]) -> None:
    deadline = 1.0
    trainer = JaxTrainer(algo, "DD", MAZES, hps, seed=4, deadline_factor=deadline)
    static, hp = trainer.static, trainer.static.hp
    envs, rollout, last_values, _ = jax.jit(
        lambda state, key: collect_rollout(
            static.env, static.spec, hp, state.params, trainer.maze_params, state.envs, key
        )
    )(trainer.state, jax.random.key(9))
    advantages, returns = compute_returns_and_advantage(
        rollout.rewards,
        rollout.values,
        rollout.episode_starts,
        last_values,
        envs.episode_starts,
        hp.gamma,
        hp.gae_lambda,
    )
    buffer, env = _sb3_rollout(trainer, np.asarray(rollout.actions), deadline)
    assert env.truncated >= 3 and env.ended > len(MAZES)  # bootstraps and maze cycling happen
    np.testing.assert_array_equal(np.asarray(rollout.observations), buffer.observations)
    np.testing.assert_array_equal(np.asarray(rollout.actions), buffer.actions[..., 0])
    np.testing.assert_array_equal(np.asarray(rollout.episode_starts), buffer.episode_starts)
    close = {"rtol": 1e-5, "atol": 1e-6}
    np.testing.assert_allclose(np.asarray(rollout.rewards), buffer.rewards, **close)
    np.testing.assert_allclose(np.asarray(rollout.values), buffer.values, **close)
    np.testing.assert_allclose(np.asarray(rollout.log_probs), buffer.log_probs, **close)
    np.testing.assert_allclose(np.asarray(advantages), buffer.advantages, **close)
    np.testing.assert_allclose(np.asarray(returns), buffer.returns, **close)
