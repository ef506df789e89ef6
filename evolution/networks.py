"""Fixed-topology networks as flat parameter vectors, a whole population per forward pass.

A :class:`NetworkSpec` describes one architecture (robot, hidden layers,
activation, image encoder); a parameter vector of ``spec.n_params`` floats is
one individual, and :meth:`NetworkSpec.population` turns a ``(P, n_params)``
array into a :class:`NetworkPopulation`, the population policy that plays all
``P`` individuals at once on the batch engine (agent ``k`` belongs to
individual ``k // M``, see :mod:`evolution.population`). This is what CMA-ES
optimises.

**Inputs.** ``DD`` robots see their 8 floats. Image robots (``CD``/``H``/``CC``)
see a ``v x v`` uint8 image, which a fixed, non-evolved encoder pools to a
``pool x pool`` grid (default 5) of pixels scaled to [0, 1], so that CMA-ES is
not given a weight per pixel: each block's mean (``pooling = "mean"``, the
default) or its brightest pixel (``"max"``). The block edges are
``floor(linspace(0, v, pool + 1) + 0.5)``; ``pool = v`` feeds the raw pixels.
``"mean-ring"`` and ``"max-ring"`` keep the image's outermost pixels (a hybrid
robot's walls and arrival marker) in the grid's outer blocks, apart from the
sign inside (:func:`amaze.agents.network_inputs.pool_edges`).

**Layers.** Dense layers ``n_inputs -> hidden... -> n_outputs``, the hidden
activation (``tanh``, ``relu``, ``sigmoid``, ``identity``) on hidden layers
only; ``hidden = ()`` is a linear policy. Outputs: 4 logits for discrete
actions (the action is the first maximal one, in E, N, W, S order); 2 for
continuous actions, squashed by tanh into accelerations in [-1, 1].

**Symmetry.** With ``symmetry = "rotations"`` the score of direction ``d`` is
the network's single output on the inputs turned a quarter-turn ``d`` times
clockwise (the 8 DD inputs shifted cyclically, the pooled grid turned with
``np.rot90``): one set of weights for the four directions, equivariant by
construction (``docs/trainers/evolution.md``). A discrete action is the best
score; an acceleration is ``(tanh(s_E - s_W), tanh(s_N - s_S))``
(:func:`turned_accelerations`).

**Parameter layout.** For each layer in order, its weights ``(d_in, d_out)``
row-major, then its biases ``(d_out,)`` (:meth:`NetworkSpec.unflatten`).
Parameter counts (weights + biases):

=================  =======  =========  ===========  ================
robot              inputs   linear     hidden (16)  hidden (32, 32)
=================  =======  =========  ===========  ================
DD                 8        36         212          1 476
DD, rotations      8        9          161          1 377
CD15/CD11          25       104        484          2 020
CD15, rotations    25       26         433          1 921
CC15, rotations    25       26         433          1 921
CC15/CC11          25       52         450          1 954
=================  =======  =========  ===========  ================

**Speed.** The forward pass is a numba kernel over blocks of up to 64 agents
(of one individual, or the same episode of 64 individuals), skipping agents
whose scored episode has ended (the ``retire`` hook of
:func:`amaze.evaluation.policy.run_episodes`). Arithmetic is float32, in one
order, with Eigen's rational tanh (within 4e-7): an individual acts the same,
bit for bit, in a population of any size, alone (:mod:`evolution.agent_file`),
on one thread or several.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from amaze.agents.engine import threads_pay_off
from amaze.agents.network_inputs import (
    DEFAULT_POOL,
    POOLINGS,
    SYMMETRIES,
    pool_blocks,
    pool_edges,
    pooling_problem,
    pools_maxima,
    rotation_index,
)
from amaze.agents.robot import Robot, RobotStringError, as_robot
from amaze.validation import (
    MAX_HIDDEN_LAYERS,
    MAX_LAYER_WIDTH,
    check_integer,
    check_layer_widths,
    closest,
)
from evolution import EvolutionConfigError
from evolution.activations import ACTIVATION_CODES, ACTIVATIONS, activate_block, tanh32
from evolution.convolution import (
    FILTER_SIDE,
    MAX_FILTERS,
    check_stride,
    convolve,
    default_stride,
    feature_turns,
    grid_side,
    turned_filters,
)

__all__ = [
    "ACTIVATIONS",
    "DEFAULT_POOL",
    "SYMMETRIES",
    "NetworkPopulation",
    "NetworkSpec",
    "check_symmetry",
    "rotation_index",
    "turned_accelerations",
]

#: Inputs of discrete-input robots, actions of discrete-output robots, accelerations.
N_DISCRETE_INPUTS = 8
N_DISCRETE_ACTIONS = 4
N_CONTINUOUS_OUTPUTS = 2
#: Widest hidden layer accepted (the bound shared by every trainer's networks,
#: far above what evolution uses; at most MAX_HIDDEN_LAYERS of them).
MAX_WIDTH = MAX_LAYER_WIDTH

_MODE_DISCRETE, _MODE_CONTINUOUS = 0, 1

#: Agents processed together by the kernel (its SIMD axis).
_BLOCK = 64
_NO_DISCRETE = np.zeros(0, dtype=np.int64)
_NO_CONTINUOUS = np.zeros((0, 2), dtype=np.float64)
#: Multiply-adds per call above which the multi-threaded kernel is the default.
_PARALLEL_MIN_WORK = 1 << 18


# -----------------------------------------------------------------------------
# Specification


@dataclass(frozen=True)
class NetworkSpec:
    """A fixed-topology network for one robot (see the module docstring).

    ``robot`` is stored as its canonical string (``DD``, ``CD15``, ``CC11``);
    ``pool`` is the side of the pooled image grid, ``None`` for discrete-input
    robots (image robots default to :data:`DEFAULT_POOL`); ``pooling`` how the
    grid is laid out and a block reduced, one of :data:`POOLINGS` (any but
    ``"mean"`` only with a pooled image; the ring poolings with a grid of at
    least 3); ``symmetry`` is
    one of :data:`SYMMETRIES` (``"rotations"``: one network scores each
    direction). ``filters`` > 0 (image robots) reads the
    image through that many evolved 3x3 filters slid with ``stride`` instead
    of pooling it (:mod:`evolution.convolution`; ``pool`` is then ``None``).
    """

    robot: str = "DD"
    hidden: tuple[int, ...] = ()
    activation: str = "tanh"
    pool: int | None = None
    symmetry: str = "none"
    filters: int = 0
    stride: int | None = None
    pooling: str = POOLINGS[0]

    def __post_init__(self) -> None:
        try:
            robot = as_robot(self.robot)
        except RobotStringError as error:
            raise EvolutionConfigError(str(error)) from None
        except (TypeError, AttributeError):
            raise EvolutionConfigError(f"robot {self.robot!r} is not a robot string") from None
        object.__setattr__(self, "robot", robot.to_string())
        hidden = self.hidden
        if isinstance(hidden, int | np.integer) and not isinstance(hidden, bool):
            hidden = (hidden,)
        if isinstance(hidden, str) or not isinstance(hidden, Sequence):
            raise EvolutionConfigError(f"hidden {hidden!r} must be a list of layer widths")
        if len(hidden) > MAX_HIDDEN_LAYERS:  # before a long sequence is copied
            raise EvolutionConfigError(
                f"hidden has {len(hidden)} layers, more than {MAX_HIDDEN_LAYERS}"
            )
        widths = check_layer_widths("hidden", tuple(hidden), error=EvolutionConfigError)
        object.__setattr__(self, "hidden", widths)
        if self.activation not in ACTIVATIONS:
            raise EvolutionConfigError(
                f"activation {self.activation!r} is not one of {', '.join(ACTIVATIONS)}"
            )
        filters = check_integer(
            "filters", self.filters, minimum=0, maximum=MAX_FILTERS, error=EvolutionConfigError
        )
        object.__setattr__(self, "filters", filters)
        if robot.discrete_inputs:
            if self.pool is not None:
                raise EvolutionConfigError(
                    f"pool {self.pool!r}: robot {robot} has no image to pool (give none)"
                )
            if filters or self.stride is not None:
                raise EvolutionConfigError(
                    f"filters {filters!r}, stride {self.stride!r}: robot {robot} has no image"
                    " to convolve (give none)"
                )
        elif filters:
            if self.pool is not None:
                raise EvolutionConfigError(
                    f"pool {self.pool!r} with filters {filters}: a network pools its image or"
                    " convolves it, not both (give one)"
                )
            vision = int(robot.vision)
            stride = default_stride(vision) if self.stride is None else self.stride
            object.__setattr__(self, "stride", check_stride(stride, vision))
        else:
            if self.stride is not None:
                raise EvolutionConfigError(
                    f"stride {self.stride!r} without filters: only a convolution has a stride"
                    " (give filters, or no stride)"
                )
            pool = DEFAULT_POOL if self.pool is None else self.pool
            pool = check_integer(
                "pool", pool, minimum=1, maximum=int(robot.vision), error=EvolutionConfigError
            )
            object.__setattr__(self, "pool", pool)
        problem = pooling_problem(self.pooling, self.pool)
        if problem:
            raise EvolutionConfigError(problem)
        if self.pooling != POOLINGS[0] and self.pool is None:
            image = "convolves its image" if filters else f"robot {robot} has no image"
            raise EvolutionConfigError(
                f"pooling {self.pooling!r}: the network {image} to pool (give no pooling)"
            )
        check_symmetry(self.symmetry)

    # -- description ----------------------------------------------------------

    @property
    def robot_info(self) -> Robot:
        """The :class:`~amaze.agents.robot.Robot` of :attr:`robot`."""
        return as_robot(self.robot)

    @property
    def grid(self) -> int | None:
        """Side of the image grid the dense layers see: ``pool``, the convolution's
        feature maps, or ``None`` (discrete inputs)."""
        if self.filters:
            return grid_side(int(self.robot_info.vision), int(self.stride))
        return self.pool

    @property
    def n_inputs(self) -> int:
        """Inputs of the first dense layer: 8, ``pool * pool`` pooled pixels, or
        ``filters x grid^2`` features."""
        if self.grid is None:
            return N_DISCRETE_INPUTS
        return max(self.filters, 1) * self.grid * self.grid

    @property
    def n_conv_params(self) -> int:
        """Parameters of the filters (9 weights and a bias each), first in a vector."""
        return self.filters * (FILTER_SIDE * FILTER_SIDE + 1)

    @property
    def n_outputs(self) -> int:
        """4 logits (discrete actions) or 2 accelerations (continuous actions)."""
        return N_DISCRETE_ACTIONS if self.robot_info.discrete_outputs else N_CONTINUOUS_OUTPUTS

    @property
    def copies(self) -> int:
        """Times the layers run per observation: 4 with rotations (one per direction), else 1."""
        return 4 if self.symmetry == "rotations" else 1

    @property
    def layer_sizes(self) -> tuple[int, ...]:
        """``(n_inputs, *hidden, last)``: ``last`` is 1 with rotations, else ``n_outputs``."""
        return (self.n_inputs, *self.hidden, 1 if self.copies > 1 else self.n_outputs)

    @property
    def layer_shapes(self) -> tuple[tuple[int, int], ...]:
        """``(d_in, d_out)`` of each dense layer, in order."""
        sizes = self.layer_sizes
        return tuple(itertools.pairwise(sizes))

    @property
    def n_params(self) -> int:
        """Length of a parameter vector: all weights and biases."""
        dense = sum(d_in * d_out + d_out for d_in, d_out in self.layer_shapes)
        return self.n_conv_params + dense

    # -- (de)serialisation ----------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """JSON-able description (:meth:`from_dict` reads it back)."""
        return {
            "robot": self.robot,
            "hidden": list(self.hidden),
            "activation": self.activation,
            "pool": self.pool,
            "symmetry": self.symmetry,
            "filters": self.filters,
            "stride": self.stride,
            "pooling": self.pooling,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> NetworkSpec:
        """The spec described by ``data`` (an optional ``"type": "mlp"`` is accepted).

        Unknown keys and bad values raise :class:`EvolutionConfigError`; a
        description without ``pooling`` (files written before it existed) means
        ``"mean"``.
        """
        if not isinstance(data, Mapping):
            raise EvolutionConfigError(f"a network spec must be a mapping, not {data!r}")
        data = dict(data)
        kind = data.pop("type", "mlp")
        if kind != "mlp":
            raise EvolutionConfigError(f"network type {kind!r} is not 'mlp'")
        keys = {"robot", "hidden", "activation", "pool", "symmetry", "filters", "stride", "pooling"}
        unknown = sorted(set(data) - keys)
        if unknown:
            named = ", ".join(f"{key}{closest(key, keys)}" for key in unknown)
            raise EvolutionConfigError(f"unknown network spec key(s): {named}")
        if "robot" not in data:
            raise EvolutionConfigError("network spec: 'robot' is missing")
        hidden = data.get("hidden", ())
        if isinstance(hidden, list):
            hidden = tuple(hidden)
        return cls(
            robot=data["robot"],
            hidden=hidden,
            activation=data.get("activation", "tanh"),
            pool=data.get("pool"),
            symmetry=data.get("symmetry", "none"),
            filters=data.get("filters", 0),
            stride=data.get("stride"),
            pooling=data.get("pooling", POOLINGS[0]),
        )

    # -- parameters -----------------------------------------------------------

    def initial_params(self, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
        """Random parameters: weights ``N(0, 1 / d_in)`` (filters: ``N(0, 1 / 9)``), biases
        zero; float64.

        One vector ``(n_params,)``, or ``(n, n_params)`` when ``n`` is given.
        """
        count = 1
        if n is not None:
            count = check_integer("n", n, minimum=1, maximum=1 << 30, error=EvolutionConfigError)
        params = np.zeros((count, self.n_params), dtype=np.float64)
        size = self.filters * FILTER_SIDE * FILTER_SIDE
        params[:, :size] = rng.normal(0.0, 1.0 / FILTER_SIDE, (count, size))
        offset = self.n_conv_params
        for d_in, d_out in self.layer_shapes:
            size = d_in * d_out
            params[:, offset : offset + size] = rng.normal(0.0, 1.0 / np.sqrt(d_in), (count, size))
            offset += size + d_out
        return params[0] if n is None else params

    def unflatten(self, params: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """The ``(weights (d_in, d_out), biases (d_out,))`` of each dense layer of one vector."""
        params = self._checked_vector(params)
        layers, offset = [], self.n_conv_params
        for d_in, d_out in self.layer_shapes:
            weights = params[offset : offset + d_in * d_out].reshape(d_in, d_out)
            offset += d_in * d_out
            layers.append((weights, params[offset : offset + d_out]))
            offset += d_out
        return layers

    def filter_params(self, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The filters of one vector: weights ``(filters, 3, 3)`` and biases ``(filters,)``."""
        params = self._checked_vector(params)
        size = self.filters * FILTER_SIDE * FILTER_SIDE
        weights = params[:size].reshape(self.filters, FILTER_SIDE, FILTER_SIDE)
        return weights, params[size : self.n_conv_params]

    def _checked_vector(self, params: np.ndarray) -> np.ndarray:
        params = np.asarray(params)
        if params.shape != (self.n_params,):
            raise EvolutionConfigError(
                f"a parameter vector of {self.n_params} values was expected, got {params.shape}"
            )
        return params

    def encode(self, observations: np.ndarray) -> np.ndarray:
        """float32 ``(n, n_inputs)``: the network inputs of a batch of observations.

        The 8 floats of discrete inputs; the pooled image (block means or
        maxima of the pixels / 255) of image robots. The kernel does the same,
        fused. (A convolutional network's inputs depend on its filters: refused.)
        """
        if self.filters:
            raise EvolutionConfigError(
                "a convolutional network's inputs depend on its filters: encode has none"
            )
        observations = np.asarray(observations)
        n = observations.shape[0]
        if self.pool is None:
            return observations.reshape(n, -1).astype(np.float32)
        v = int(self.robot_info.vision)
        if pools_maxima(self.pooling):
            pixels = observations.reshape(n, v * v)[:, pool_blocks(v, self.pool, self.pooling)]
            return pixels.max(axis=-1).astype(np.float32) * np.float32(1.0 / 255.0)
        images = observations.reshape(n, v, v).astype(np.float64)
        edges = pool_edges(v, self.pool, self.pooling)
        out = np.empty((n, self.pool, self.pool), dtype=np.float64)
        for r in range(self.pool):
            for c in range(self.pool):
                block = images[:, edges[r] : edges[r + 1], edges[c] : edges[c + 1]]
                out[:, r, c] = block.mean(axis=(1, 2)) / 255.0
        return out.reshape(n, -1).astype(np.float32)

    def rotation_index(self) -> np.ndarray:
        """int64 ``(4, n_inputs)``: row ``d`` gathers the inputs turned so that side ``d`` is east.

        ``inputs[:, index[d]]`` are the inputs seen after turning the cell ``d``
        quarter-turns clockwise (E, N, W, S order of ``d``): the 4 wall and 4
        sign values of DD robots shifted cyclically, the pooled grid of image
        robots turned by ``np.rot90(grid, -d)`` (row 0 is north). A
        convolutional network gathers from the maps of its filters in their 4
        turns instead (``(4, filters x grid^2)`` into ``4 x filters x grid^2``
        maps, :func:`~evolution.convolution.feature_turns`).
        """
        if self.filters:
            return feature_turns(self.filters, int(self.grid))
        return rotation_index(self.pool)

    def population(self, params: np.ndarray, *, parallel: bool | None = None) -> NetworkPopulation:
        """The population policy of ``params`` (``(P, n_params)``, one row per individual)."""
        return NetworkPopulation(self, params, parallel=parallel)


