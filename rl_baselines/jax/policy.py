"""A trained actor-critic policy in numpy, as a policy of the shared protocol.

:class:`NumpyPolicy` maps a batch of observations in the ``AMaze-v0`` format
(float32 ``(n, 8)`` or uint8 ``(n, 1, v, v)``) to the deterministic actions of
SB3's ``predict(obs, deterministic=True)``: the ``argmax`` of the action
probabilities (SB3's ``CategoricalDistribution.mode``), as int64 ``(n,)``; a
continuous robot's mean accelerations, float64 ``(n, 2)``. It
has a ``robot`` attribute, so :class:`amaze.evaluation.protocol.Evaluator` and
:func:`amaze.evaluation.policy.run_episodes` take it as they take an
:class:`~rl_baselines.agent.SB3Agent`.

The forward pass is the one of :mod:`rl_baselines.jax.networks`, in float32
numpy (the convolutions as matrix products of 3x3 patches): the evaluation
protocol calls a policy once per step with a few hundred observations at most,
where a jitted JAX call would cost its dispatch and a compilation per batch
size. Neither JAX nor torch is imported.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from amaze.agents.robot import Robot
from rl_baselines import RLConfigError
from rl_baselines.jax.spec import CONV1, CONV2, FILTERS, LINEAR, PolicySpec, accelerations

__all__ = ["NumpyPolicy"]


def _linear(layer: Mapping[str, np.ndarray], x: np.ndarray) -> np.ndarray:
    return x @ layer["weight"].T + layer["bias"]


#: The hidden activations of a ``network`` kind's MLPs, by name.
_ACTIVATIONS = {
    "tanh": np.tanh,
    "relu": lambda x: np.maximum(x, 0),
    "sigmoid": lambda x: 1 / (1 + np.exp(-x)),
    "identity": lambda x: x,
}


def _conv3x3(layer: Mapping[str, np.ndarray], x: np.ndarray) -> np.ndarray:
    """``nn.Conv2d(kernel_size=3, padding=1)`` on NCHW images, as one matrix product."""
    n, c, h, w = x.shape
    padded = np.pad(x, ((0, 0), (0, 0), (1, 1), (1, 1)))
    patches = np.stack(
        [padded[:, :, dy : dy + h, dx : dx + w] for dy in range(3) for dx in range(3)], axis=2
    ).reshape(n, c * 9, h * w)
    weight = layer["weight"].reshape(layer["weight"].shape[0], c * 9)
    out = np.matmul(weight, patches) + layer["bias"][None, :, None]
    return out.reshape(n, -1, h, w)


def _filter_maps(
    spec: PolicySpec, layer: Mapping[str, np.ndarray], observations: np.ndarray
) -> np.ndarray:
    """A ``network`` kind's convolution, as :mod:`rl_baselines.jax.networks` computes it."""
    patches = spec.filter_patches(observations, np)
    weight = layer["weight"].reshape(spec.filters, -1)
    maps = np.einsum("fk,nkij->nfij", weight, patches) + layer["bias"][None, :, None, None]
    maps = _ACTIVATIONS[spec.activation](maps).astype(np.float32)
    n = observations.shape[0]
    return maps.reshape(n, 4, -1) if spec.copies == 4 else maps.reshape(n, -1)


