"""SB3's returns, advantages, losses and updates of A2C and PPO, in JAX.

Each function follows one definition of stable-baselines3 2.x:

* :func:`compute_returns_and_advantage`: ``RolloutBuffer.compute_returns_and_advantage``
  (``common/buffers.py``): GAE(lambda) with SB3's ``episode_starts`` (an
  episode starts at step ``t`` when the previous step ended one, so the value
  after step ``t`` is not bootstrapped when ``episode_starts[t + 1]``, or the
  last ``dones`` for the last step), in SB3's order of float32 operations;
* :func:`flatten_rollout`: ``BaseBuffer.swap_and_flatten``: ``(n_steps, n_envs, ...)``
  to ``(n_envs * n_steps, ...)``, environment-major;
* :func:`ppo_update`: ``PPO.train`` (``ppo/ppo.py``): ``n_epochs`` passes, each
  over the minibatches of one permutation of the rollout (SB3's
  ``RolloutBuffer.get``: ``indices[start : start + batch_size]``, the last one
  shorter when ``batch_size`` does not divide the rollout), per-minibatch
  advantage normalisation (``(a - mean) / (std + 1e-8)``, torch's unbiased
  ``std``, skipped for a minibatch of one), the clipped surrogate, the value
  loss (clipped around the old values when ``clip_range_vf`` is set), the
  entropy loss, ``loss = policy + ent_coef * entropy + vf_coef * value``,
  torch's ``clip_grad_norm_`` and Adam; with ``target_kl``, SB3's early stop:
  a minibatch whose approximate KL (before its step) exceeds ``1.5 * target_kl``
  is not stepped and ends the update;
* :func:`a2c_update`: ``A2C.train`` (``a2c/a2c.py``): one gradient step on the
  whole rollout, ``policy_loss = -mean(advantage * log_prob)``, optional
  advantage normalisation (off by default), RMSprop or Adam.

The permutations are arguments (the trainer draws them with ``jax.random``),
so that a test can hand SB3's ``np.random.permutation`` to both sides.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from rl_baselines.jax.hyperparameters import Hyperparameters
from rl_baselines.jax.networks import (
    Params,
    PolicySpec,
    action_entropy,
    action_log_prob,
    apply,
)
from rl_baselines.jax.optim import OptState, optimizer_step

__all__ = [
    "Batch",
    "LossTerms",
    "UpdateStats",
    "a2c_loss",
    "a2c_update",
    "compute_returns_and_advantage",
    "explained_variance",
    "flatten_rollout",
    "ppo_loss",
    "ppo_update",
]


class Batch(NamedTuple):
    """A rollout flattened in SB3's order (:func:`flatten_rollout`), as ``RolloutBufferSamples``."""

    observations: jax.Array
    actions: jax.Array
    old_values: jax.Array
    old_log_prob: jax.Array
    advantages: jax.Array
    returns: jax.Array


class LossTerms(NamedTuple):
    """What SB3 logs of one loss evaluation (``train/...``); PPO's two last are NaN for A2C."""

    policy_loss: jax.Array
    value_loss: jax.Array
    entropy_loss: jax.Array
    approx_kl: jax.Array
    clip_fraction: jax.Array


class UpdateStats(NamedTuple):
    """One update's figures, as SB3's ``train()`` records them.

    ``policy_loss``, ``value_loss``, ``entropy_loss``, ``clip_fraction``: means over
    the minibatches evaluated (all epochs); ``approx_kl``: mean over the last
    epoch's (SB3 logs ``approx_kl_divs`` of the last epoch); ``loss``: the last
    minibatch's total loss; ``gradient_steps``: steps taken (fewer than
    ``n_epochs x minibatches`` after a ``target_kl`` stop); ``explained_variance``
    of the rollout's values for its returns.
    """

    policy_loss: jax.Array
    value_loss: jax.Array
    entropy_loss: jax.Array
    approx_kl: jax.Array
    clip_fraction: jax.Array
    loss: jax.Array
    gradient_steps: jax.Array
    explained_variance: jax.Array