def check_symmetry(symmetry: object, name: str = "symmetry") -> str:
    """``symmetry`` if it is one of :data:`SYMMETRIES`.

    Every robot takes both: with ``"rotations"`` a discrete action is the best
    of the four directions' scores, an acceleration their difference along
    each axis (:func:`turned_accelerations`). ``name`` names the value in the
    error (:class:`~evolution.EvolutionConfigError`).
    """
    if symmetry not in SYMMETRIES:
        raise EvolutionConfigError(f"{name} {symmetry!r} is not one of {', '.join(SYMMETRIES)}")
    return str(symmetry)


@numba.njit(cache=True, error_model="numpy")
def _turned_accelerations(scores, out):
    for k in range(scores.shape[0]):
        out[k, 0] = tanh32(np.float32(scores[k, 0] - scores[k, 2]))
        out[k, 1] = tanh32(np.float32(scores[k, 1] - scores[k, 3]))


def turned_accelerations(scores: np.ndarray) -> np.ndarray:
    """Accelerations ``(n, 2)`` from the direction scores ``(n, 4)`` (E, N, W, S) of a network
    shared by the four directions: ``(tanh(s_E - s_W), tanh(s_N - s_S))``.

    The score of direction ``d`` is the network's output on the image turned
    so that ``d`` lies east, so turning the maze a quarter-turn turns the
    acceleration with it: the continuous form of the discrete argmax.
    Computed in float32 with :func:`~evolution.activations.tanh32`, one agent
    at a time, so an agent accelerates the same in any batch.
    """
    scores = np.ascontiguousarray(scores)
    out = np.empty((scores.shape[0], N_CONTINUOUS_OUTPUTS), dtype=np.float64)
    _turned_accelerations(scores, out)
    return out


