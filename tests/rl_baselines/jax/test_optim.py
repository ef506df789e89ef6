"""torch's Adam, RMSprop and ``clip_grad_norm_`` against the JAX ones, step by step.

Same parameters and gradients on both sides (a few tensors of SB3's shapes,
gradients of very different magnitudes so that ``eps`` matters, a new
gradient each step); after each clipped step the parameters and the
optimizer's moments must agree within float32 rounding.
"""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")
torch = pytest.importorskip("torch")

from rl_baselines.jax.optim import (  # noqa: E402
    AdamState,
    RMSpropState,
    clip_grad_norm,
    init_optimizer,
    optimizer_step,
)

SHAPES = {"a": (64, 8), "b": (64,), "c": (4, 64), "d": (1,)}
STEPS = 6


def _draws(seed: int) -> tuple[dict[str, np.ndarray], list[dict[str, np.ndarray]]]:
    """Parameters and ``STEPS`` gradients; gradient scales from 1e-7 to 10 across entries."""
    rng = np.random.default_rng(seed)
    params = {k: rng.normal(0, 0.5, s).astype(np.float32) for k, s in SHAPES.items()}
    grads = [
        {
            k: (rng.normal(0, 1, s) * 10.0 ** rng.uniform(-7, 1, s)).astype(np.float32)
            for k, s in SHAPES.items()
        }
        for _ in range(STEPS)
    ]
    return params, grads


def _torch_run(
    params: dict[str, np.ndarray], grads: list[dict[str, np.ndarray]], rms: bool, max_norm: float
) -> tuple[dict[str, np.ndarray], dict[str, dict[str, np.ndarray]]]:
    """torch's optimizer as SB3 builds it: PPO's Adam(eps=1e-5), A2C's RMSprop(0.99, 1e-5)."""
    tensors = {k: torch.tensor(v, requires_grad=True) for k, v in params.items()}
    if rms:
        optimizer = torch.optim.RMSprop(
            tensors.values(), lr=7e-4, alpha=0.99, eps=1e-5, weight_decay=0
        )
    else:
        optimizer = torch.optim.Adam(tensors.values(), lr=3e-4, eps=1e-5)
    for grad in grads:
        optimizer.zero_grad()
        for k, t in tensors.items():
            t.grad = torch.tensor(grad[k])
        torch.nn.utils.clip_grad_norm_(tensors.values(), max_norm)
        optimizer.step()
    state = {
        k: {name: v.numpy() for name, v in optimizer.state[t].items() if name != "step"}
        for k, t in tensors.items()
    }
    return {k: t.detach().numpy() for k, t in tensors.items()}, state


@pytest.mark.parametrize("rms", [False, True], ids=["adam", "rmsprop"])
@pytest.mark.parametrize("max_norm", [0.5, 1e9], ids=["clipped", "unclipped"])
def test_optimizer_steps_equal_torch(rms: bool, max_norm: float) -> None:
    params, grads = _draws(seed=int(rms) + 2 * int(max_norm > 1))
    expected, torch_state = _torch_run(params, grads, rms, max_norm)
    current = jax.tree.map(jax.numpy.asarray, params)
    state = init_optimizer(current, rms_prop=rms)
    step = jax.jit(
        lambda p, g, s: optimizer_step(
            p, g, s, lr=7e-4 if rms else 3e-4, max_grad_norm=max_norm, rms_prop_eps=1e-5
        )
    )
    for grad in grads:
        current, state, _ = step(current, grad, state)
    assert isinstance(state, RMSpropState if rms else AdamState)
    assert int(state.step) == STEPS
    for k in SHAPES:
        np.testing.assert_allclose(np.asarray(current[k]), expected[k], rtol=1e-6, atol=1e-7)
        for name, value in torch_state[k].items():
            np.testing.assert_allclose(
                np.asarray(getattr(state, name)[k]), value, rtol=1e-5, atol=1e-12, err_msg=name
            )


def test_clip_grad_norm_equals_torch() -> None:
    """The clipped gradients and the norm before clipping, as ``clip_grad_norm_`` returns."""
    _, grads = _draws(seed=5)
    grad = grads[0]
    tensors = [torch.zeros(s, requires_grad=True) for s in SHAPES.values()]
    for t, k in zip(tensors, SHAPES, strict=True):
        t.grad = torch.tensor(grad[k])
    norm = torch.nn.utils.clip_grad_norm_(tensors, 0.5)
    clipped, total = clip_grad_norm(jax.tree.map(jax.numpy.asarray, grad), 0.5)
    np.testing.assert_allclose(float(total), float(norm), rtol=1e-6)
    assert float(total) > 0.5  # the clipping is active
    for t, k in zip(tensors, SHAPES, strict=True):
        np.testing.assert_allclose(np.asarray(clipped[k]), t.grad.numpy(), rtol=1e-6, atol=1e-12)
