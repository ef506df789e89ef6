"""CMA-ES (through the ``cma`` package) over the flat parameters of a fixed-topology network.

The search space is the parameter vector of one :class:`~evolution.networks.NetworkSpec`
(robot from the run, hidden layers, activation, pooling and symmetry from
:class:`CMAESConfig`). :class:`CMAESAlgorithm` drives ``cma.CMAEvolutionStrategy``
by ask / tell, like :class:`~evolution.neat.NeatAlgorithm`: ``ask()`` gives the
candidate vectors, :meth:`CMAESAlgorithm.population_policy` turns them into one
:class:`~evolution.networks.NetworkPopulation` for the batch engine, and
``tell(candidates, fitness)`` hands cma the negated fitness (cma minimises, the
runs maximise).

**Randomness.** ``cma`` draws from numpy's global random state (its sampler
and, with few candidates, its mirrored sampling). The algorithm owns a state
of that generator, seeded from ``seed``, and swaps it into ``np.random``
around every cma call, restoring the caller's state afterwards. cma is given a
``randn`` that looks up ``np.random.randn`` when called (instead of the bound
method of the global generator, which pickles as a detached copy), so that a
pickled algorithm, cma's strategy included, resumes bit-identically: pickling
is the checkpoint. The initial means (the first one and each restart's) come
from a separate ``numpy.random.Generator`` seeded with ``seed``, also part of the state.

**Restarts.** With ``restarts > 0`` the algorithm is IPOP-CMA-ES (Auger &
Hansen, 2005): when cma's own termination criteria fire (``es.stop()``: flat
fitness, ``tolfun``, ``tolx``, stagnation...), a new strategy starts from a
fresh random mean with twice the population. Once no restart is left,
:attr:`CMAESAlgorithm.stopped` turns true and the run loop can end early.
"""

from __future__ import annotations

import contextlib
import functools
import math
import warnings
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import cma
import numpy as np
from threadpoolctl import ThreadpoolController

from amaze.agents.network_inputs import POOLINGS
from amaze.agents.robot import Robot, as_robot
from amaze.runs.config import config_from_dict
from amaze.validation import check_integer, check_number, closest
from evolution import EvolutionConfigError
from evolution.convolution import MAX_FILTERS
from evolution.networks import NetworkPopulation, NetworkSpec

__all__ = ["DEFAULT_NETWORK", "CMAESAlgorithm", "CMAESConfig", "default_popsize"]

#: The default network: a linear policy (see :class:`CMAESConfig`).
DEFAULT_NETWORK: dict[str, Any] = {"hidden": [], "activation": "tanh"}
#: Network keys a CMA-ES configuration may set (the robot comes from the run).
_NETWORK_KEYS = ("hidden", "activation", "pool", "symmetry", "filters", "stride", "pooling")
#: cma options the algorithm sets itself (they may not be given in ``cma_options``).
_RESERVED_OPTIONS = frozenset(
    "seed popsize CMA_diagonal randn verbose verb_log verb_disp verb_filenameprefix"
    " verb_append verb_plot verb_time signals_filename".split()
)
#: Largest population accepted (a sanity bound; restarts may double it further).
MAX_POPULATION = 1 << 16
#: Largest number of IPOP restarts accepted (each one doubles the population).
MAX_RESTARTS = 16
#: Default IPOP restarts (see :class:`CMAESConfig`).
DEFAULT_RESTARTS = 9


def default_popsize(n_params: int) -> int:
    """cma's default population for ``n_params`` dimensions: ``4 + floor(3 ln n)``."""
    return 4 + int(3 * math.log(n_params))


class _GlobalRandn:
    """Standard normal draws ``randn(*shape)`` from numpy's global state *at call time*.

    Unlike ``np.random.randn`` (a bound method, which pickles as a copy of the
    generator it belongs to), it keeps following ``np.random`` after a pickle
    round trip, where the algorithm swaps its own state in.
    """

    def __call__(self, *shape: int) -> np.ndarray:
        return np.random.randn(*shape)  # noqa: NPY002 (cma's sampler draws from the global state)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _GlobalRandn)

    def __hash__(self) -> int:
        return hash(_GlobalRandn)


