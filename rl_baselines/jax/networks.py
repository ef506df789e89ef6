"""SB3's ``ActorCriticPolicy`` for AMaze robots in JAX: parameters, initialisation, forward.

The architecture is the one :func:`rl_baselines.learner.new_sb3_model` builds:

* ``DD`` (``MlpPolicy``): the 8 floats go through SB3's ``FlattenExtractor`` (no
  parameters), then two separate MLPs (``MlpExtractor``, SB3's default
  ``net_arch = dict(pi=[64, 64], vf=[64, 64])``, Tanh after each layer), the
  policy's ending in ``action_net`` (4 logits) and the value's in ``value_net``;
* hybrid robots (``CnnPolicy`` with :class:`rl_baselines.networks.SmallCNN`): the
  ``(1, v, v)`` uint8 image divided by 255 (SB3's ``preprocess_obs`` with
  ``normalize_images``), then 3x3 convolution (padding 1) to 16 channels, ReLU,
  3x3 convolution to 32, ReLU, 2x2 max-pool (floor), flatten (channel-major, as
  torch), linear to ``features_dim`` (64), ReLU; these features are shared by
  the policy and value MLPs (``share_features_extractor=True``).

**Initialisation** (``ActorCriticPolicy._build`` with ``ortho_init=True`` and
``BasePolicy.init_weights``): every ``nn.Linear`` and ``nn.Conv2d`` weight is
orthogonal (torch's ``orthogonal_``: the weight as a ``(out, in * k * k)`` matrix
with orthonormal rows or columns) with gain sqrt(2) in the features extractor
(the CNN's two convolutions and its linear layer) and in the MLPs, 0.01 in
``action_net`` and 1 in ``value_net``; every bias is 0. The draws are numpy's
(seeded by the JAX key), so the same distribution as torch's, not the same
numbers.

**Parameters** (:data:`Params`) are a dict keyed by SB3's module names, each
``{"weight": ..., "bias": ...}`` in torch's layout, so that a parameter is
``params[module][kind]`` = SB3's ``state_dict()[f"{module}.{kind}"]`` with no
transposition:

=================================  ===================================
key (SB3 ``state_dict`` prefix)    weight, bias shapes (DD / H15)
=================================  ===================================
``features_extractor.cnn.0``       ``(16, 1, 3, 3)``, ``(16,)``
``features_extractor.cnn.2``       ``(32, 16, 3, 3)``, ``(32,)``
``features_extractor.linear.0``    ``(64, 1568)``, ``(64,)``
``mlp_extractor.policy_net.0``     ``(64, 8 | 64)``, ``(64,)``
``mlp_extractor.policy_net.2``     ``(64, 64)``, ``(64,)``
``mlp_extractor.value_net.0``      ``(64, 8 | 64)``, ``(64,)``
``mlp_extractor.value_net.2``      ``(64, 64)``, ``(64,)``
``action_net``                     ``(4, 64)``, ``(4,)``
``value_net``                      ``(1, 64)``, ``(1,)``
=================================  ===================================

(the CNN's entries for hybrid robots only; SB3's state_dict repeats them as
``pi_features_extractor.*`` and ``vf_features_extractor.*``, the same tensors).
MLP layers are numbered ``0, 2, 4...`` as in SB3's ``nn.Sequential`` (Linear,
Tanh, Linear, ...).

A ``network`` kind's policy (:mod:`rl_baselines.jax.spec`) has the same
modules without the CNN: the MLPs read the 8 floats, the pooled retina or the
maps of its ``features_extractor.filters`` (3x3, slid with the spec's stride
over the image / 255, then the activation; ``(F, 1, 3, 3)``, ``(F,)``), with
the spec's activation; with rotations, ``action_net`` and ``value_net`` have
one output, scored on each of the four turned views (the logits of the four
directions; the value their mean); a convolution reads the image turned
``d`` quarter-turns clockwise for direction ``d``.

**Continuous robots** (``network`` kind only, :mod:`rl_baselines.jax.spec`):
:func:`apply` gives the Gaussian's mean, the accelerations evolution's network
of the same spec outputs (``tanh`` of ``action_net``'s 2 outputs, or with
rotations ``(tanh(s_E - s_W), tanh(s_N - s_S))``), and ``params["log_std"]``
holds SB3's ``log_std`` (``{"data": (2,)}``, zeros at the start). Actions are
drawn as SB3's ``DiagGaussianDistribution`` draws them (``mean + std * eps``,
kept unclipped for the log-probability; the environment clips them to
[-1, 1]); log-probabilities and entropies are torch's ``Normal``'s summed
over the two dimensions (:func:`action_log_prob`, :func:`action_entropy`).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from rl_baselines.jax.spec import (
    CONV1,
    CONV2,
    FILTERS,
    LINEAR,
    LOG_STD,
    N_ACCELERATIONS,
    N_ACTIONS,
    PolicySpec,
    accelerations,
)

__all__ = [
    "N_ACTIONS",
    "Params",
    "PolicySpec",
    "accelerations",
    "action_entropy",
    "action_log_prob",
    "apply",
    "as_numpy",
    "deterministic_actions",
    "entropy",
    "init_params",
    "log_probabilities",
    "predict_values",
    "sample_actions",
]

Params = dict[str, dict[str, jax.Array]]


def _orthogonal(rng: np.random.Generator, shape: tuple[int, ...], gain: float) -> np.ndarray:
    """torch's ``orthogonal_`` on a weight of ``shape`` (``(out, in, ...)``), numpy's draws.

    The weight as an ``(out, prod(rest))`` matrix: QR of a standard normal matrix
    (transposed when it is wide), columns signed by ``R``'s diagonal, times ``gain``.
    """
    rows = shape[0]
    cols = int(np.prod(shape[1:]))
    flat = rng.standard_normal((max(rows, cols), min(rows, cols)))
    q, r = np.linalg.qr(flat)
    q = q * np.sign(np.diag(r))
    if rows < cols:
        q = q.T
    return (gain * q).reshape(shape).astype(np.float32)


def init_params(spec: PolicySpec, key: jax.Array) -> Params:
    """Fresh parameters: SB3's orthogonal initialisation (see the module docstring).

    The draws are numpy's, from a generator seeded by ``key``'s data, and the QR
    decompositions numpy's, on the host: in JAX, each QR compiles apart
    (seconds per policy) for a few milliseconds of work.
    """
    seed = np.asarray(jax.random.key_data(key)).astype(np.uint32).ravel().tolist()
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    params = {
        module: {
            "weight": jnp.asarray(_orthogonal(rng, shape, spec.gain(module))),
            "bias": jnp.zeros((shape[0],), jnp.float32),
        }
        for module, shape in spec.layer_shapes().items()
    }
    if spec.continuous:  # SB3's log_std_init = 0
        params[LOG_STD] = {"data": jnp.zeros((N_ACCELERATIONS,), jnp.float32)}
    return params


def _linear(layer: dict[str, jax.Array], x: jax.Array) -> jax.Array:
    """torch's ``nn.Linear``: ``x @ weight.T + bias``."""
    return x @ layer["weight"].T + layer["bias"]