# -----------------------------------------------------------------------------
# Compiled forward pass


@numba.njit(cache=True)
def _u(index):
    """An index known to be non-negative, as unsigned (no wraparound check: vectorises)."""
    return numba.uint64(index)


@numba.njit(cache=True, error_model="numpy")
def _emit(b, agents, nb, d_last, mode, values, discrete, continuous):
    """Write the outputs ``b`` of the block's agents, and their actions."""
    for r in range(nb):
        k = agents[r]
        for o in range(d_last):
            values[k, o] = b[o, r]
        if mode == _MODE_DISCRETE:
            best = 0
            top = b[0, r]
            for o in range(1, d_last):
                if b[o, r] > top:
                    top = b[o, r]
                    best = o
            discrete[k] = best
        else:
            for o in range(d_last):
                continuous[k, o] = tanh32(b[o, r])


@numba.njit(cache=True, error_model="numpy")
def _block_of_individual(
    p,
    s0,
    s1,
    x,
    rows,
    params,
    layers,
    activation,
    mode,
    a,
    b,
    agents,
    values,
    discrete,
    continuous,
):
    """Agents ``rows[s0:s1]``, all of individual ``p``: one weight for the whole SIMD axis."""
    nb = s1 - s0
    n_layers = layers.shape[0]
    for r in range(nb):
        k = rows[s0 + r]
        agents[r] = k
        for i in range(layers[0, 0]):
            a[i, r] = x[k, i]
    for layer in range(n_layers):
        d_in = layers[layer, 0]
        d_out = layers[layer, 1]
        w0 = layers[layer, 2]
        b0 = layers[layer, 3]
        for o in range(d_out):
            bias = params[p, b0 + o]
            for r in range(nb):
                b[o, r] = bias
        for i in range(d_in):
            for o in range(d_out):
                weight = params[p, w0 + i * d_out + o]
                for r in range(nb):
                    b[o, r] += weight * a[i, r]
        if layer < n_layers - 1:
            activate_block(a, b, d_out, nb, activation)
    _emit(b, agents, nb, layers[n_layers - 1, 1], mode, values, discrete, continuous)


