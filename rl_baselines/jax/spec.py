"""The architecture of an actor-critic policy for an AMaze robot, without JAX.

:class:`PolicySpec` says which modules a policy has and their shapes (torch's
layout, SB3's names); :mod:`rl_baselines.jax.networks` builds and runs them in
JAX, :mod:`rl_baselines.jax.policy` in numpy. It imports no JAX, so that a
trained policy can be evaluated without loading JAX.

Two kinds of policy:

* ``sb3`` (the default): SB3's ``MlpPolicy`` (DD) or ``CnnPolicy`` with
  :class:`~rl_baselines.networks.SmallCNN` (hybrid robots), Tanh; an agent is
  saved as an SB3 zip;
* ``network``: the fixed-topology network of evolution's ``network`` spec
  (:mod:`amaze.agents.network_inputs`): the 8 floats, the pooled retina or
  the feature maps of ``filters`` 3x3 filters slid with ``stride`` (shared by
  the actor and the critic, as SB3 shares its features extractor), hidden
  layers of ``activation``, and with ``symmetry = "rotations"`` one
  network scored on each turned view (the actor's logit of direction ``d``
  from the inputs turned ``d`` quarter-turns, the critic the mean of its
  four turned values, so invariant under turns). The actor is exactly an
  evolved network of the same spec: an agent is saved as an evolved agent's
  file (:meth:`PolicySpec.architecture`, :meth:`PolicySpec.actor_vector`).

**Continuous robots** (``CC<v>``: accelerations out) have a ``network`` kind
policy only. Its actor is evolution's: ``action_net`` gives 2 outputs squashed
by tanh (with rotations its single output per turned view, the acceleration
``(tanh(s_E - s_W), tanh(s_N - s_S))``), the mean of SB3's diagonal Gaussian
(``DiagGaussianDistribution``), whose log standard deviations are one more
parameter, :data:`LOG_STD` (SB3's ``log_std``, 0 at the start: a standard
deviation of 1). The deterministic action is the mean, what the evolved
network of the same spec does; an SB3 policy (a linear mean, no squash) is not
offered, so that every agent it trains is an evolved agent's file.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from amaze.agents.network_inputs import (
    ACTIVATIONS,
    DEFAULT_POOL,
    FILTER_SIDE,
    MAX_FILTERS,
    POOLINGS,
    SYMMETRIES,
    default_stride,
    grid_side,
    pool_blocks,
    pool_matrix,
    pooling_problem,
    pools_maxima,
    rotation_index,
    stride_problem,
)
from amaze.agents.robot import Robot, as_robot
from amaze.validation import check_integer, check_layer_widths, closest
from rl_baselines import RLConfigError

__all__ = [
    "CONV1",
    "CONV2",
    "FILTERS",
    "KINDS",
    "LINEAR",
    "LOG_STD",
    "N_ACCELERATIONS",
    "N_ACTIONS",
    "PolicySpec",
    "accelerations",
    "network_spec",
]

#: Discrete actions of AMaze's robots: E, N, W, S.
N_ACTIONS = 4
#: A continuous robot's action: its acceleration (x east, y north).
N_ACCELERATIONS = 2
#: The Gaussian's log standard deviations of a continuous robot's policy (SB3's name).
LOG_STD = "log_std"
#: SB3's initialisation gains (``ActorCriticPolicy._build``).
GAIN_HIDDEN = float(np.sqrt(2))
GAIN_ACTION = 0.01
GAIN_VALUE = 1.0
#: The modules of SmallCNN (``rl_baselines/networks.py``) by their SB3 names.
CONV1, CONV2, LINEAR = (
    "features_extractor.cnn.0",
    "features_extractor.cnn.2",
    "features_extractor.linear.0",
)
#: The ``network`` kind's convolution (its ``filters``), shared by the actor and the critic.
FILTERS = "features_extractor.filters"
#: The kinds of policy (see the module docstring).
KINDS: tuple[str, ...] = ("sb3", "network")
#: The keys of a ``network`` spec in a config (evolution's, less its robot).
NETWORK_KEYS: tuple[str, ...] = (
    "hidden",
    "activation",
    "pool",
    "symmetry",
    "filters",
    "stride",
    "pooling",
)


@dataclass(frozen=True)
class PolicySpec:
    """The architecture of one policy: robot, MLP layers, inputs (hashable, static).

    ``robot`` is a robot string: ``DD``, ``H<v>``, or ``CC<v>`` with a ``network`` kind;
    ``net_pi`` / ``net_vf`` the hidden widths of the policy and value MLPs;
    ``features_dim`` the CNN's output width (``sb3`` kind, hybrid robots);
    ``kind``, ``activation``, ``symmetry``, ``pool``, ``pooling``, ``filters``
    and ``stride`` as the module docstring says (``sb3``: tanh, no symmetry,
    no pool, no filters).
    """

    robot: str = "DD"
    net_pi: tuple[int, ...] = (64, 64)
    net_vf: tuple[int, ...] = (64, 64)
    features_dim: int = 64
    kind: str = "sb3"
    activation: str = "tanh"
    symmetry: str = "none"
    pool: int | None = None
    filters: int = 0
    stride: int | None = None
    pooling: str = POOLINGS[0]

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise RLConfigError(f"policy kind {self.kind!r} is not one of {', '.join(KINDS)}")
        if self.kind == "sb3" and (
            self.activation,
            self.symmetry,
            self.pool,
            self.filters,
            self.pooling,
        ) != ("tanh", "none", None, 0, POOLINGS[0]):
            raise RLConfigError(
                "an SB3 policy has tanh, no symmetry, no pool and no filters (a network spec"
                " gives them)"
            )
        if self.kind == "sb3" and self.continuous:
            raise RLConfigError(
                f"robot {self.robot} has continuous actions: the JAX learners train them with"
                ' a network spec (give the config a network, e.g. {"hidden": [16],'
                ' "symmetry": "rotations"})'
            )

    @property
    def parsed_robot(self) -> Robot:
        return as_robot(self.robot)

    @property
    def continuous(self) -> bool:
        """Whether the robot's actions are accelerations (a Gaussian policy), not E/N/W/S."""
        return not self.parsed_robot.discrete_outputs

    @property
    def n_action_outputs(self) -> int:
        """Outputs of ``action_net``: 1 with rotations (a score per turned view), else 2
        (accelerations) or 4 (logits)."""
        if self.copies == 4:
            return 1
        return N_ACCELERATIONS if self.continuous else N_ACTIONS

    @property
    def images(self) -> bool:
        """Whether the policy reads images through a CNN (SB3's policy for a hybrid robot)."""
        return self.kind == "sb3" and not self.parsed_robot.discrete_inputs

    @property
    def copies(self) -> int:
        """Times the MLPs run per observation: 4 with rotations (one per direction), else 1."""
        return 4 if self.symmetry == "rotations" else 1

    @property
    def grid(self) -> int:
        """Side of the convolution's feature maps (``filters`` > 0)."""
        assert self.filters and self.stride is not None
        return grid_side(int(self.parsed_robot.vision), self.stride)

    def filter_patches(self, observations: Any, xp: Any) -> Any:
        """The 3x3 patches the filters read, ``(n x copies, 9, grid, grid)``, in ``xp``.

        ``observations``: uint8 images ``(n, 1, v, v)`` (or ``(n, v, v)``),
        scaled to [0, 1]; with rotations each turned ``d`` quarter-turns
        clockwise for direction ``d`` (image ``4 k + d``). ``xp`` is the array
        module (numpy, or ``jax.numpy`` inside the JAX learners) so that both
        forward passes read the same patches.
        """
        v = int(self.parsed_robot.vision)
        images = xp.asarray(observations).astype(xp.float32).reshape(-1, v, v) / 255.0
        if self.copies == 4:
            turned = [xp.rot90(images, -d, axes=(1, 2)) for d in range(4)]
            images = xp.stack(turned, axis=1).reshape(-1, v, v)
        stride = int(self.stride or 1)
        span = stride * (self.grid - 1) + 1
        sides = range(FILTER_SIDE)
        shifted = [
            images[:, a : a + span : stride, b : b + span : stride] for a in sides for b in sides
        ]
        return xp.stack(shifted, axis=1)

    @property
    def n_inputs(self) -> int:
        """Inputs of the MLPs (``network`` kind): the 8 floats, the pooled grid's cells or
        the feature maps' positions (``filters x grid^2``, filter-major)."""
        if self.filters:
            return self.filters * self.grid * self.grid
        return 8 if self.pool is None else self.pool * self.pool

    def turns(self) -> np.ndarray:
        """int64 ``(4, n_inputs)``: the inputs' gather of each quarter-turn (rotations)."""
        return rotation_index(self.pool)

    def pooled(self, pixels: Any, xp: Any) -> Any:
        """The pooled retina ``(n, pool * pool)`` of float32 ``pixels`` ``(n, v * v)`` (0..255).

        Block means (a product with :func:`~amaze.agents.network_inputs.pool_matrix`)
        or maxima (a gather of :func:`~amaze.agents.network_inputs.pool_blocks`),
        scaled to [0, 1], in ``xp`` (numpy or ``jax.numpy``), as evolution's encoder.
        """
        assert self.pool is not None
        vision = int(self.parsed_robot.vision)
        if pools_maxima(self.pooling):
            blocks = pool_blocks(vision, self.pool, self.pooling)
            brightest = pixels[:, xp.asarray(blocks)].max(axis=-1)
            return brightest * np.float32(1.0 / 255.0)
        means = pool_matrix(vision, self.pool, self.pooling).astype(np.float32)
        return pixels @ xp.asarray(means)

    @property
    def observation_shape(self) -> tuple[int, ...]:
        if not self.images:
            return (8,)
        v = int(self.parsed_robot.vision)
        return (1, v, v)

    def layer_shapes(self) -> dict[str, tuple[int, ...]]:
        """The weight shape (torch layout) of every module, in SB3's parameter order."""
        shapes: dict[str, tuple[int, ...]] = {}
        width = self.n_inputs
        if self.filters:
            shapes[FILTERS] = (self.filters, 1, FILTER_SIDE, FILTER_SIDE)
        if self.images:
            v = self.observation_shape[-1]
            shapes[CONV1] = (16, 1, 3, 3)
            shapes[CONV2] = (32, 16, 3, 3)
            shapes[LINEAR] = (self.features_dim, 32 * (v // 2) * (v // 2))
            width = self.features_dim
        for net, layers in (("policy_net", self.net_pi), ("value_net", self.net_vf)):
            previous = width
            for i, size in enumerate(layers):
                shapes[f"mlp_extractor.{net}.{2 * i}"] = (size, previous)
                previous = size
        shapes["action_net"] = (self.n_action_outputs, self.net_pi[-1] if self.net_pi else width)
        shapes["value_net"] = (1, self.net_vf[-1] if self.net_vf else width)
        return shapes

    def gain(self, module: str) -> float:
        """The orthogonal gain SB3 gives ``module`` (``ActorCriticPolicy._build``)."""
        if module == "action_net":
            return GAIN_ACTION
        if module == "value_net":
            return GAIN_VALUE
        return GAIN_HIDDEN

    # -- the network kind as an evolved agent --------------------------------------------

    def actor_modules(self) -> list[str]:
        """The actor's layers in order: the filters if any, the policy MLP's, ``action_net``."""
        hidden = [f"mlp_extractor.policy_net.{2 * i}" for i in range(len(self.net_pi))]
        return [*([FILTERS] if self.filters else []), *hidden, "action_net"]

    def architecture(self) -> dict[str, Any]:
        """The actor as an evolved agent file's ``architecture`` (evolution's network spec)."""
        if self.kind != "network":
            raise RLConfigError("an SB3 policy is saved as an SB3 zip, not as a network")
        return {
            "type": "mlp",
            "robot": self.robot,
            "hidden": list(self.net_pi),
            "activation": self.activation,
            "pool": self.pool,
            "symmetry": self.symmetry,
            "filters": self.filters,
            "stride": self.stride,
            "pooling": self.pooling,
        }

    def actor_vector(self, params: Mapping[str, Mapping[str, np.ndarray]]) -> np.ndarray:
        """float64: the actor's parameters in an evolved network's layout.

        The filters first (each one's 3 x 3 weights row-major, then their
        biases), then for each layer its weights as ``(d_in, d_out)`` row-major
        (torch's ``(out, in)`` transposed), then its biases.
        """
        parts = []
        for module in self.actor_modules():
            weight = np.asarray(params[module]["weight"], np.float64)
            parts.append((weight if module == FILTERS else weight.T).ravel())
            parts.append(np.asarray(params[module]["bias"], np.float64).ravel())
        return np.concatenate(parts)

    def actor_vector_size(self) -> int:
        """Parameters of the actor: the length of :meth:`actor_vector`."""
        shapes = self.layer_shapes()
        return sum(int(np.prod(shapes[m])) + shapes[m][0] for m in self.actor_modules())

    def actor_from_vector(self, vector: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
        """The actor's layers (torch's layout, float32) of an evolved network's vector."""
        shapes = self.layer_shapes()
        expected = self.actor_vector_size()
        vector = np.asarray(vector, np.float64)
        if vector.shape != (expected,):
            raise RLConfigError(
                f"a network of {expected} parameters was expected, got shape {vector.shape}"
            )
        layers, offset = {}, 0
        for module in self.actor_modules():
            shape = shapes[module]
            d_out, size = shape[0], int(np.prod(shape))
            piece = vector[offset : offset + size]
            weight = piece.reshape(shape) if module == FILTERS else piece.reshape(-1, d_out).T
            offset += size
            layers[module] = {
                "weight": weight.astype(np.float32),
                "bias": vector[offset : offset + d_out].astype(np.float32),
            }
            offset += d_out
        return layers


def accelerations(spec: PolicySpec, outputs: Any, xp: Any) -> Any:
    """A continuous robot's ``(n, 2)`` accelerations from ``action_net``'s outputs.

    ``tanh`` of the 2 outputs, or with rotations (the four directions' scores
    ``(n, 4)``, E N W S) ``(tanh(s_E - s_W), tanh(s_N - s_S))``: evolution's
    network of the same spec. ``xp``: ``jax.numpy`` or numpy.
    """
    if spec.copies == 4:
        outputs = xp.stack([outputs[:, 0] - outputs[:, 2], outputs[:, 1] - outputs[:, 3]], axis=1)
    return xp.tanh(outputs)


def network_spec(robot: str, network: Mapping[str, Any]) -> PolicySpec:
    """The ``network`` kind's spec of a config's ``network`` for ``robot``, every value checked.

    ``network`` takes evolution's keys (:data:`NETWORK_KEYS`): ``hidden`` (the
    actor's and the critic's hidden widths), ``activation``, ``pool`` (image
    robots; default :data:`~amaze.agents.network_inputs.DEFAULT_POOL`),
    ``pooling`` (one of :data:`~amaze.agents.network_inputs.POOLINGS`, with
    a pool), ``symmetry``, and for
    image robots ``filters`` (a convolution instead of the pool) with its
    ``stride`` (default: the largest of 3, 2, 1 that tiles the retina).
    Unknown keys and bad values raise :class:`RLConfigError`.
    """
    if not isinstance(network, Mapping):
        raise RLConfigError(f"network {network!r} is not a mapping of {', '.join(NETWORK_KEYS)}")
    unknown = sorted(set(network) - set(NETWORK_KEYS))
    if unknown:
        named = ", ".join(f"{key!r}{closest(key, NETWORK_KEYS)}" for key in unknown)
        raise RLConfigError(
            f"network key(s) {named}: the RL learners' networks take {', '.join(NETWORK_KEYS)}"
        )
    parsed = as_robot(robot)
    hidden = network.get("hidden", [])
    if isinstance(hidden, int) and not isinstance(hidden, bool):
        hidden = [hidden]
    widths = check_layer_widths("network hidden", hidden, error=RLConfigError)
    activation = network.get("activation", "tanh")
    if activation not in ACTIVATIONS:
        raise RLConfigError(
            f"network activation {activation!r} is not one of {', '.join(ACTIVATIONS)}"
        )
    symmetry = network.get("symmetry", "none")
    if symmetry not in SYMMETRIES:
        raise RLConfigError(f"network symmetry {symmetry!r} is not one of {', '.join(SYMMETRIES)}")
    pool, filters, stride = network.get("pool"), network.get("filters", 0), network.get("stride")
    pooling = network.get("pooling", POOLINGS[0])
    if pooling not in POOLINGS:
        raise RLConfigError(f"network pooling {pooling!r} is not one of {', '.join(POOLINGS)}")
    filters = check_integer(
        "network filters", filters, minimum=0, maximum=MAX_FILTERS, error=RLConfigError
    )
    if parsed.discrete_inputs:
        if pool is not None or filters or stride is not None:
            named = "pool" if pool is not None else "filters" if filters else "stride"
            value = {"pool": pool, "filters": filters, "stride": stride}[named]
            raise RLConfigError(f"network {named} {value!r}: robot {parsed} has no image to read")
    elif filters:
        pool, stride = _checked_convolution(pool, filters, stride, int(parsed.vision))
    else:
        if stride is not None:
            raise RLConfigError(
                f"network stride {stride!r} without filters: only a convolution has a stride"
            )
        vision = int(parsed.vision)
        pool = check_integer(
            "network pool",
            DEFAULT_POOL if pool is None else pool,
            minimum=1,
            maximum=vision,
            error=RLConfigError,
        )
    if pooling != POOLINGS[0] and pool is None:
        image = "convolves its image" if filters else f"robot {parsed} has no image"
        raise RLConfigError(f"network pooling {pooling!r}: the network {image} to pool")
    problem = pooling_problem(pooling, pool)
    if problem:
        raise RLConfigError(f"network {problem}")
    return PolicySpec(
        parsed.to_string(),
        widths,
        widths,
        kind="network",
        activation=activation,
        symmetry=symmetry,
        pool=pool,
        filters=filters,
        stride=stride,
        pooling=pooling,
    )


def _checked_convolution(pool: Any, filters: int, stride: Any, vision: int) -> tuple[None, int]:
    """A convolution's (no pool, its stride), checked: it tiles the ``vision``-pixel retina."""
    if pool is not None:
        raise RLConfigError(
            f"network pool {pool!r} with filters {filters}: a network pools its image or"
            " convolves it, not both"
        )
    stride = default_stride(vision) if stride is None else stride
    stride = check_integer("network stride", stride, minimum=1, maximum=3, error=RLConfigError)
    problem = stride_problem(stride, vision)
    if problem:
        raise RLConfigError(f"network {problem}")
    return None, stride