def _conv(layer: dict[str, jax.Array], x: jax.Array) -> jax.Array:
    """torch's ``nn.Conv2d(kernel_size=3, padding=1)`` on NCHW images.

    On CPU it is :func:`conv_patches`: XLA's CPU convolution runs about ten
    times slower inside a loop (the compiled rollout's and update's
    ``lax.scan``) than outside, and the patch product about seven times faster
    than it there (``benchmarks/bench_jax_rl.py --robot H15``). Elsewhere
    (GPU) it is XLA's convolution, :func:`conv_xla`.
    """
    conv = conv_patches if jax.default_backend() == "cpu" else conv_xla
    return conv(layer["weight"], x) + layer["bias"][None, :, None, None]


def conv_patches(weight: jax.Array, x: jax.Array) -> jax.Array:
    """A 3x3 convolution with padding 1 (no bias) as a matrix product of ``weight``
    ``(O, C, 3, 3)`` with the image's 3x3 patches (nine shifted slices of the padded
    image), NCHW in and out."""
    n, c, h, w = x.shape
    padded = jnp.pad(x, ((0, 0), (0, 0), (1, 1), (1, 1)))
    shifted = [padded[:, :, a : a + h, b : b + w] for a in range(3) for b in range(3)]
    patches = jnp.stack(shifted, axis=2).reshape(n, c * 9, h * w)
    y = jnp.einsum("ok,nkp->nop", weight.reshape(weight.shape[0], -1), patches)
    return y.reshape(n, weight.shape[0], h, w)