def _json_value(name: str, value: Any) -> Any:
    """``value`` if it is a plain JSON value (numbers, booleans, None, lists of them).

    Strings are refused: cma evaluates string option values as Python
    expressions, so a string in a config file would be code that runs.
    """
    if isinstance(value, list | tuple):
        return [_json_value(name, v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, str):
        raise EvolutionConfigError(
            f"CMA-ES config '{name}' is the string {value!r}: cma evaluates option strings"
            " as Python code, so give the value itself (a number, a boolean or a list)"
        )
    if value is None or isinstance(value, bool | int):
        return value
    if isinstance(value, float) and math.isfinite(value):
        return value
    raise EvolutionConfigError(
        f"CMA-ES config '{name}' must hold finite numbers or booleans, got {value!r}"
    )


@functools.cache
def _threadpools() -> ThreadpoolController:
    """The process's native thread pools (found once: a look-up reads every loaded library)."""
    return ThreadpoolController()


def one_blas_thread() -> contextlib.AbstractContextManager[Any]:
    """A context in which BLAS (OpenBLAS, MKL...) runs on one thread, as before once it exits."""
    return _threadpools().limit(limits=1, user_api="blas")


@dataclass
class CMAESConfig:
    """Parameters of CMA-ES over a fixed network.

    * ``network``: the :class:`~evolution.networks.NetworkSpec` fields but the
      robot (``hidden``, ``activation``, ``pool``, ``symmetry``: ``"rotations"``
      shares one network across the four directions, see
      :mod:`evolution.networks`; ``filters`` and ``stride``: image robots read
      their image through evolved 3x3 filters, :mod:`evolution.convolution`). Default: a **linear
      policy** (``hidden: []``, 36 parameters for ``DD``). On the trivial and
      simple columns of the standard suite (6 mazes x 4 rotations, ``DD``,
      paper reward), the champion reached success 1.0 after a median of 76
      generations (15 seeds out of 15, at most 25 s on 2 shared cores), against
      156 for one hidden layer of 4 tanh units and 164 for 8 (56 and 108
      parameters, 5 seeds each). Following the clues (towards the brightest
      sign, else an open side other than the arrival one) is a linear function
      of the 8 inputs, so hidden layers add dimensions, not abilities the task
      needs.
    * ``population_size``: candidates per generation; ``None`` is cma's default
      ``4 + floor(3 ln n)`` (14 for 36 parameters).
    * ``sigma0``: the initial step size around the ``N(0, 1/fan_in)`` start of
      :meth:`NetworkSpec.initial_params`. Default 1.0: a single descent
      (no restart) solved the two columns for 7 seeds of 28, against 2 with 0.5
      and 6 with 2.0; with restarts the three are alike.
    * ``separable``: sep-CMA-ES, a diagonal covariance matrix (cma's
      ``CMA_diagonal``), linear time and memory per sample: for networks of
      thousands of parameters.
    * ``restarts``: IPOP restarts, each with twice the population of the last.
      Default 9 (up to 512 times the first population). Maze fitness has wide
      plateaus (most early policies bump into walls until the deadline), on
      which cma's flat-fitness criterion soon stops a descent; restarting
      from a new random mean is what makes runs reliable (all 25 seeds
      measured succeeded, after 0 to 3 restarts).
    * ``cma_options``: further ``cma`` options (``tolfun``, ``tolflatfitness``,
      ``tolx``...), except those the algorithm sets itself (seed, popsize,
      CMA_diagonal, randn and the verbosity/logging ones).
    """

    network: dict[str, Any] = field(default_factory=lambda: dict(DEFAULT_NETWORK))
    population_size: int | None = None
    sigma0: float = 1.0
    separable: bool = False
    restarts: int = DEFAULT_RESTARTS
    cma_options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Check (and normalise) every value; raise :class:`EvolutionConfigError` naming it."""
        self.network = _check_network(self.network)
        if self.population_size is not None:  # None: cma's default
            self.population_size = check_integer(
                "CMA-ES config 'population_size'",
                self.population_size,
                minimum=2,
                maximum=MAX_POPULATION,
                error=EvolutionConfigError,
            )
        self.sigma0 = check_number(
            "CMA-ES config 'sigma0'",
            self.sigma0,
            minimum=0,
            strict_minimum=True,
            error=EvolutionConfigError,
        )
        if not isinstance(self.separable, bool | np.bool_):
            raise EvolutionConfigError(
                f"CMA-ES config 'separable' must be true or false, got {self.separable!r}"
            )
        self.separable = bool(self.separable)
        self.restarts = check_integer(
            "CMA-ES config 'restarts'",
            self.restarts,
            minimum=0,
            maximum=MAX_RESTARTS,
            error=EvolutionConfigError,
        )
        self.cma_options = _check_cma_options(self.cma_options)

    def to_dict(self) -> dict[str, Any]:
        """The configuration as a JSON-ready dictionary (:meth:`from_dict` reads it back)."""
        return {
            "network": {
                key: (list(v) if key == "hidden" else v) for key, v in self.network.items()
            },
            "population_size": self.population_size,
            "sigma0": self.sigma0,
            "separable": self.separable,
            "restarts": self.restarts,
            "cma_options": dict(self.cma_options),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> CMAESConfig:
        """A configuration from a mapping; missing keys take their defaults.

        Unknown keys and bad values raise :class:`EvolutionConfigError` naming them.
        """
        return config_from_dict(cls, data, EvolutionConfigError, "CMA-ES config")


def _check_network(network: Any) -> dict[str, Any]:
    """The network part of a config, checked, with defaults filled in and ``hidden`` a list."""
    if not isinstance(network, Mapping):
        raise EvolutionConfigError(
            f"CMA-ES config 'network' must be a mapping, got {type(network).__name__}"
        )
    network = dict(network)
    kind = network.pop("type", "mlp")
    if kind != "mlp":
        raise EvolutionConfigError(f"CMA-ES config 'network': type {kind!r} is not 'mlp'")
    unknown = sorted(set(network) - set(_NETWORK_KEYS))
    if unknown:
        named = ", ".join(f"{key}{closest(key, _NETWORK_KEYS)}" for key in unknown)
        raise EvolutionConfigError(
            f"CMA-ES config 'network': unknown key(s) {named}"
            f" (expected {', '.join(_NETWORK_KEYS)}; the robot comes from the run)"
        )
    hidden = network.get("hidden", DEFAULT_NETWORK["hidden"])
    activation = network.get("activation", DEFAULT_NETWORK["activation"])
    pool = network.get("pool")
    symmetry = network.get("symmetry", "none")
    try:
        spec = NetworkSpec(
            "DD",
            tuple(hidden) if isinstance(hidden, list) else hidden,
            activation,
            symmetry=symmetry,
        )
    except EvolutionConfigError as error:
        raise EvolutionConfigError(f"CMA-ES config 'network': {error}") from None
    if pool is not None:  # None: the default pooling of image robots
        pool = check_integer(
            "CMA-ES config 'network': pool", pool, minimum=1, error=EvolutionConfigError
        )
    filters = check_integer(
        "CMA-ES config 'network': filters",
        network.get("filters", 0),
        minimum=0,
        maximum=MAX_FILTERS,
        error=EvolutionConfigError,
    )
    stride = network.get("stride")
    if stride is not None:  # None: the default stride of the robot's retina
        stride = check_integer(
            "CMA-ES config 'network': stride", stride, minimum=1, error=EvolutionConfigError
        )
    pooling = network.get("pooling", POOLINGS[0])
    if pooling not in POOLINGS:
        raise EvolutionConfigError(
            f"CMA-ES config 'network': pooling {pooling!r} is not one of {', '.join(POOLINGS)}"
        )
    return {
        "hidden": list(spec.hidden),
        "activation": spec.activation,
        "pool": pool,
        "symmetry": spec.symmetry,
        "filters": filters,
        "stride": stride,
        "pooling": pooling,
    }


def _check_cma_options(options: Any) -> dict[str, Any]:
    """Extra cma options, checked against cma's option names and for JSON values."""
    if not isinstance(options, Mapping):
        raise EvolutionConfigError(
            f"CMA-ES config 'cma_options' must be a mapping, got {type(options).__name__}"
        )
    known = set(cma.CMAOptions())
    checked: dict[str, Any] = {}
    for name, value in options.items():
        if not isinstance(name, str) or name not in known:
            raise EvolutionConfigError(f"CMA-ES config 'cma_options': unknown cma option {name!r}")
        if name in _RESERVED_OPTIONS:
            raise EvolutionConfigError(
                f"CMA-ES config 'cma_options': {name!r} is set by the algorithm"
                " (use population_size, separable or the run's seed)"
            )
        checked[name] = _json_value(f"cma_options.{name}", value)
    return checked


class CMAESAlgorithm:
    """CMA-ES (optionally separable, optionally IPOP) for a network driving ``robot``.

    ``ask()`` gives this generation's candidate parameter vectors (float64,
    ``(spec.n_params,)`` each), :meth:`population_policy` makes them one
    population policy, ``tell(candidates, fitness)`` records their (maximised)
    fitness, updates the champion and the statistics, and restarts the strategy
    when cma stops and restarts remain. Deterministic given ``seed``; pickling the
    object is a checkpoint that resumes bit-identically (see the module docstring).
    It satisfies :class:`~evolution.algorithms.SearchAlgorithm`.
    """

    #: The configuration dataclass (:func:`evolution.algorithms.make_algorithm` reads it).
    config_class: ClassVar[type[CMAESConfig]] = CMAESConfig

    def __init__(
        self, config: CMAESConfig | Mapping[str, Any], robot: Robot | str, seed: int
    ) -> None:
        if isinstance(config, Mapping):
            config = CMAESConfig.from_dict(config)
        if not isinstance(config, CMAESConfig):
            raise EvolutionConfigError(f"expected a CMAESConfig, got {type(config).__name__}")
        config.validate()
        self.seed = check_integer("seed", seed, error=EvolutionConfigError)
        self.config = config
        self.robot = as_robot(robot)
        network = config.network
        self.spec = NetworkSpec(
            robot=self.robot.to_string(),
            hidden=tuple(network["hidden"]),
            activation=network["activation"],
            pool=network["pool"],
            symmetry=network["symmetry"],
            filters=network.get("filters", 0),
            stride=network.get("stride"),
            pooling=network.get("pooling", POOLINGS[0]),
        )
        self._rng = np.random.default_rng(self.seed)
        self._np_state = np.random.RandomState(self.seed).get_state()
        self._generation = 0
        self._restarts = 0
        self._stopped = False
        self._stop_reasons: dict[str, Any] = {}
        self._champion: tuple[np.ndarray, float] | None = None
        self._stats: dict[str, float] = {}
        self._asked: list[np.ndarray] | None = None
        popsize = config.population_size or default_popsize(self.spec.n_params)
        self._es = self._new_strategy(popsize)

    # -- state -------------------------------------------------------------

    @contextlib.contextmanager
    def _own_random(self) -> Iterator[None]:
        """Run with the algorithm's state in ``np.random``, leaving the caller's intact.

        cma's warnings (flat fitness and the like) are silenced: the run loop
        reports the statistics itself. cma's linear algebra runs on one BLAS
        thread (:func:`one_blas_thread`): OpenBLAS sums a product in another
        order on more threads, so the candidates would depend on the
        machine's cores and on ``OMP_NUM_THREADS`` (a study's workers set it
        to 1), not on the config and seed alone.
        """
        outer = np.random.get_state()  # noqa: NPY002
        np.random.set_state(self._np_state)  # noqa: NPY002
        try:
            with warnings.catch_warnings(), one_blas_thread():
                warnings.simplefilter("ignore")
                yield
        finally:
            self._np_state = np.random.get_state()  # noqa: NPY002
            np.random.set_state(outer)  # noqa: NPY002

    def _new_strategy(self, popsize: int) -> cma.CMAEvolutionStrategy:
        """A fresh strategy of ``popsize`` candidates from a new random mean."""
        mean = self.spec.initial_params(self._rng)
        options: dict[str, Any] = {
            **self.config.cma_options,
            "popsize": int(popsize),
            "CMA_diagonal": self.config.separable,
            "randn": _GlobalRandn(),
            "seed": np.nan,
            "verbose": -9,
            "verb_log": 0,
            "verb_disp": 0,
            "verb_filenameprefix": "",
            # cma reads options from a file of this name in the working directory at
            # every iteration; a run depends on its config and seed alone.
            "signals_filename": "",
        }
        with self._own_random():
            try:
                return cma.CMAEvolutionStrategy(mean, self.config.sigma0, options)
            except (ValueError, TypeError) as error:
                raise EvolutionConfigError(f"cma rejected the CMA-ES options: {error}") from None

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a checkpoint, refusing cma options that cma would evaluate as code."""
        self.__dict__.update(state)
        for name, value in self._es.opts.items():
            if isinstance(value, str) and value:
                raise EvolutionConfigError(
                    f"the CMA-ES strategy's option {name!r} holds the string {value!r}"
                    " (cma evaluates option strings as code)"
                )

    # -- interface ---------------------------------------------------------

    @property
    def generation(self) -> int:
        """Generations told so far (over all restarts)."""
        return self._generation

    @property
    def restarts(self) -> int:
        """IPOP restarts done so far."""
        return self._restarts

    @property
    def popsize(self) -> int:
        """Candidates per generation of the current strategy."""
        return int(self._es.popsize)

    @property
    def es(self) -> cma.CMAEvolutionStrategy:
        """The current ``cma`` strategy (read it, do not drive it)."""
        return self._es

    @property
    def stopped(self) -> bool:
        """True once cma's termination criteria fired with no restart left."""
        return self._stopped

    @property
    def stop_reasons(self) -> dict[str, Any]:
        """cma's termination criteria that fired last (``{}`` while running)."""
        return dict(self._stop_reasons)

    @property
    def champion(self) -> tuple[np.ndarray, float] | None:
        """The best parameters ever told and their fitness (the first on ties), None before."""
        if self._champion is None:
            return None
        params, fitness = self._champion
        return params.copy(), fitness

    def champion_arrays(self) -> tuple[dict[str, np.ndarray], dict]:
        """The champion for an agent file: ``({"params": float64}, {"type": "mlp", ...spec})``."""
        if self._champion is None:
            raise RuntimeError("no champion yet: tell() the fitness of a generation first")
        return self.candidate_arrays(self._champion[0])

    def candidate_arrays(self, candidate: np.ndarray) -> tuple[dict[str, np.ndarray], dict]:
        """A candidate parameter vector for an agent file (as :meth:`champion_arrays`)."""
        params = np.array(candidate, dtype=np.float64)
        return {"params": params}, {"type": "mlp", **self.spec.to_dict()}

    def ask(self) -> list[np.ndarray]:
        """This generation's candidate parameter vectors (asking again gives the same ones)."""
        if self._stopped:
            raise RuntimeError("CMA-ES has stopped (no restart left): see stop_reasons")
        if self._asked is None:
            with self._own_random():
                asked = self._es.ask()
            self._asked = [np.array(x, dtype=np.float64) for x in asked]
        return [x.copy() for x in self._asked]

    def population_policy(self, candidates: Sequence[np.ndarray]) -> NetworkPopulation:
        """``candidates`` as one population policy (agent ``k`` uses candidate ``k // M``)."""
        return self.spec.population(np.stack([np.asarray(c) for c in candidates]))

    def tell(self, candidates: Sequence[np.ndarray], fitness: np.ndarray) -> None:
        """Record the (maximised) fitness of the last asked candidates; step or restart cma."""
        asked = self._asked
        if asked is None:
            raise ValueError("tell() needs the candidates of the last ask(), none are pending")
        if len(candidates) != len(asked) or any(
            not np.array_equal(np.asarray(a), b) for a, b in zip(candidates, asked, strict=False)
        ):
            raise ValueError("tell() needs the candidates of the last ask(), in the same order")
        fitness = np.asarray(fitness, dtype=np.float64).reshape(-1)
        if fitness.shape[0] != len(asked):
            raise ValueError(f"{fitness.shape[0]} fitness values for {len(asked)} candidates")
        if not np.all(np.isfinite(fitness)):
            raise ValueError("fitness values must be finite")
        best = int(np.argmax(fitness))
        if self._champion is None or fitness[best] > self._champion[1]:
            self._champion = (asked[best].copy(), float(fitness[best]))
        popsize = len(asked)
        with self._own_random():
            self._es.tell(asked, (-fitness).tolist())
            stop = dict(self._es.stop())
        self._asked = None
        self._generation += 1
        self._stats = {
            "best": float(fitness[best]),
            "mean": float(fitness.mean()),
            "std": float(fitness.std()),
            "min": float(fitness.min()),
            "sigma": float(self._es.sigma),
            "popsize": float(popsize),
            "restarts": float(self._restarts),
            "champion": self._champion[1],
        }
        self._stop_reasons = stop
        if stop:
            if self._restarts < self.config.restarts:
                self._restarts += 1
                self._es = self._new_strategy(2 * popsize)
            else:
                self._stopped = True

    def reseed(self, seed: int) -> None:
        """Fresh random streams seeded with ``seed``: numpy's state for cma and the mean generator.

        Candidates asked but not told are dropped (they came from the old
        stream); the strategy (mean, covariance, step size) is kept.
        """
        self.seed = check_integer("seed", seed, error=EvolutionConfigError)
        self._rng = np.random.default_rng(self.seed)
        self._np_state = np.random.RandomState(self.seed).get_state()
        self._asked = None

    def forget_champion(self) -> None:
        """Forget the champion: the next ``tell`` starts a new one (see the protocol)."""
        self._champion = None

    def stats(self) -> dict[str, float]:
        """The last generation's statistics, ``{}`` before the first tell.

        ``best``, ``mean``, ``std``, ``min`` of its fitness, ``champion`` (best
        ever), ``popsize``, ``sigma`` (cma's step size after the update) and
        ``restarts`` (the restarts done before that generation).
        """
        return dict(self._stats)

    def describe(self) -> str:
        """A one-line summary for the run log."""
        hidden, activation = self.spec.hidden, self.spec.activation
        network = f"hidden {list(hidden)} {activation}" if hidden else "linear"
        kind = "sep-CMA-ES" if self.config.separable else "CMA-ES"
        restarts = f", IPOP restarts {self._restarts}/{self.config.restarts}"
        return (
            f"{kind} {self.robot} {network}: {self.spec.n_params} params,"
            f" popsize {self.popsize}, sigma0 {self.config.sigma0:g}"
            + (restarts if self.config.restarts else "")
        )