@numba.njit(cache=True, error_model="numpy")
def _block_of_episode(
    e,
    p0,
    p1,
    m,
    x,
    params_t,
    layers,
    activation,
    mode,
    a,
    b,
    agents,
    values,
    discrete,
    continuous,
):
    """Episode ``e`` of individuals ``p0 .. p1 - 1``: weights vary along the SIMD axis."""
    nb = p1 - p0
    n_layers = layers.shape[0]
    for r in range(nb):
        k = (p0 + r) * m + e
        agents[r] = k
        for i in range(layers[0, 0]):
            a[i, r] = x[k, i]
    for layer in range(n_layers):
        d_in = layers[layer, 0]
        d_out = layers[layer, 1]
        w0 = layers[layer, 2]
        b0 = layers[layer, 3]
        for o in range(d_out):
            for r in range(nb):
                b[o, r] = params_t[b0 + o, _u(p0 + r)]
        for i in range(d_in):
            for o in range(d_out):
                w = w0 + i * d_out + o
                for r in range(nb):
                    b[o, r] += params_t[w, _u(p0 + r)] * a[i, r]
        if layer < n_layers - 1:
            activate_block(a, b, d_out, nb, activation)
    _emit(b, agents, nb, layers[n_layers - 1, 1], mode, values, discrete, continuous)


