"""A continuous robot's PPO and A2C updates in JAX against SB3's ``train()``.

A continuous robot (``CC7``: 7x7 images in, an acceleration in [-1, 1]^2 out)
is trained with a ``network`` kind policy only (:mod:`rl_baselines.jax.spec`),
whose Gaussian mean is ``tanh(action_net(latent))``, not SB3's linear mean, so
:mod:`rl_baselines.jax.sb3_io` has no SB3 model to compare it with. Here SB3
runs the same policy: an ``ActorCriticPolicy`` whose features extractor is
the pooled retina (``pixels @ pool_matrix``, a fixed buffer, with
``normalize_images=False`` since the matrix scales by 1/255 itself), MLPs of
``[8]`` with Tanh, and ``action_net`` wrapped as ``Sequential(Linear, Tanh)``
so that SB3's ``DiagGaussianDistribution`` (its ``log_std`` a parameter)
takes the squashed mean. Compared:

* the forward pass, log-probabilities and entropies of the two policies on
  the same observations and actions (what the rest relies on);
* one whole update (PPO: several minibatches, a shorter last one, two epochs,
  gradient clipping, the ratio clipped; A2C: RMSprop) from the same parameters,
  buffer and minibatch permutations: every parameter including ``log_std``,
  the optimizer's moments, and the figures SB3 logs (``train/std`` included);
* the JAX Gaussian's log-probability and entropy against torch's ``Normal``,
  with their gradients with respect to ``log_std`` (a detached ``log_std``
  would train no standard deviation).

SB3's buffer is filled as ``collect_rollouts`` would, with actions drawn
around the policy's means wider than its standard deviation (some outside
[-1, 1], stored unclipped, the environment stepped with them clipped),
perturbed log-probabilities (so that PPO's ratios move and clip), random
rewards and episode starts. Before that, ``action_net`` is scaled up (SB3's
gain of 0.01 would keep ``tanh`` linear) and ``log_std`` set apart from 0 per
dimension, so that the squash and the standard deviations matter.
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
from stable_baselines3 import A2C, PPO  # noqa: E402
from stable_baselines3.common.base_class import BaseAlgorithm  # noqa: E402
from stable_baselines3.common.logger import configure  # noqa: E402
from stable_baselines3.common.policies import ActorCriticPolicy  # noqa: E402
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor  # noqa: E402
from torch import nn  # noqa: E402

from amaze.agents.network_inputs import pool_matrix  # noqa: E402
from rl_baselines.jax.hyperparameters import checked_hyperparameters  # noqa: E402
from rl_baselines.jax.networks import (  # noqa: E402
    action_entropy,
    action_log_prob,
    apply,
    init_params,
    sample_actions,
)
from rl_baselines.jax.optim import AdamState, OptState, RMSpropState, init_optimizer  # noqa: E402
from rl_baselines.jax.spec import LOG_STD, network_spec  # noqa: E402
from rl_baselines.jax.update import Batch, a2c_update, flatten_rollout, ppo_update  # noqa: E402
from rl_baselines.vec_env import SB3VecEnv  # noqa: E402
from tests.rl_baselines.jax.sb3_reference import (  # noqa: E402
    GRAD_RTOL,
    MAZES,
    PARAMS_ATOL,
    PARAMS_RTOL,
    assert_trees_close,
    sb3_permutations,
)

ROBOT, VISION, POOL, HIDDEN = "CC7", 7, 3, 8
SPEC = network_spec(ROBOT, {"hidden": [HIDDEN], "pool": POOL})
N_ENVS = 4
#: ``log_std`` of the policy that fills the buffer (see the module docstring).
START_LOG_STD = (0.3, -0.4)


class PooledRetina(BaseFeaturesExtractor):
    """The ``network`` kind's features: the image's block means scaled to [0, 1], no parameters."""

    def __init__(self, observation_space: spaces.Box, vision: int, pool: int) -> None:
        super().__init__(observation_space, features_dim=pool * pool)
        matrix = torch.as_tensor(pool_matrix(vision, pool).astype(np.float32))
        self.register_buffer("pool_matrix", matrix)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        pixels = observations.float().reshape(observations.shape[0], -1)
        return pixels @ self.pool_matrix


class SquashedMeanPolicy(ActorCriticPolicy):
    """SB3's policy with the Gaussian's mean squashed: ``action_net`` is ``Linear`` then Tanh."""

    def _build(self, lr_schedule: Any) -> None:
        super()._build(lr_schedule)  # the optimizer holds the Linear's parameters already
        self.action_net = nn.Sequential(self.action_net, nn.Tanh())


POLICY_KWARGS = {
    "features_extractor_class": PooledRetina,
    "features_extractor_kwargs": {"vision": VISION, "pool": POOL},
    "normalize_images": False,  # the pool matrix divides by 255
    "net_arch": {"pi": [HIDDEN], "vf": [HIDDEN]},
    "activation_fn": nn.Tanh,
    "log_std_init": 0.0,
}

#: SB3's parameter of each JAX leaf: ``(module, kind)`` to the ``named_parameters`` name.
SB3_NAMES = {
    **{
        (module, kind): f"{'action_net.0' if module == 'action_net' else module}.{kind}"
        for module in SPEC.layer_shapes()
        for kind in ("weight", "bias")
    },
    (LOG_STD, "data"): "log_std",
}


def _sb3_model(algo: str, hps: dict[str, Any], seed: int) -> BaseAlgorithm:
    env = SB3VecEnv(MAZES, ROBOT, N_ENVS, seed=seed)
    algorithm = PPO if algo == "ppo" else A2C
    model = algorithm(
        SquashedMeanPolicy, env, policy_kwargs=POLICY_KWARGS, seed=seed, device="cpu", **hps
    )
    model.set_logger(configure(None, [""]))
    policy = model.policy
    with torch.no_grad():  # in place: the optimizer keeps these very tensors
        generator = torch.Generator().manual_seed(seed)
        linear = policy.action_net[0]
        linear.weight.add_(torch.randn(linear.weight.shape, generator=generator))
        linear.bias.add_(0.3 * torch.randn(linear.bias.shape, generator=generator))
        policy.log_std.copy_(torch.tensor(START_LOG_STD))
    return model


def _jax_params(policy: ActorCriticPolicy) -> dict[str, dict[str, jax.Array]]:
    """The SB3 policy's parameters by the JAX names (copies)."""
    named = dict(policy.named_parameters())
    params: dict[str, dict[str, jax.Array]] = {}
    for (module, kind), name in SB3_NAMES.items():
        value = named[name].detach().numpy().copy()
        params.setdefault(module, {})[kind] = jnp.asarray(value)
    return params


