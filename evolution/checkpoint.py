"""What an evolution checkpoint may hold: the classes and values of its states.

A run's ``checkpoints/state.npz`` and a curriculum learner's ``learner.npz``
are written and read by :mod:`amaze.runs.checkpoint`, which rebuilds only what
a :class:`~amaze.runs.checkpoint.StateCodec` registers. :func:`evolution_codec`
is that codec for evolution: the run states, the learner, both search
algorithms and their parts, the co-evolved maze population, and the objects
of ``cma`` and ``deap`` inside the algorithms (every class those packages
define, since which of them a strategy holds depends on its options).
"""

from __future__ import annotations

import functools
import operator
from typing import Any

import numpy as np

from amaze.runs.checkpoint import StateCodec, curriculum_classes, package_classes

__all__ = ["evolution_codec"]


def _subclasses(module: Any, base: type) -> list[type]:
    """The subclasses of ``base`` (itself included) defined in ``module``."""
    return [v for v in vars(module).values() if isinstance(v, type) and issubclass(v, base)]


@functools.cache
def _libraries() -> StateCodec:
    """The classes and values every evolution state may hold, from the loaded algorithms up."""
    import cma
    import cma.boundary_handler
    import cma.options_parameters
    import cma.sigma_adaptation
    from deap import tools

    import evolution.generations  # noqa: F401 (the state's ChosenAgent)
    from evolution.algorithms import ALGORITHMS, algorithm_class

    for name in ALGORITHMS:
        algorithm_class(name)
    classes = [
        *package_classes("evolution.cmaes"),
        *package_classes("evolution.generations"),
        *package_classes("evolution.networks"),
        *package_classes("evolution.neat"),
        *curriculum_classes(),
        *package_classes("cma"),
        *package_classes("deap"),
    ]
    constants = [
        operator.eq,  # deap's HallOfFame compares individuals with it
        cma.evolution_strategy._pass,
        cma.options_parameters.is_feasible,
        np.linalg.eigh,
        tools.Logbook,  # the factory of a Logbook's chapters
        # classes that cma's options name as values (``BoundaryHandler``, ``AdaptSigma``)
        *_subclasses(cma.boundary_handler, cma.boundary_handler.BoundaryHandlerBase),
        *_subclasses(cma.sigma_adaptation, cma.sigma_adaptation.CMAAdaptSigmaBase),
    ]
    return StateCodec(classes, constants)


@functools.cache
def evolution_codec(*classes: type) -> StateCodec:
    """The codec of an evolution checkpoint holding ``classes`` (a run's own state class).

    Beside ``classes``: the classes of both algorithms and their networks, the
    robot, the curriculum's (the co-evolved maze population), ``cma``'s and
    ``deap``'s.
    """
    return _libraries().union(StateCodec(classes))