def conv_xla(weight: jax.Array, x: jax.Array) -> jax.Array:
    """The same convolution as :func:`conv_patches`, by ``lax.conv_general_dilated``."""
    return jax.lax.conv_general_dilated(
        x,
        weight,
        window_strides=(1, 1),
        padding=((1, 1), (1, 1)),
        dimension_numbers=("NCHW", "OIHW", "NCHW"),
    )


#: The hidden activations of a ``network`` kind's MLPs, by name.
_ACTIVATIONS = {
    "tanh": jnp.tanh,
    "relu": jax.nn.relu,
    "sigmoid": jax.nn.sigmoid,
    "identity": lambda x: x,
}


def _filter_maps(spec: PolicySpec, params: Params, obs: jax.Array) -> jax.Array:
    """A ``network`` kind's convolution: ``(n, filters x grid^2)`` maps, filter-major;
    with rotations ``(n, 4, filters x grid^2)``, those of the image turned ``d`` times."""
    patches = spec.filter_patches(obs, jnp)
    layer = params[FILTERS]
    weight = layer["weight"].reshape(spec.filters, -1)
    maps = jnp.einsum("fk,nkij->nfij", weight, patches) + layer["bias"][None, :, None, None]
    maps = _ACTIVATIONS[spec.activation](maps)
    shape = (obs.shape[0], 4, -1) if spec.copies == 4 else (obs.shape[0], -1)
    return maps.reshape(shape)


def _features(spec: PolicySpec, params: Params, obs: jax.Array) -> jax.Array:
    """SB3's ``extract_features``: the floats as they are, or SmallCNN on images / 255.

    A ``network`` kind: the 8 floats, the pooled retina or the filters' maps,
    and with rotations the four turned views, ``(n, 4, n_inputs)``.
    """
    if spec.kind == "network" and spec.filters:
        return _filter_maps(spec, params, obs)
    if spec.kind == "network":
        x = obs.astype(jnp.float32).reshape(obs.shape[0], -1)
        if spec.pool is not None:
            x = spec.pooled(x, jnp)
        if spec.copies == 4:
            x = x[:, jnp.asarray(spec.turns())]
        return x
    if not spec.images:
        return obs.astype(jnp.float32)
    x = obs.astype(jnp.float32) / 255.0
    x = jax.nn.relu(_conv(params[CONV1], x))
    x = jax.nn.relu(_conv(params[CONV2], x))
    x = jax.lax.reduce_window(x, -jnp.inf, jax.lax.max, (1, 1, 2, 2), (1, 1, 2, 2), "VALID")
    x = x.reshape(x.shape[0], -1)
    return jax.nn.relu(_linear(params[LINEAR], x))


def _mlp(spec: PolicySpec, params: Params, net: str, x: jax.Array) -> jax.Array:
    """One of ``MlpExtractor``'s nets: Linear and the activation (Tanh), once per layer."""
    activation = _ACTIVATIONS[spec.activation]
    layers = len(spec.net_pi if net == "policy_net" else spec.net_vf)
    for i in range(layers):
        x = activation(_linear(params[f"mlp_extractor.{net}.{2 * i}"], x))
    return x


def _values(spec: PolicySpec, params: Params, features: jax.Array) -> jax.Array:
    """``(n,)`` values of the features (with rotations, the mean over the four turns)."""
    values = _linear(params["value_net"], _mlp(spec, params, "value_net", features))[..., 0]
    return values.mean(axis=1) if spec.copies == 4 else values