@numba.njit(cache=True, error_model="numpy")
def _run_block(
    j,
    by_episode,
    m,
    x,
    rows,
    blocks,
    params,
    params_t,
    layers,
    activation,
    mode,
    a,
    b,
    agents,
    values,
    discrete,
    continuous,
):
    if by_episode:
        _block_of_episode(
            blocks[j, 0],
            blocks[j, 1],
            blocks[j, 2],
            m,
            x,
            params_t,
            layers,
            activation,
            mode,
            a,
            b,
            agents,
            values,
            discrete,
            continuous,
        )
    else:
        _block_of_individual(
            blocks[j, 0],
            blocks[j, 1],
            blocks[j, 2],
            x,
            rows,
            params,
            layers,
            activation,
            mode,
            a,
            b,
            agents,
            values,
            discrete,
            continuous,
        )


@numba.njit(cache=True, error_model="numpy")
def _forward_serial(
    by_episode,
    m,
    x,
    rows,
    blocks,
    params,
    params_t,
    layers,
    width,
    activation,
    mode,
    values,
    discrete,
    continuous,
):
    a = np.empty((width, _BLOCK), dtype=np.float32)
    b = np.empty((width, _BLOCK), dtype=np.float32)
    agents = np.empty(_BLOCK, dtype=np.int64)
    for j in range(blocks.shape[0]):
        _run_block(
            j,
            by_episode,
            m,
            x,
            rows,
            blocks,
            params,
            params_t,
            layers,
            activation,
            mode,
            a,
            b,
            agents,
            values,
            discrete,
            continuous,
        )


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _forward_parallel(
    by_episode,
    m,
    x,
    rows,
    blocks,
    params,
    params_t,
    layers,
    width,
    activation,
    mode,
    values,
    discrete,
    continuous,
):
    for j in numba.prange(blocks.shape[0]):
        a = np.empty((width, _BLOCK), dtype=np.float32)
        b = np.empty((width, _BLOCK), dtype=np.float32)
        agents = np.empty(_BLOCK, dtype=np.int64)
        _run_block(
            j,
            by_episode,
            m,
            x,
            rows,
            blocks,
            params,
            params_t,
            layers,
            activation,
            mode,
            a,
            b,
            agents,
            values,
            discrete,
            continuous,
        )


