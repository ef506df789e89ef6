"""Evolution in the ``edens-populations`` regime: EDEnS over co-evolved maze populations.

``amaze-evolve --regime edens-populations --budget-seconds 300 --out runs/ep``
runs the co-evolution loop of :mod:`evolution.coevolution` (a generation on a
batch of the maze population, the champion on validation mazes) under the
EDEnS selector of :mod:`amaze.runs.edens_populations`: every epoch, the
search algorithm and the maze population are copied into the selector's
alternatives, each plays ``selector.epoch`` generations with its own
population controller, and one goes on. An alternative's learner is its
search algorithm (CMA-ES's or NEAT's whole state, random generator
included); the champion is kept in the run's state, outside the alternatives.
"""

from __future__ import annotations

from typing import Any

from amaze.runs.edens_populations import EPOCH_FIELDS, EdensPopulationsRun
from evolution.algorithms import SearchAlgorithm
from evolution.coevolution import PROGRESS_FIELDS, EvolutionCoevolutionRun

__all__ = ["EvolutionEdensPopulationsRun"]


class EvolutionEdensPopulationsRun(EdensPopulationsRun, EvolutionCoevolutionRun):
    """Generations of agents on co-evolved mazes, the population's controller selected by EDEnS."""

    progress_fields = (*PROGRESS_FIELDS, *EPOCH_FIELDS)

    def learner(self) -> SearchAlgorithm:
        return self.state.algorithm

    def adopt_learner(self, learner: Any) -> None:
        self.state.algorithm = learner
