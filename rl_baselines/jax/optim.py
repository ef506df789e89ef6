"""torch's Adam, RMSprop and ``clip_grad_norm_`` as SB3 uses them, in JAX.

SB3's policies step ``torch.optim.Adam`` (``eps=1e-5``, SB3's
``ActorCriticPolicy.__init__``) or, for A2C, ``torch.optim.RMSprop(alpha=0.99,
eps=rms_prop_eps, weight_decay=0)`` (``a2c.py``), after
``torch.nn.utils.clip_grad_norm_(parameters, max_grad_norm)``. They are written
here operation by operation as torch runs them on CPU (its single-tensor code
paths, ``torch/optim/adam.py`` ``_single_tensor_adam`` and
``torch/optim/rmsprop.py`` ``_single_tensor_rmsprop``), rather than taken from
optax, whose ``adam`` and ``rmsprop`` round differently (optax's ``rmsprop``
puts ``eps`` inside the square root unless ``eps_in_sqrt=False``; its
``clip_by_global_norm`` divides by the norm without torch's ``1e-6``):

* Adam: ``m.lerp_(g, 1 - b1)``; ``v = v * b2 + (1 - b2) * g * g``;
  ``denom = sqrt(v) / sqrt(1 - b2^t) + eps``; ``p -= lr / (1 - b1^t) * m / denom``.
  torch computes the bias corrections in float64 on the host; here they are
  float32 (a relative difference of about ``1e-7 t``, far below float32 noise
  of the rest after a few steps);
* RMSprop: ``s = s * alpha + (1 - alpha) * g * g``; ``p -= lr * g / (sqrt(s) + eps)``
  (``eps`` outside the square root);
* ``clip_grad_norm_``: ``total = ||(||g_1||, ..., ||g_n||)||``; every gradient is
  multiplied by ``min(max_norm / (total + 1e-6), 1)``.

Optimizer states are pytrees of arrays: :class:`AdamState` (``step``, ``exp_avg``,
``exp_avg_sq``) and :class:`RMSpropState` (``step``, ``square_avg``), named as
torch's optimizer state so that they map to SB3's zips (:mod:`rl_baselines.jax.sb3_io`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

__all__ = [
    "ADAM_BETAS",
    "RMSPROP_ALPHA",
    "AdamState",
    "OptState",
    "RMSpropState",
    "adam_step",
    "clip_grad_norm",
    "init_optimizer",
    "optimizer_step",
    "rmsprop_step",
]

Params = Any

#: torch's Adam defaults, which SB3 keeps.
ADAM_BETAS = (0.9, 0.999)
#: SB3's A2C RMSprop smoothing constant (``a2c.py``: ``alpha=0.99``).
RMSPROP_ALPHA = 0.99


class AdamState(NamedTuple):
    """torch Adam's state: the step count and both moments, per parameter."""

    step: jax.Array
    exp_avg: Params
    exp_avg_sq: Params


class RMSpropState(NamedTuple):
    """torch RMSprop's state (no momentum, not centered): the step count and ``square_avg``."""

    step: jax.Array
    square_avg: Params


OptState = AdamState | RMSpropState


def init_optimizer(params: Params, rms_prop: bool) -> OptState:
    """A fresh state (zero moments, step 0) of RMSprop (``rms_prop``) or Adam."""
    zeros = jax.tree.map(jnp.zeros_like, params)
    step = jnp.zeros((), jnp.int32)
    if rms_prop:
        return RMSpropState(step, zeros)
    return AdamState(step, zeros, jax.tree.map(jnp.zeros_like, params))


def clip_grad_norm(grads: Params, max_norm: float) -> tuple[Params, jax.Array]:
    """torch's ``clip_grad_norm_``: the gradients scaled to a total norm within ``max_norm``.

    Returns the clipped gradients and the total norm before clipping. As torch,
    the norm of the per-tensor norms, and the scale ``max_norm / (total + 1e-6)``
    clamped at 1 (applied always, so a gradient within the limit is multiplied
    by 1).
    """
    leaves = jax.tree.leaves(grads)
    norms = jnp.stack([jnp.sqrt(jnp.sum(g * g)) for g in leaves])
    total = jnp.sqrt(jnp.sum(norms * norms))
    scale = jnp.minimum(max_norm / (total + 1e-6), 1.0)
    return jax.tree.map(lambda g: g * scale, grads), total


def _lerp(start: jax.Array, end: jax.Array, weight: float) -> jax.Array:
    """torch's ``lerp`` for a weight below 0.5: ``start + weight * (end - start)``."""
    return start + weight * (end - start)


def adam_step(
    params: Params, grads: Params, state: AdamState, lr: float, eps: float = 1e-5
) -> tuple[Params, AdamState]:
    """One step of torch's Adam (``_single_tensor_adam``, no weight decay, no amsgrad)."""
    beta1, beta2 = ADAM_BETAS
    step = state.step + 1
    t = step.astype(jnp.float32)
    bias_correction1 = 1 - jnp.float32(beta1) ** t
    bias_correction2 = 1 - jnp.float32(beta2) ** t
    step_size = lr / bias_correction1
    bias_correction2_sqrt = jnp.sqrt(bias_correction2)
    exp_avg = jax.tree.map(lambda m, g: _lerp(m, g, 1 - beta1), state.exp_avg, grads)
    exp_avg_sq = jax.tree.map(lambda v, g: v * beta2 + (1 - beta2) * g * g, state.exp_avg_sq, grads)

    def update(p: jax.Array, m: jax.Array, v: jax.Array) -> jax.Array:
        denom = jnp.sqrt(v) / bias_correction2_sqrt + eps
        return p - step_size * (m / denom)

    new = jax.tree.map(update, params, exp_avg, exp_avg_sq)
    return new, AdamState(step, exp_avg, exp_avg_sq)


def rmsprop_step(
    params: Params, grads: Params, state: RMSpropState, lr: float, eps: float
) -> tuple[Params, RMSpropState]:
    """One step of torch's RMSprop as SB3's A2C builds it (alpha 0.99, no momentum)."""
    alpha = RMSPROP_ALPHA
    square_avg = jax.tree.map(lambda s, g: s * alpha + (1 - alpha) * g * g, state.square_avg, grads)
    new = jax.tree.map(
        lambda p, g, s: p - lr * (g / (jnp.sqrt(s) + eps)), params, grads, square_avg
    )
    return new, RMSpropState(state.step + 1, square_avg)


def optimizer_step(
    params: Params,
    grads: Params,
    state: OptState,
    *,
    lr: float,
    max_grad_norm: float,
    rms_prop_eps: float,
) -> tuple[Params, OptState, jax.Array]:
    """Clip the gradients (torch's ``clip_grad_norm_``), then step the optimizer of ``state``.

    Returns the new params, the new state and the gradients' norm before clipping.
    """
    grads, norm = clip_grad_norm(grads, max_grad_norm)
    if isinstance(state, RMSpropState):
        params, state = rmsprop_step(params, grads, state, lr, rms_prop_eps)
    else:
        params, state = adam_step(params, grads, state, lr)
    return params, state, norm
