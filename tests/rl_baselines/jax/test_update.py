"""PPO and A2C updates in JAX against SB3's ``train()`` on the same buffer and minibatches.

SB3's side is SB3's own code: its ``RolloutBuffer`` filled with a rollout
(``sb3_reference.filled_model``), numpy's permutations fixed, ``model.train()``.
The JAX update starts from the same parameters (copied from the SB3 policy) and
takes the same permutations. Compared: the gradients (SB3's ``.grad`` after a
one-minibatch update whose clipping is a no-op), the logged losses, and the
parameters and optimizer moments after whole updates (several minibatches
and epochs, gradient clipping active, Adam or RMSprop).
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np
import pytest

from rl_baselines.jax.optim import init_optimizer
from rl_baselines.jax.sb3_io import opt_state_from_sb3, params_from_sb3
from rl_baselines.jax.update import a2c_loss, a2c_update, ppo_loss, ppo_update
from tests.rl_baselines.jax.sb3_reference import (
    GRAD_ATOL,
    GRAD_RTOL,
    PARAMS_ATOL,
    PARAMS_RTOL,
    assert_trees_close,
    filled_model,
    jax_batch,
    sb3_permutations,
    spec_and_hp,
)


def _jax_update(model: Any, algo: str, robot: str, hps: dict[str, Any], seed: int) -> tuple:
    """The JAX update from the model's current parameters; the SB3 permutations armed."""
    spec, hp = spec_and_hp(algo, robot, hps, model.n_envs)
    params = params_from_sb3(model, spec)
    opt_state = init_optimizer(params, rms_prop=algo == "a2c" and hp.use_rms_prop)
    batch = jax_batch(model)
    if algo == "ppo":
        permutations = sb3_permutations(model, hp.n_epochs, seed)
        return spec, ppo_update(spec, hp, params, opt_state, batch, permutations)
    sb3_permutations(model, 1, seed)
    return spec, a2c_update(spec, hp, params, opt_state, batch)


UPDATES = [
    (
        "ppo",
        "DD",
        {"n_steps": 16, "batch_size": 24, "n_epochs": 2, "clip_range_vf": 0.1, "ent_coef": 0.01},
    ),
    ("ppo", "DD", {"n_steps": 16, "batch_size": 16, "n_epochs": 2, "normalize_advantage": False,
                   "gamma": 0.9, "gae_lambda": 0.8, "clip_range": 0.1, "vf_coef": 0.7}),
    ("ppo", "H15", {"n_steps": 8, "batch_size": 16, "n_epochs": 2}),
    ("a2c", "DD", {}),
    ("a2c", "DD", {"n_steps": 8, "use_rms_prop": False, "normalize_advantage": True,
                   "ent_coef": 0.05, "gae_lambda": 0.9}),
    ("a2c", "DD", {"n_steps": 8, "rms_prop_eps": 1e-3, "learning_rate": 1e-2}),
    ("a2c", "H15", {"n_steps": 5}),
]  # fmt: skip


@pytest.mark.parametrize(("algo", "robot", "hps"), UPDATES)
def test_update_equals_sb3_train(algo: str, robot: str, hps: dict[str, Any]) -> None:
    """Parameters, optimizer moments and logged losses after one whole update."""
    model = filled_model(algo, robot, hps, seed=3)
    spec, (params, opt_state, stats) = _jax_update(model, algo, robot, hps, seed=11)
    model.train()
    assert_trees_close(params, params_from_sb3(model, spec), PARAMS_RTOL, PARAMS_ATOL)
    expected_state = opt_state_from_sb3(
        model, params, rms_prop=type(opt_state).__name__ != "AdamState"
    )
    assert int(opt_state.step) == int(expected_state.step) > 0
    assert_trees_close(opt_state, expected_state, PARAMS_RTOL, PARAMS_ATOL)
    logged = model.logger.name_to_value
    prefix = "train/policy_gradient_loss" if algo == "ppo" else "train/policy_loss"
    for name, value in ((prefix, stats.policy_loss), ("train/value_loss", stats.value_loss),
                        ("train/entropy_loss", stats.entropy_loss),
                        ("train/explained_variance", stats.explained_variance)):  # fmt: skip
        # explained variance is 1 - Var(returns - values) / Var(returns): near 0 the ratio
        # is near 1, so float32's rounding of it (about 1e-7 of 1) is an absolute error
        atol = 1e-6 if name == "train/explained_variance" else 0.0
        np.testing.assert_allclose(
            float(value), logged[name], rtol=GRAD_RTOL, atol=atol, err_msg=name
        )
    if algo == "ppo":
        for name in ("approx_kl", "clip_fraction", "loss"):
            np.testing.assert_allclose(
                float(getattr(stats, name)), logged[f"train/{name}"], rtol=GRAD_RTOL, atol=1e-7
            )
        assert stats.clip_fraction > 0  # the perturbed log-probabilities exercise the clipping


