"""The ``edens-populations`` regime with ``--framework jax``: EDEnS over maze populations.

``amaze-train --framework jax --preset fast --regime edens-populations --budget-seconds 300``
runs the co-evolution rounds of :class:`~rl_baselines.jax.coevolution.JaxCoevolutionRun`
under the EDEnS selector of :mod:`amaze.runs.edens_populations`: every epoch,
the learner and the maze population are copied into the selector's
alternatives, each plays ``selector.epoch`` rounds with its own population
controller, and one goes on, as in evolution's
(:mod:`evolution.edens_populations`).

An alternative's learner is the JAX trainer's whole training state as named
numpy arrays (:meth:`~rl_baselines.jax.trainer.JaxTrainer.state_arrays`:
parameters, optimizer moments, random key, environments, counters), so the
copies are plain data: a checkpoint taken in the middle of an epoch holds the
parent's and the finished alternatives' states like any other array, and a
resumed run goes on as one never interrupted. Every alternative's env steps
count in the budget (the trainer's own counter goes back with the copy it
adopts; the run's ``steps`` does not).

SB3 (``--framework sb3``) is refused in this regime: its model and rollout
buffer cannot be copied into a checkpoint as data.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from amaze.runs.coevolution import CoevolutionRun
from amaze.runs.edens_populations import EPOCH_FIELDS, EPOCHS_FILE, EdensPopulationsRun
from rl_baselines.coevolution import PROGRESS_FIELDS
from rl_baselines.jax.coevolution import JaxCoevolutionRun

__all__ = ["JaxEdensPopulationsRun"]


class JaxEdensPopulationsRun(EdensPopulationsRun, JaxCoevolutionRun):
    """Rounds of a JAX learner on co-evolved mazes, their population steered by EDEnS."""

    progress_fields = (*PROGRESS_FIELDS, *EPOCH_FIELDS)
    outputs: ClassVar[tuple[str, ...]] = (
        "agent.zip",
        "agent.npz",
        *CoevolutionRun.outputs,
        EPOCHS_FILE,
        "epochs.png",
    )

    def learner(self) -> dict[str, np.ndarray]:
        """The trainer's whole training state, copied out of the device as numpy arrays."""
        assert self.trainer is not None
        return {name: np.array(value) for name, value in self.trainer.state_arrays().items()}

    def adopt_learner(self, learner: Any) -> None:
        """Continue from ``learner`` (arrays of :meth:`learner`, checked by the trainer)."""
        assert self.trainer is not None
        self.trainer.load_state_arrays(learner)
