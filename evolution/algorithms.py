"""What a search algorithm offers the generation loop, and the registry of algorithms by name.

:class:`SearchAlgorithm` is the interface the run loop drives, one generation
at a time: ``ask`` for candidates, turn them into one population policy,
have an evaluation backend play it, ``tell`` the fitness back. CMA-ES
(:class:`~evolution.cmaes.CMAESAlgorithm`) and the NEAT-like GA
(:class:`~evolution.neat.NeatAlgorithm`) both satisfy it.

:data:`ALGORITHMS` names each algorithm's class as ``"module:Class"``, so that
no algorithm module (nor ``cma`` or ``deap``) is imported before a run asks
for it; :func:`make_algorithm` builds one from a name and its JSON options.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from evolution import EvolutionConfigError

if TYPE_CHECKING:
    from evolution.population import PopulationPolicy

__all__ = [
    "ALGORITHMS",
    "SearchAlgorithm",
    "algorithm_class",
    "make_algorithm",
    "population_size",
]


@runtime_checkable
class SearchAlgorithm(Protocol):
    """A population-based search driven by ask / tell, one generation per round.

    ``ask()`` gives the candidates to evaluate (parameter vectors, genomes...),
    :meth:`population_policy` compiles them into one batched policy for the
    evaluator (agent ``k`` of ``P * M`` plays candidate ``k // M``), and
    ``tell(candidates, fitness)`` hands back their fitness (maximised), after
    which the algorithm updates its champion and statistics and prepares the
    next generation. The model is pycma's ``interfaces.OOOptimizer``.
    ``reseed`` and ``forget_champion`` serve curricula: branches copied from
    one state draw from their own random streams, and a stage's new mazes
    start a new champion.

    **Algorithms never call the simulator**: evaluation is the caller's
    business (an evaluation backend, local or distributed), so the same
    algorithm runs whatever plays its candidates.

    **The algorithm object is its own checkpoint state.** It holds everything
    a run needs to go on, the states of its own random generators included
    (swapped into ``random`` or ``np.random`` around its own draws only, so
    that nothing else advances them), and is pickled whole today: a run
    resumed from the pickle continues bit-identically.

    Classes listed in :data:`ALGORITHMS` also take ``(config, robot, seed)``
    and name their config dataclass (with ``from_dict``) in a class attribute
    ``config_class``, which :func:`make_algorithm` relies on.
    """

    def ask(self) -> list[Any]:
        """The candidates of this generation, in the order ``tell`` expects them back."""
        ...

    def population_policy(self, candidates: Sequence[Any]) -> PopulationPolicy:
        """``candidates`` as one batched policy (agent ``k`` uses candidate ``k // M``)."""
        ...

    def tell(self, candidates: Sequence[Any], fitness: np.ndarray) -> None:
        """Record the (maximised) fitness of the last asked candidates; breed the next ones."""
        ...

    @property
    def champion(self) -> tuple[Any, float] | None:
        """The best candidate ever told and its fitness, None before the first tell."""
        ...

    @property
    def stopped(self) -> bool:
        """True when the algorithm cannot go on (e.g. CMA-ES with no restart left)."""
        ...

    @property
    def generation(self) -> int:
        """Generations told so far."""
        ...

    def champion_arrays(self) -> tuple[dict[str, np.ndarray], dict]:
        """The champion's arrays and its architecture metadata, for an agent file."""
        ...

    def candidate_arrays(self, candidate: Any) -> tuple[dict[str, np.ndarray], dict]:
        """Any candidate of ``ask()`` as :meth:`champion_arrays` gives the champion."""
        ...

    def stats(self) -> dict[str, float]:
        """The last generation's statistics (best, mean...), ``{}`` before the first tell."""
        ...

    def reseed(self, seed: int) -> None:
        """Replace the algorithm's own random streams by fresh ones seeded with ``seed``.

        Everything else (population, strategy, champion) is kept: copies of
        one state reseeded differently (the branches of a curriculum) draw
        independently from then on, and copies reseeded alike draw alike.
        """
        ...

    def forget_champion(self) -> None:
        """Forget the champion: the next ``tell`` starts a new one.

        For a change of mazes (a curriculum's next stage): fitness told so
        far no longer compares with fitness told from then on, so neither the
        champion nor the algorithm's other records of past fitness (NEAT's
        species progress) should outrank the new mazes' candidates.
        """
        ...


#: The algorithms by name: ``"module:Class"`` of a :class:`SearchAlgorithm`
#: class, imported only when :func:`algorithm_class` is asked for it.
ALGORITHMS: dict[str, str] = {
    "cmaes": "evolution.cmaes:CMAESAlgorithm",
    "neat": "evolution.neat:NeatAlgorithm",
}


def algorithm_class(name: str) -> type:
    """The class registered as ``name`` in :data:`ALGORITHMS` (its module imported now).

    An unknown name raises :class:`~evolution.EvolutionConfigError` naming it
    and the choices.
    """
    target = ALGORITHMS.get(name) if isinstance(name, str) else None
    if target is None:
        raise EvolutionConfigError(
            f"unknown algorithm {name!r} (choose from {', '.join(ALGORITHMS)})"
        )
    module, _, attribute = target.partition(":")
    return getattr(importlib.import_module(module), attribute)


def make_algorithm(name: str, options: Mapping[str, Any], robot: str, seed: int) -> SearchAlgorithm:
    """A fresh algorithm ``name`` for ``robot``, seeded with ``seed``.

    ``options`` are the algorithm's own settings as JSON (a
    :class:`~evolution.cmaes.CMAESConfig` or :class:`~evolution.neat.NeatConfig`
    mapping), read by the class's ``config_class.from_dict``: missing keys take
    their defaults, unknown keys and bad values raise
    :class:`~evolution.EvolutionConfigError` naming them.
    """
    cls = algorithm_class(name)
    return cls(cls.config_class.from_dict(options), robot, seed)


def population_size(algorithm: SearchAlgorithm) -> int:
    """The candidates of the algorithm's next generation.

    CMA-ES knows it without sampling them (its ``popsize``): the sampling, with
    its occasional eigendecomposition, then happens where the generation asks,
    and is timed there; other algorithms are asked.
    """
    size = getattr(algorithm, "popsize", None)
    return int(size) if size is not None else len(algorithm.ask())