def test_target_kl_stops_as_sb3() -> None:
    """With a small ``target_kl``, both stop at the same minibatch (SB3's early stop)."""
    # The perturbed log-probabilities give approximate KLs of 0.02 to 0.061 over the 12
    # minibatches; 1.5 x 0.039 stops at the first above 0.0585, the 10th (epoch 3).
    hps = {"n_steps": 16, "batch_size": 16, "n_epochs": 3, "target_kl": 0.039}
    model = filled_model("ppo", "DD", hps, seed=5)
    spec, (params, opt_state, stats) = _jax_update(model, "ppo", "DD", hps, seed=2)
    model.train()
    steps = int(stats.gradient_steps)
    assert steps == 9  # stopped early, in the last epoch
    assert int(opt_state.step) == steps
    assert_trees_close(params, params_from_sb3(model, spec), PARAMS_RTOL, PARAMS_ATOL)
    sb3_steps = int(model.policy.optimizer.state_dict()["state"][0]["step"])
    assert sb3_steps == steps


def _sb3_gradients(model: Any, spec: Any) -> dict[str, dict[str, np.ndarray]]:
    """SB3's ``.grad`` of every parameter, by the JAX names."""
    grads: dict[str, dict[str, np.ndarray]] = {}
    for name, parameter in model.policy.named_parameters():
        module, kind = name.rsplit(".", 1)
        grads.setdefault(module, {})[kind] = parameter.grad.detach().numpy()
    return grads


@pytest.mark.parametrize(
    ("algo", "robot", "hps"),
    [
        ("ppo", "DD", {"n_steps": 16, "batch_size": 64, "n_epochs": 1, "ent_coef": 0.02,
                       "vf_coef": 0.3, "clip_range_vf": 0.2}),
        ("a2c", "DD", {"n_steps": 8, "ent_coef": 0.02}),
        ("a2c", "H15", {"n_steps": 5}),
    ],
)  # fmt: skip
def test_gradients_equal_sb3(algo: str, robot: str, hps: dict[str, Any]) -> None:
    """The loss's gradient: one minibatch over the whole rollout, clipping out of the way."""
    hps = {**hps, "max_grad_norm": 1e9}
    model = filled_model(algo, robot, hps, seed=7)
    spec, hp = spec_and_hp(algo, robot, hps, model.n_envs)
    params = params_from_sb3(model, spec)
    batch = jax_batch(model)
    if algo == "ppo":
        permutation = sb3_permutations(model, 1, seed=4)[0]
        batch = jax.tree.map(lambda x: x[permutation], batch)
        grad_fn = jax.jit(jax.grad(ppo_loss, has_aux=True), static_argnums=(1, 2))
    else:
        sb3_permutations(model, 1, seed=4)
        grad_fn = jax.jit(jax.grad(a2c_loss, has_aux=True), static_argnums=(1, 2))
    grads, _ = grad_fn(params, spec, hp, batch)
    model.train()
    assert_trees_close(grads, _sb3_gradients(model, spec), GRAD_RTOL, GRAD_ATOL)