def compute_returns_and_advantage(
    rewards: jax.Array,
    values: jax.Array,
    episode_starts: jax.Array,
    last_values: jax.Array,
    dones: jax.Array,
    gamma: float,
    gae_lambda: float,
) -> tuple[jax.Array, jax.Array]:
    """``(advantages, returns)``, ``(n_steps, n_envs)`` float32, as SB3's RolloutBuffer.

    ``episode_starts[t]`` is 1 where step ``t`` starts an episode (SB3's
    ``_last_episode_starts``: the previous step's ``dones``); ``last_values`` are
    the values of the observations after the last step, ``dones`` its ends.
    """
    starts = episode_starts.astype(jnp.float32)
    next_non_terminal = jnp.concatenate(
        [1.0 - starts[1:], (1.0 - dones.astype(jnp.float32))[None]], axis=0
    )
    next_values = jnp.concatenate([values[1:], last_values[None]], axis=0)
    decay = gamma * gae_lambda  # a Python float, as SB3's ``self.gamma * self.gae_lambda``

    def back(last_gae_lam: jax.Array, step: tuple[jax.Array, ...]) -> tuple[jax.Array, jax.Array]:
        reward, value, next_value, non_terminal = step
        delta = reward + gamma * next_value * non_terminal - value
        last_gae_lam = delta + decay * non_terminal * last_gae_lam
        return last_gae_lam, last_gae_lam

    zero = jnp.zeros_like(last_values)
    steps = (rewards, values, next_values, next_non_terminal)
    _, advantages = jax.lax.scan(back, zero, steps, reverse=True)
    return advantages, advantages + values


def flatten_rollout(x: jax.Array) -> jax.Array:
    """SB3's ``swap_and_flatten``: ``(n_steps, n_envs, ...)`` to ``(n_envs * n_steps, ...)``."""
    return jnp.swapaxes(x, 0, 1).reshape(x.shape[0] * x.shape[1], *x.shape[2:])


def explained_variance(values: jax.Array, returns: jax.Array) -> jax.Array:
    """SB3's ``explained_variance(y_pred, y_true)``: ``1 - Var(y - y_pred) / Var(y)``, NaN if 0."""
    var_y = jnp.var(returns)
    return jnp.where(var_y == 0, jnp.nan, 1 - jnp.var(returns - values) / var_y)


def _mean(x: jax.Array, mask: jax.Array | None) -> jax.Array:
    """The mean of ``x``, or of its entries where ``mask`` (a shorter last minibatch)."""
    if mask is None:
        return jnp.mean(x)
    return jnp.sum(jnp.where(mask, x, 0.0)) / jnp.sum(mask)


def _normalized(advantages: jax.Array, mask: jax.Array | None) -> jax.Array:
    """``(a - a.mean()) / (a.std() + 1e-8)``, torch's unbiased std; unchanged for one sample."""
    count = advantages.shape[0] if mask is None else jnp.sum(mask)
    mean = _mean(advantages, mask)
    centred = advantages - mean
    squares = centred * centred if mask is None else jnp.where(mask, centred * centred, 0.0)
    std = jnp.sqrt(jnp.sum(squares) / (count - 1))
    return jnp.where(count > 1, centred / (std + 1e-8), advantages)