@numba.njit(cache=True, error_model="numpy")
def _pool(images, rows, edges, scale, maximum, out):
    """Pooled features of the listed agents: block sums (or maxima) of the pixels times ``scale``.

    Each band of image rows is reduced column-wise first (contiguous, vectorised),
    then the band's column sums (maxima) are cut into blocks.
    """
    v = images.shape[2]
    g = edges.shape[0] - 1
    band = np.empty(v, dtype=np.int32)
    for j in range(rows.shape[0]):
        k = rows[j]
        for gr in range(g):
            for c in range(v):
                band[c] = 0
            if maximum:
                for r in range(edges[gr], edges[gr + 1]):
                    for c in range(v):
                        band[c] = max(band[c], np.int32(images[k, r, c]))
            else:
                for r in range(edges[gr], edges[gr + 1]):
                    for c in range(v):
                        band[c] += images[k, r, c]
            for gc in range(g):
                total = 0
                if maximum:
                    for c in range(edges[gc], edges[gc + 1]):
                        total = max(total, band[c])
                else:
                    for c in range(edges[gc], edges[gc + 1]):
                        total += band[c]
                f = gr * g + gc
                out[k, f] = np.float32(total) * scale[f]


# -----------------------------------------------------------------------------
# Population policy


class NetworkPopulation:
    """``P`` networks of one :class:`NetworkSpec`, played as one population policy.

    Called with a batch of ``P * M`` observations (gymnasium format), agent
    ``k`` acts with the network of individual ``k // M``: int64 actions
    ``(P*M,)`` (argmax, first maximum) for discrete outputs, float64
    accelerations ``(P*M, 2)`` in [-1, 1] for continuous ones. A population
    of one plays any number of agents (:mod:`evolution.agent_file`).

    ``reset(n_agents)`` starts a run; ``retire(agents)`` (called by
    :func:`amaze.evaluation.policy.run_episodes`) lets the forward pass skip agents whose
    scored episode has ended (those it skips get action 0, or no acceleration)
    until the next ``reset``, or until all agents are retired (the run is over).
    ``parallel`` picks the multi-threaded kernel (default: when the work is
    large and cores are idle); the actions do not depend on it. Instances
    pickle as their spec and parameters.
    """

    def __init__(
        self, spec: NetworkSpec, params: np.ndarray, *, parallel: bool | None = None
    ) -> None:
        if not isinstance(spec, NetworkSpec):
            raise EvolutionConfigError(f"expected a NetworkSpec, not {spec!r}")
        params = np.asarray(params)
        if params.ndim == 1:
            params = params[None]
        if params.ndim != 2 or params.shape[1] != spec.n_params or params.shape[0] < 1:
            raise EvolutionConfigError(
                f"parameters must have shape (P, {spec.n_params}) for {spec.to_dict()},"
                f" got {params.shape}"
            )
        if not np.all(np.isfinite(params)):
            raise EvolutionConfigError("parameters must be finite numbers")
        self.spec = spec
        self.robot: Robot = spec.robot_info
        self.params = np.ascontiguousarray(params, dtype=np.float32)
        self.params.flags.writeable = False
        self.n_policies = int(self.params.shape[0])
        self.parallel = parallel
        sizes = spec.layer_sizes
        layers, offset = [], spec.n_conv_params
        for d_in, d_out in spec.layer_shapes:
            layers.append((d_in, d_out, offset, offset + d_in * d_out))
            offset += d_in * d_out + d_out
        self._layers = np.array(layers, dtype=np.int64)
        self._width = max(sizes)
        self._macs = sum(d_in * d_out for d_in, d_out in spec.layer_shapes)
        self._filters: tuple[np.ndarray, np.ndarray] | None = None
        if spec.filters:  # (P, E, 9) and (P, E): E = filters, or 4 x filters turned
            size = spec.filters * FILTER_SIDE * FILTER_SIDE
            weights = self.params[:, :size].reshape(self.n_policies, spec.filters, -1)
            biases = self.params[:, size : spec.n_conv_params]
            if spec.copies > 1:
                weights, biases = turned_filters(weights, biases)
            self._filters = (np.ascontiguousarray(weights), np.ascontiguousarray(biases))
            self._n_features = weights.shape[1] * int(spec.grid) ** 2
            self._macs += self._n_features * FILTER_SIDE * FILTER_SIDE // spec.copies
        self._activation = ACTIVATION_CODES[spec.activation]
        self._mode = _MODE_DISCRETE if self.robot.discrete_outputs else _MODE_CONTINUOUS
        self._vision = None if spec.grid is None else int(self.robot.vision)
        if spec.pool is not None:
            edges = pool_edges(self._vision, spec.pool, spec.pooling)
            self._edges = edges
            self._maximum = pools_maxima(spec.pooling)
            counts = np.outer(np.diff(edges), np.diff(edges)).ravel()
            if self._maximum:
                counts = np.ones_like(counts)  # the brightest pixel, not a sum
            self._scale = (1.0 / (255.0 * counts)).astype(np.float32)
        self._params_t = np.ascontiguousarray(self.params.T)
        self._n_inputs = spec.n_inputs
        self._n_outputs = spec.n_outputs
        # with rotations every agent is ``copies`` rows of the kernel (one per direction)
        self._copies = spec.copies
        self._turns = spec.rotation_index() if self._copies > 1 else None
        self._n_agents = -1
        self._active: np.ndarray | None = None
        self._dirty = True
        self._by_episode = False
        self._rows = np.zeros(0, dtype=np.int64)
        self._blocks = np.zeros((0, 3), dtype=np.int64)
        self._kernel = _forward_serial

    def __len__(self) -> int:
        return self.n_policies

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.spec, np.array(self.params)), {"parallel": self.parallel})

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.parallel = state.get("parallel")

    def __repr__(self) -> str:
        return f"NetworkPopulation({self.n_policies} x {self.spec!r})"

    # -- population ------------------------------------------------------------

    def subset(self, indices: Sequence[int] | np.ndarray) -> NetworkPopulation:
        """The population of the individuals ``indices`` (in that order)."""
        indices = np.asarray(indices, dtype=np.int64).reshape(-1)
        if indices.size == 0:
            raise EvolutionConfigError("subset: give at least one individual")
        if indices.min() < -self.n_policies or indices.max() >= self.n_policies:
            raise EvolutionConfigError(f"subset: indices must be in [0, {self.n_policies})")
        return NetworkPopulation(self.spec, self.params[indices], parallel=self.parallel)

    def individual(self, index: int) -> NetworkPopulation:
        """Individual ``index`` alone, as a policy for any number of agents."""
        return self.subset([index])

    # -- the policy protocol ---------------------------------------------------

    def _episodes_per_individual(self, n_agents: int) -> int:
        if n_agents < 1 or n_agents % self.n_policies:
            raise EvolutionConfigError(
                f"{n_agents} agents cannot be shared by {self.n_policies} individuals:"
                " give M agents to each (P x M in all)"
            )
        return n_agents // self.n_policies

    def reset(self, n_agents: int) -> None:
        """Start a run of ``n_agents`` agents (``M = n_agents // P`` each); all agents act."""
        self._episodes_per_individual(int(n_agents))
        self._start(int(n_agents) * self._copies)

    def _start(self, n_agents: int) -> None:
        self._n_agents = n_agents
        self._active = np.ones(n_agents, dtype=bool)
        self._dirty = True

    def retire(self, agents: np.ndarray) -> None:
        """Stop computing ``agents`` (their actions are ignored) until the next reset.

        Once every agent is retired (the end of a run), all act again.
        """
        if self._active is not None:
            agents = np.asarray(agents, dtype=np.int64)
            if self._copies > 1:  # the kernel rows of an agent: one per direction
                agents = (agents[:, None] * self._copies + np.arange(self._copies)).ravel()
            self._active[agents] = False
            self._dirty = True
            if not self._active.any():
                self._n_agents = -1

    def _plan(self, n_agents: int, m: int) -> tuple[bool, np.ndarray, np.ndarray]:
        """How the kernel covers the active agents: ``(by_episode, rows, blocks)``.

        A block puts up to 64 agents side by side on the SIMD axis: agents of
        one individual (``(individual, start, stop)`` into ``rows``, the sorted
        active agents), or, when individuals outnumber their episodes, the
        same episode of consecutive individuals (``(episode, first, stop)``;
        ``rows`` then lists the agents the blocks cover).
        """
        if n_agents != self._n_agents:
            self._start(n_agents)
        if self._dirty:
            p_count = self.n_policies
            self._by_episode = min(p_count, _BLOCK) > min(m, _BLOCK)
            if self._by_episode:
                active = self._active.reshape(p_count, m)
                blocks = [
                    (e, p0, min(p0 + _BLOCK, p_count))
                    for e in range(m)
                    for p0 in range(0, p_count, _BLOCK)
                    if active[p0 : p0 + _BLOCK, e].any()
                ]
                self._blocks = np.array(blocks, dtype=np.int64).reshape(-1, 3)
                rows = [np.arange(p0, p1) * m + e for e, p0, p1 in blocks]
                self._rows = np.sort(np.concatenate(rows)) if rows else np.zeros(0, np.int64)
            else:
                rows = np.flatnonzero(self._active)
                starts = np.searchsorted(rows, np.arange(p_count + 1) * m)
                lengths = np.diff(starts)
                counts = (lengths + _BLOCK - 1) // _BLOCK
                owner = np.repeat(np.arange(p_count), counts)
                first = np.repeat(starts[:-1], counts)
                index = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
                begin = first + index * _BLOCK
                end = np.minimum(begin + _BLOCK, np.repeat(starts[1:], counts))
                self._blocks = np.stack([owner, begin, end], axis=1).astype(np.int64)
                self._rows = rows.astype(np.int64)
            self._rows = np.ascontiguousarray(self._rows, dtype=np.int64)
            self._blocks = np.ascontiguousarray(self._blocks)
            if self.parallel is None:
                threads = threads_pay_off(len(self._rows) * self._macs, _PARALLEL_MIN_WORK)
                self._kernel = _forward_parallel if threads else _forward_serial
            self._dirty = False
        return self._by_episode, self._rows, self._blocks

    def _run(self, observations: np.ndarray, all_rows: bool) -> tuple[np.ndarray, np.ndarray]:
        """(network outputs float32 (n, n_outputs), actions) of a batch of observations."""
        observations = np.asarray(observations)
        n = int(observations.shape[0]) if observations.ndim else 0
        m = self._episodes_per_individual(n)
        copies = self._copies
        if all_rows:
            saved = (self._n_agents, self._active, self._dirty)
            self._start(n * copies)
        by_episode, rows, blocks = self._plan(n * copies, m * copies)
        if self._vision is None:
            if observations.shape[1:] != (N_DISCRETE_INPUTS,):
                raise EvolutionConfigError(
                    f"expected observations of shape (n, 8), got {observations.shape}"
                )
            x = np.ascontiguousarray(observations, dtype=np.float32)
        else:
            v = self._vision
            if observations.size != n * v * v:
                raise EvolutionConfigError(
                    f"expected {v}x{v} images for robot {self.robot}, got {observations.shape}"
                )
            images = np.ascontiguousarray(observations.reshape(n, v, v))
            # an agent's kernel rows are its ``copies`` consecutive ones, active together
            agents = rows[::copies] // copies
            if self._filters is not None:
                x = np.empty((n, self._n_features), dtype=np.float32)
                weights, biases = self._filters
                stride = int(self.spec.stride)
                convolve(
                    images, agents, m, weights, biases, stride, self._activation, x,
                    parallel=self._threaded(),
                )  # fmt: skip
            else:
                x = np.empty((n, self._n_inputs), dtype=np.float32)
                _pool(images, agents, self._edges, self._scale, self._maximum, x)
        mode = self._mode
        if copies > 1:
            # kernel row 4 k + d: agent k's inputs turned so that side d is east;
            # its single output is the logit of moving to d
            x = np.ascontiguousarray(x[:, self._turns].reshape(n * copies, -1))
            values = np.zeros((n * copies, 1), dtype=np.float32)
            discrete, continuous = np.zeros(n * copies, dtype=np.int64), _NO_CONTINUOUS
            mode = _MODE_DISCRETE  # (the kernel's argmax of one output is not used)
        elif mode == _MODE_DISCRETE:
            values = np.empty((n, self._n_outputs), dtype=np.float32)
            discrete, continuous = np.zeros(n, dtype=np.int64), _NO_CONTINUOUS
        else:
            values = np.empty((n, self._n_outputs), dtype=np.float32)
            discrete = _NO_DISCRETE
            continuous = np.zeros((n, N_CONTINUOUS_OUTPUTS), dtype=np.float64)
        kernel = _forward_parallel if self._threaded() else _forward_serial
        kernel(
            by_episode,
            m * copies,
            x,
            rows,
            blocks,
            self.params,
            self._params_t,
            self._layers,
            self._width,
            self._activation,
            mode,
            values,
            discrete,
            continuous,
        )
        if all_rows:
            self._n_agents, self._active, self._dirty = saved
        if copies > 1:  # one score per direction (E, N, W, S order); 0 for retired agents
            scores = values.reshape(n, copies)
            if self._mode == _MODE_DISCRETE:  # the first maximal score
                return scores, np.argmax(scores, axis=1).astype(np.int64)
            return scores, turned_accelerations(scores)
        return values, (discrete if mode == _MODE_DISCRETE else continuous)

    def _threaded(self) -> bool:
        """Whether this call's kernels run on several threads: ``parallel``, else by the work."""
        return self._kernel is _forward_parallel if self.parallel is None else self.parallel

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """The actions of a batch of ``P * M`` observations (see the class docstring)."""
        return self._run(observations, all_rows=False)[1]

    def forward(self, observations: np.ndarray) -> np.ndarray:
        """float32 ``(P*M, n_outputs)``: the output layer (logits, or pre-tanh accelerations).

        Every agent is computed (retired ones too); the run's state is untouched.
        """
        return self._run(observations, all_rows=True)[0]