def _jax_opt_state(policy: ActorCriticPolicy, rms_prop: bool) -> OptState:
    """The SB3 policy's torch optimizer state by the JAX names."""
    named = dict(policy.named_parameters())
    state = policy.optimizer.state
    fields = ("square_avg",) if rms_prop else ("exp_avg", "exp_avg_sq")
    moments: dict[str, dict[str, dict[str, jax.Array]]] = {field: {} for field in fields}
    for (module, kind), name in SB3_NAMES.items():
        for field in fields:
            value = state[named[name]][field].numpy().copy()
            moments[field].setdefault(module, {})[kind] = jnp.asarray(value)
    step = jnp.int32(int(state[named["log_std"]]["step"]))
    if rms_prop:
        return RMSpropState(step, moments["square_avg"])
    return AdamState(step, moments["exp_avg"], moments["exp_avg_sq"])


def _fill(model: BaseAlgorithm, seed: int) -> None:
    """Fill the rollout buffer as ``collect_rollouts`` would, then returns and advantages."""
    rng = np.random.default_rng(seed)
    env, policy, buffer = model.env, model.policy, model.rollout_buffer
    buffer.reset()
    obs = env.reset()
    for step in range(model.n_steps):
        with torch.no_grad():
            mean = policy.get_distribution(torch.as_tensor(obs)).distribution.mean.numpy()
        std = np.exp(np.asarray(START_LOG_STD, np.float32))
        actions = (mean + 1.5 * std * rng.normal(size=mean.shape)).astype(np.float32)
        with torch.no_grad():
            values, log_prob, _ = policy.evaluate_actions(
                torch.as_tensor(obs), torch.as_tensor(actions)
            )
        noisy = log_prob + torch.as_tensor(rng.normal(0, 0.3, N_ENVS), dtype=torch.float32)
        rewards = rng.normal(0, 1, N_ENVS).astype(np.float32)
        starts = np.ones(N_ENVS) if step == 0 else rng.random(N_ENVS) < 0.2
        buffer.add(obs, actions, rewards, starts, values, noisy)
        obs, _, _, _ = env.step(np.clip(actions, -1, 1))
    with torch.no_grad():
        last_values = policy.predict_values(torch.as_tensor(obs))
    buffer.compute_returns_and_advantage(last_values=last_values, dones=rng.random(N_ENVS) < 0.3)
    assert np.any(np.abs(buffer.actions) > 1)  # unclipped samples are stored