def _evaluate_actions(
    spec: PolicySpec, params: Params, batch: Batch
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """SB3's ``ActorCriticPolicy.evaluate_actions``: values, log-probabilities, entropies."""
    outputs, values = apply(spec, params, batch.observations)
    log_prob = action_log_prob(spec, params, outputs, batch.actions)
    return values, log_prob, action_entropy(spec, params, outputs)


def ppo_loss(
    params: Params,
    spec: PolicySpec,
    hp: Hyperparameters,
    batch: Batch,
    mask: jax.Array | None = None,
) -> tuple[jax.Array, LossTerms]:
    """PPO's loss on one minibatch (``PPO.train``), with its logged terms.

    ``mask`` marks the samples of a padded (shorter) last minibatch.
    """
    assert hp.clip_range is not None
    values, log_prob, ent = _evaluate_actions(spec, params, batch)
    advantages = batch.advantages
    if hp.normalize_advantage:
        advantages = _normalized(advantages, mask)
    ratio = jnp.exp(log_prob - batch.old_log_prob)
    policy_loss_1 = advantages * ratio
    policy_loss_2 = advantages * jnp.clip(ratio, 1 - hp.clip_range, 1 + hp.clip_range)
    policy_loss = -_mean(jnp.minimum(policy_loss_1, policy_loss_2), mask)
    clip_fraction = _mean((jnp.abs(ratio - 1) > hp.clip_range).astype(jnp.float32), mask)
    values_pred = values
    if hp.clip_range_vf is not None:
        values_pred = batch.old_values + jnp.clip(
            values - batch.old_values, -hp.clip_range_vf, hp.clip_range_vf
        )
    value_loss = _mean((batch.returns - values_pred) ** 2, mask)
    entropy_loss = -_mean(ent, mask)
    loss = policy_loss + hp.ent_coef * entropy_loss + hp.vf_coef * value_loss
    log_ratio = jax.lax.stop_gradient(log_prob - batch.old_log_prob)
    approx_kl = _mean((jnp.exp(log_ratio) - 1) - log_ratio, mask)
    return loss, LossTerms(policy_loss, value_loss, entropy_loss, approx_kl, clip_fraction)


def a2c_loss(
    params: Params, spec: PolicySpec, hp: Hyperparameters, batch: Batch
) -> tuple[jax.Array, LossTerms]:
    """A2C's loss on the whole rollout (``A2C.train``), with its logged terms."""
    values, log_prob, ent = _evaluate_actions(spec, params, batch)
    advantages = batch.advantages
    if hp.normalize_advantage:
        advantages = _normalized(advantages, None)
    policy_loss = -jnp.mean(advantages * log_prob)
    value_loss = jnp.mean((batch.returns - values) ** 2)
    entropy_loss = -jnp.mean(ent)
    loss = policy_loss + hp.ent_coef * entropy_loss + hp.vf_coef * value_loss
    nan = jnp.float32(jnp.nan)
    return loss, LossTerms(policy_loss, value_loss, entropy_loss, nan, nan)


def _step(
    hp: Hyperparameters, params: Params, grads: Params, opt_state: OptState
) -> tuple[Params, OptState]:
    params, opt_state, _ = optimizer_step(
        params,
        grads,
        opt_state,
        lr=hp.learning_rate,
        max_grad_norm=hp.max_grad_norm,
        rms_prop_eps=hp.rms_prop_eps,
    )
    return params, opt_state


def a2c_update(
    spec: PolicySpec, hp: Hyperparameters, params: Params, opt_state: OptState, batch: Batch
) -> tuple[Params, OptState, UpdateStats]:
    """One A2C update: one clipped gradient step on the whole rollout."""
    grad_fn = jax.value_and_grad(a2c_loss, has_aux=True)
    (loss, terms), grads = grad_fn(params, spec, hp, batch)
    params, opt_state = _step(hp, params, grads, opt_state)
    stats = UpdateStats(
        *terms,
        loss=loss,
        gradient_steps=jnp.int32(1),
        explained_variance=explained_variance(batch.old_values, batch.returns),
    )
    return params, opt_state, stats


def _flat_state(state: OptState) -> OptState:
    """The optimizer's moments each as one flat vector (as ``ravel_pytree`` of the params)."""
    moments = {f: ravel_pytree(getattr(state, f))[0] for f in state._fields if f != "step"}
    return state._replace(**moments)


def _unflat_state(state: OptState, unravel: Callable[[jax.Array], Params]) -> OptState:
    """The moments of :func:`_flat_state` back as parameter pytrees."""
    moments = {f: unravel(getattr(state, f)) for f in state._fields if f != "step"}
    return state._replace(**moments)


#: Per minibatch of an epoch: its terms, total loss, evaluated, stepped.
_EpochOut = tuple[LossTerms, jax.Array, jax.Array, jax.Array]


def _minibatches(
    hp: Hyperparameters, batch: Batch, permutation: jax.Array
) -> tuple[Batch, jax.Array | None]:
    """One epoch's minibatches, ``(n_minibatches, batch_size, ...)``, in SB3's order.

    Minibatch ``i`` holds the samples ``permutation[i * B : (i + 1) * B]``; when
    ``B`` does not divide the rollout, the last one is padded (with sample 0) and
    the mask (``(n_minibatches, B)``, else ``None``) marks its real samples.
    """
    size = permutation.shape[0]
    b = hp.batch_size
    count = -(-size // b)
    mask = None
    if count * b != size:
        permutation = jnp.concatenate([permutation, jnp.zeros(count * b - size, permutation.dtype)])
        mask = (jnp.arange(count * b) < size).reshape(count, b)
    shuffled = jax.tree.map(lambda x: x[permutation].reshape(count, b, *x.shape[1:]), batch)
    return shuffled, mask


def _epoch(
    spec: PolicySpec,
    hp: Hyperparameters,
    carry: tuple[Params, OptState, jax.Array],
    batch: Batch,
    permutation: jax.Array,
    unravel: Callable[[jax.Array], Params],
) -> tuple[tuple[jax.Array, OptState, jax.Array], _EpochOut]:
    """One epoch of ``PPO.train``: a step per minibatch while no KL stop has happened.

    ``carry`` is ``(params, opt_state, going)``, the parameters and moments as flat
    vectors (``unravel`` gives the parameters back): one optimizer step is then
    a dozen operations on one vector, not a dozen per parameter tensor, which
    on a CPU costs more than the tiny MLP's arithmetic. Returns per minibatch its terms,
    its total loss, whether SB3 evaluates it (no stop before it) and whether it
    is stepped (evaluated and not stopping).
    """
    minibatches, masks = _minibatches(hp, batch, permutation)

    def flat_loss(
        flat: jax.Array, minibatch: Batch, mask: jax.Array | None
    ) -> tuple[jax.Array, LossTerms]:
        return ppo_loss(unravel(flat), spec, hp, minibatch, mask)

    grad_fn = jax.value_and_grad(flat_loss, has_aux=True)

    def one(
        carry: tuple[Params, OptState, jax.Array], item: tuple[Batch, jax.Array | None]
    ) -> tuple[tuple[Params, OptState, jax.Array], _EpochOut]:
        params, opt_state, going = carry
        minibatch, mask = item
        (loss, terms), grads = grad_fn(params, minibatch, mask)
        new_params, new_state = _step(hp, params, grads, opt_state)
        if hp.target_kl is None:
            return (new_params, new_state, going), (terms, loss, going, going)
        take = going & ~(terms.approx_kl > 1.5 * hp.target_kl)
        params, opt_state = jax.tree.map(
            lambda new, old: jnp.where(take, new, old), (new_params, new_state), (params, opt_state)
        )
        return (params, opt_state, take), (terms, loss, going, take)

    return jax.lax.scan(one, carry, (minibatches, masks))


def ppo_update(
    spec: PolicySpec,
    hp: Hyperparameters,
    params: Params,
    opt_state: OptState,
    batch: Batch,
    permutations: jax.Array,
) -> tuple[Params, OptState, UpdateStats]:
    """One PPO update (``PPO.train``): ``n_epochs`` epochs, ``permutations[e]`` the e-th's order.

    ``permutations``: int32 ``(n_epochs, n_envs * n_steps)``.
    """

    flat, unravel = ravel_pytree(params)
    flat_state = _flat_state(opt_state)

    def epoch(
        carry: tuple[jax.Array, OptState, jax.Array], permutation: jax.Array
    ) -> tuple[tuple[jax.Array, OptState, jax.Array], _EpochOut]:
        return _epoch(spec, hp, carry, batch, permutation, unravel)

    carry = (flat, flat_state, jnp.bool_(True))
    (flat, flat_state, _), out = jax.lax.scan(epoch, carry, permutations)
    params, opt_state = unravel(flat), _unflat_state(flat_state, unravel)
    terms, losses, seen, taken = out
    weights = seen.astype(jnp.float32)  # (n_epochs, n_minibatches)
    count = jnp.sum(weights)

    def mean(x: jax.Array) -> jax.Array:
        return jnp.sum(x * weights) / count

    epochs_seen = jnp.sum(jnp.any(seen, axis=1))
    last = jnp.maximum(epochs_seen - 1, 0)  # the last epoch with an evaluated minibatch
    last_kl = jnp.sum(terms.approx_kl[last] * weights[last]) / jnp.sum(weights[last])
    flat_seen = seen.reshape(-1)
    last_loss = losses.reshape(-1)[jnp.maximum(jnp.sum(flat_seen) - 1, 0)]
    stats = UpdateStats(
        policy_loss=mean(terms.policy_loss),
        value_loss=mean(terms.value_loss),
        entropy_loss=mean(terms.entropy_loss),
        approx_kl=last_kl,
        clip_fraction=mean(terms.clip_fraction),
        loss=last_loss,
        gradient_steps=jnp.sum(taken.astype(jnp.int32)),
        explained_variance=explained_variance(batch.old_values, batch.returns),
    )
    return params, opt_state, stats