class NumpyPolicy:
    """Deterministic actions of an SB3 actor-critic's parameters (see the module docstring).

    ``params``: ``{module: {"weight", "bias"}}`` with SB3's names and torch's
    layout (:mod:`rl_baselines.jax.networks`), checked against ``spec``.
    ``actor_only``: the value modules may be missing (a ``network`` kind's
    agent file holds the actor alone); :meth:`logits_and_values` then fails.
    """

    def __init__(
        self,
        spec: PolicySpec,
        params: Mapping[str, Mapping[str, np.ndarray]],
        *,
        actor_only: bool = False,
    ) -> None:
        self.spec = spec
        self.robot: Robot = spec.parsed_robot
        self.params: dict[str, dict[str, np.ndarray]] = {}
        if spec.kind == "network" and not spec.filters:
            self._turns = spec.turns()
        for module, shape in spec.layer_shapes().items():
            layer = params.get(module)
            if layer is None and actor_only and "value_net" in module:
                continue
            if layer is None:
                raise RLConfigError(f"policy parameters: module {module!r} is missing")
            # C order whatever the source (a view read back from a file is transposed):
            # the product's BLAS kernel, and so its rounding, depends on the layout
            weight = np.ascontiguousarray(layer["weight"], np.float32)
            bias = np.ascontiguousarray(layer["bias"], np.float32)
            if weight.shape != shape or bias.shape != shape[:1]:
                raise RLConfigError(
                    f"policy parameters: {module} has weight {list(weight.shape)} and bias"
                    f" {list(bias.shape)}, not {list(shape)} and {list(shape[:1])}"
                )
            self.params[module] = {"weight": weight, "bias": bias}

    def _features(self, observations: np.ndarray) -> np.ndarray:
        x = np.asarray(observations)
        if self.spec.kind == "network" and self.spec.filters:
            return _filter_maps(self.spec, self.params[FILTERS], x)
        if self.spec.kind == "network":
            x = x.reshape(x.shape[0], -1).astype(np.float32)
            if self.spec.pool is not None:
                x = self.spec.pooled(x, np)
            return x[:, self._turns] if self.spec.copies == 4 else x
        if not self.spec.images:
            return x.astype(np.float32, copy=False).reshape(-1, 8)
        v = self.spec.observation_shape[-1]
        x = x.reshape(-1, 1, v, v).astype(np.float32) / np.float32(255.0)
        x = np.maximum(_conv3x3(self.params[CONV1], x), 0)
        x = np.maximum(_conv3x3(self.params[CONV2], x), 0)
        h = v // 2
        x = x[:, :, : 2 * h, : 2 * h].reshape(x.shape[0], x.shape[1], h, 2, h, 2).max(axis=(3, 5))
        return np.maximum(_linear(self.params[LINEAR], x.reshape(x.shape[0], -1)), 0)

    def _mlp(self, net: str, layers: int, x: np.ndarray) -> np.ndarray:
        activation = _ACTIVATIONS[self.spec.activation]
        for i in range(layers):
            x = activation(_linear(self.params[f"mlp_extractor.{net}.{2 * i}"], x))
        return x

    def logits(self, observations: np.ndarray) -> np.ndarray:
        """``(n, 4)`` float32 logits of a batch of observations (the actor alone); a
        continuous robot's ``action_net`` outputs before their tanh (``(n, 2)``, or with
        rotations the four directions' scores)."""
        features = self._features(observations)
        latent_pi = self._mlp("policy_net", len(self.spec.net_pi), features)
        logits = _linear(self.params["action_net"], latent_pi)
        return logits[..., 0] if self.spec.copies == 4 else logits

    def logits_and_values(self, observations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(logits (n, 4), values (n,))`` of a batch of observations, float32."""
        features = self._features(observations)
        latent_vf = self._mlp("value_net", len(self.spec.net_vf), features)
        values = _linear(self.params["value_net"], latent_vf)[..., 0]
        if self.spec.copies == 4:
            values = values.mean(axis=1)
        return self.logits(observations), values

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """Deterministic actions: int64 ``(n,)``, the most probable one (first on ties);
        a continuous robot's float64 ``(n, 2)`` accelerations, its Gaussian's mean."""
        logits = self.logits(observations)
        if self.spec.continuous:
            return accelerations(self.spec, logits, np).astype(np.float64)
        shifted = np.exp(logits - logits.max(axis=1, keepdims=True))
        probabilities = shifted / shifted.sum(axis=1, keepdims=True)
        return probabilities.argmax(axis=1).astype(np.int64)