def _batch(model: BaseAlgorithm) -> Batch:
    """The filled buffer flattened in SB3's order; actions float32 ``(N, 2)``."""
    b = model.rollout_buffer
    return Batch(
        observations=flatten_rollout(jnp.asarray(b.observations)),
        actions=flatten_rollout(jnp.asarray(b.actions, jnp.float32)),
        old_values=flatten_rollout(jnp.asarray(b.values)),
        old_log_prob=flatten_rollout(jnp.asarray(b.log_probs)),
        advantages=flatten_rollout(jnp.asarray(b.advantages)),
        returns=flatten_rollout(jnp.asarray(b.returns)),
    )


def test_the_sb3_policy_is_the_network_spec() -> None:
    """The SB3 stand-in has the spec's parameters, all in its optimizer, and its forward pass."""
    model = _sb3_model("ppo", {"n_steps": 8, "batch_size": 32}, seed=1)
    policy = model.policy
    named = dict(policy.named_parameters())
    assert set(named) == set(SB3_NAMES.values())  # the pool matrix is a buffer, not trained
    shapes = SPEC.layer_shapes()
    for (module, kind), name in SB3_NAMES.items():
        expected = (2,) if module == LOG_STD else shapes[module][: 1 if kind == "bias" else None]
        assert tuple(named[name].shape) == expected, name
    held = {id(p) for group in policy.optimizer.param_groups for p in group["params"]}
    assert held == {id(p) for p in policy.parameters()}  # wrapping kept action_net's Linear
    _fill(model, seed=2)
    params = _jax_params(policy)
    batch = _batch(model)
    for obs in (np.array(batch.observations), model.env.reset()):  # buffer floats, env bytes
        means, values = apply(SPEC, params, jnp.asarray(obs))
        with torch.no_grad():
            distribution = policy.get_distribution(torch.as_tensor(obs)).distribution
            sb3_values = policy.predict_values(torch.as_tensor(obs))[:, 0]
        np.testing.assert_allclose(means, distribution.mean.numpy(), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(values, sb3_values.numpy(), rtol=1e-5, atol=1e-6)
        assert np.max(np.abs(np.asarray(means))) > 0.5  # the squash is not linear here
    with torch.no_grad():
        _, log_prob, ent = policy.evaluate_actions(
            torch.as_tensor(np.array(batch.observations)), torch.as_tensor(np.array(batch.actions))
        )
    means, _ = apply(SPEC, params, batch.observations)
    got = action_log_prob(SPEC, params, means, batch.actions)
    np.testing.assert_allclose(got, log_prob.numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(action_entropy(SPEC, params, means), ent.numpy(), rtol=1e-6)


UPDATES = [
    ("ppo", {"n_steps": 16, "batch_size": 24, "n_epochs": 2, "ent_coef": 0.01}),
    ("a2c", {"n_steps": 8}),
]


# SB3 warns of PPO's shorter last minibatch (64 = 24 + 24 + 16), which is intended here
@pytest.mark.parametrize(("algo", "hps"), UPDATES)
@pytest.mark.filterwarnings("ignore:You have specified a mini-batch size")
def test_continuous_update_equals_sb3_train(algo: str, hps: dict[str, Any]) -> None:
    """Parameters (``log_std`` too), optimizer moments and logged figures after one update."""
    model = _sb3_model(algo, hps, seed=3)
    _fill(model, seed=4)
    hp = checked_hyperparameters(algo, hps, robot_images=True, n_envs=N_ENVS)
    rms_prop = algo == "a2c" and hp.use_rms_prop
    params = _jax_params(model.policy)
    opt_state = init_optimizer(params, rms_prop=rms_prop)
    batch = _batch(model)
    if algo == "ppo":
        permutations = sb3_permutations(model, hp.n_epochs, seed=11)
        params, opt_state, stats = ppo_update(SPEC, hp, params, opt_state, batch, permutations)
    else:
        sb3_permutations(model, 1, seed=11)
        params, opt_state, stats = a2c_update(SPEC, hp, params, opt_state, batch)
    model.train()

    expected_params = _jax_params(model.policy)
    assert_trees_close(params, expected_params, PARAMS_RTOL, PARAMS_ATOL)
    moved = np.asarray(expected_params[LOG_STD]["data"]) - np.asarray(START_LOG_STD, np.float32)
    assert np.all(np.abs(moved) > 1e-4)  # the update trains the standard deviations
    expected_state = _jax_opt_state(model.policy, rms_prop)
    assert type(opt_state) is type(expected_state)
    assert int(opt_state.step) == int(expected_state.step) > 0
    assert_trees_close(opt_state, expected_state, PARAMS_RTOL, PARAMS_ATOL)

    logged = model.logger.name_to_value
    policy_loss = "train/policy_gradient_loss" if algo == "ppo" else "train/policy_loss"
    std = jnp.exp(params[LOG_STD]["data"]).mean()
    figures = [
        (policy_loss, stats.policy_loss, 0.0),
        ("train/value_loss", stats.value_loss, 0.0),
        ("train/entropy_loss", stats.entropy_loss, 0.0),
        ("train/std", std, 0.0),
        ("train/explained_variance", stats.explained_variance, 1e-6),
    ]
    if algo == "ppo":
        figures += [
            ("train/approx_kl", stats.approx_kl, 1e-7),
            ("train/clip_fraction", stats.clip_fraction, 1e-7),
            ("train/loss", stats.loss, 1e-7),
        ]
        assert 0 < float(stats.clip_fraction) < 1  # the perturbed log-probabilities clip
        assert int(stats.gradient_steps) == int(opt_state.step) == 2 * 3  # 64 = 24 + 24 + 16
    for name, value, atol in figures:
        np.testing.assert_allclose(
            float(value), logged[name], rtol=GRAD_RTOL, atol=atol, err_msg=name
        )


def test_gaussian_log_prob_and_entropy_are_torchs() -> None:
    """``action_log_prob`` / ``action_entropy``: torch's ``Normal`` summed over the 2
    dimensions, values and gradients with respect to the means and ``log_std``."""
    rng = np.random.default_rng(0)
    n = 32
    means = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
    actions = (means + rng.normal(0, 1.5, (n, 2))).astype(np.float32)
    params = init_params(SPEC, jax.random.key(0))
    for log_std in (np.zeros(2, np.float32), rng.normal(0, 0.7, 2).astype(np.float32)):
        params[LOG_STD] = {"data": jnp.asarray(log_std)}

        def total_log_prob(p: Any, m: jax.Array) -> jax.Array:
            return action_log_prob(SPEC, p, m, jnp.asarray(actions)).sum()

        def total_entropy(p: Any, m: jax.Array) -> jax.Array:
            return action_entropy(SPEC, p, m).sum()

        t_mean = torch.tensor(means, requires_grad=True)
        t_log_std = torch.tensor(log_std, requires_grad=True)
        normal = torch.distributions.Normal(t_mean, torch.exp(t_log_std))
        t_log_prob = normal.log_prob(torch.as_tensor(actions)).sum(-1)
        t_entropy = normal.entropy().sum(-1)

        log_prob = action_log_prob(SPEC, params, jnp.asarray(means), jnp.asarray(actions))
        np.testing.assert_allclose(log_prob, t_log_prob.detach().numpy(), rtol=1e-6, atol=1e-6)
        entropy = action_entropy(SPEC, params, jnp.asarray(means))
        assert entropy.shape == (n,)
        np.testing.assert_allclose(entropy, t_entropy.detach().numpy(), rtol=1e-6, atol=1e-6)

        for jax_total, torch_total in ((total_log_prob, t_log_prob), (total_entropy, t_entropy)):
            grad_params, grad_means = jax.grad(jax_total, argnums=(0, 1))(
                params, jnp.asarray(means)
            )
            t_grad_log_std, t_grad_mean = torch.autograd.grad(
                torch_total.sum(), (t_log_std, t_mean), retain_graph=True, allow_unused=True
            )
            grad_log_std = np.asarray(grad_params[LOG_STD]["data"])
            assert np.all(np.abs(grad_log_std) > 1e-3)  # log_std is not detached
            np.testing.assert_allclose(grad_log_std, t_grad_log_std.numpy(), rtol=1e-5)
            expected_mean = np.zeros_like(means) if t_grad_mean is None else t_grad_mean.numpy()
            np.testing.assert_allclose(grad_means, expected_mean, rtol=1e-5, atol=1e-6)

        # the sampler's log-probabilities are the same density's
        outputs = jnp.asarray(means)
        sampled, sampled_log_prob = sample_actions(SPEC, params, outputs, jax.random.key(1))
        expected = torch.distributions.Normal(torch.as_tensor(means), torch.exp(t_log_std.detach()))
        np.testing.assert_allclose(
            sampled_log_prob,
            expected.log_prob(torch.as_tensor(np.array(sampled))).sum(-1).numpy(),
            rtol=1e-5,
            atol=1e-5,
        )