def apply(spec: PolicySpec, params: Params, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``(logits (n, 4), values (n,))`` of a batch of observations (SB3's ``forward``).

    A continuous robot's policy gives its Gaussian's mean, ``(n, 2)``, instead
    of logits (:func:`accelerations`).
    """
    features = _features(spec, params, obs)
    outputs = _linear(params["action_net"], _mlp(spec, params, "policy_net", features))
    if spec.copies == 4:
        outputs = outputs[..., 0]
    if spec.continuous:
        outputs = accelerations(spec, outputs, jnp)
    return outputs, _values(spec, params, features)


def predict_values(spec: PolicySpec, params: Params, obs: jax.Array) -> jax.Array:
    """``(n,)`` values alone (SB3's ``predict_values``), without the policy's MLP."""
    return _values(spec, params, _features(spec, params, obs))


def log_probabilities(logits: jax.Array) -> jax.Array:
    """torch's ``Categorical(logits=...)`` normalised logits: ``logits - logsumexp``."""
    return logits - jax.nn.logsumexp(logits, axis=-1, keepdims=True)


def entropy(log_probs: jax.Array) -> jax.Array:
    """torch's ``Categorical.entropy`` from normalised logits: ``-sum(softmax(l) * l)``."""
    return -jnp.sum(log_probs * jax.nn.softmax(log_probs, axis=-1), axis=-1)


def deterministic_actions(logits: jax.Array) -> jax.Array:
    """SB3's ``CategoricalDistribution.mode``: ``argmax`` of the probabilities (first on ties)."""
    return jnp.argmax(jax.nn.softmax(logits, axis=-1), axis=-1)


def _gaussian_scale(params: Params) -> tuple[jax.Array, jax.Array]:
    """SB3's ``action_std = exp(log_std)`` and torch ``Normal``'s ``log(scale)``."""
    scale = jnp.exp(params[LOG_STD]["data"])
    return scale, jnp.log(scale)


def action_log_prob(
    spec: PolicySpec, params: Params, outputs: jax.Array, actions: jax.Array
) -> jax.Array:
    """``(n,)`` log-probabilities of ``actions`` under the distribution of :func:`apply`'s
    ``outputs``: a categorical's (logits), or the diagonal Gaussian's (mean), torch's
    ``Normal.log_prob`` summed over the two dimensions."""
    if not spec.continuous:
        log_probs = log_probabilities(outputs)
        return jnp.take_along_axis(log_probs, actions[:, None].astype(jnp.int32), axis=1)[:, 0]
    scale, log_scale = _gaussian_scale(params)
    log_prob = -((actions - outputs) ** 2) / (2 * scale**2) - log_scale - np.log(np.sqrt(2 * np.pi))
    return jnp.sum(log_prob, axis=1)


def action_entropy(spec: PolicySpec, params: Params, outputs: jax.Array) -> jax.Array:
    """``(n,)`` entropies of the distributions of :func:`apply`'s ``outputs`` (torch's
    ``Categorical.entropy``, or ``Normal.entropy`` summed over the two dimensions)."""
    if not spec.continuous:
        return entropy(log_probabilities(outputs))
    _, log_scale = _gaussian_scale(params)
    per_dimension = 0.5 + 0.5 * np.log(2 * np.pi) + log_scale
    return jnp.broadcast_to(jnp.sum(per_dimension), outputs.shape[:1])


def sample_actions(
    spec: PolicySpec, params: Params, outputs: jax.Array, key: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """Actions drawn from the distributions of :func:`apply`'s ``outputs``, with their
    log-probabilities: int32 ``(n,)`` (categorical), or float32 ``(n, 2)``
    (``mean + std * eps``, not clipped: the environment clips them)."""
    if not spec.continuous:
        actions = jax.random.categorical(key, outputs).astype(jnp.int32)
    else:
        scale, _ = _gaussian_scale(params)
        actions = outputs + scale * jax.random.normal(key, outputs.shape, outputs.dtype)
    return actions, action_log_prob(spec, params, outputs, actions)


def as_numpy(params: Any) -> dict[str, dict[str, np.ndarray]]:
    """Parameters as float32 numpy arrays (host copies)."""
    return {
        m: {k: np.asarray(v, np.float32) for k, v in layer.items()} for m, layer in params.items()
    }
