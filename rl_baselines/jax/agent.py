"""A JAX trainer's policy as a run's agent: evaluated in numpy, saved as an SB3 agent.

:class:`JaxAgent` is what a ``--framework jax`` run hands over and evaluates:
the policy of the trainer at the moment the agent was taken (a snapshot: the
trainer training on does not change it), acting deterministically through
:class:`~rl_baselines.jax.policy.NumpyPolicy` (no torch, no compilation per
batch size). :meth:`JaxAgent.save` writes it as SB3 writes its agents (the
zip and the JSON beside it, :func:`rl_baselines.jax.sb3_io.export_sb3`), so
``agent.zip`` of a JAX run is read by :meth:`rl_baselines.agent.SB3Agent.load`,
``amaze evaluate`` and ``amaze run`` exactly as an SB3 run's.
"""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from rl_baselines.jax.trainer import JaxTrainer

__all__ = ["JaxAgent"]


class JaxAgent:
    """The policy of ``trainer`` now, deterministic; ``save`` writes an SB3 agent."""

    def __init__(self, trainer: JaxTrainer) -> None:
        self._trainer = copy.copy(trainer)  # its state is immutable arrays: a snapshot
        self.policy = trainer.policy()
        self.robot = self.policy.robot
        self.algo = trainer.hyperparameters.algo
        #: Env steps the policy was trained on.
        self.num_timesteps = trainer.num_timesteps

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """Deterministic actions for a batch of observations (int64 ``(n,)``)."""
        return self.policy(observations)

    def params(self) -> dict[str, dict[str, np.ndarray]]:
        """The policy's parameters (SB3's names, torch's layout)."""
        return self.policy.params

    def save(self, path: str | os.PathLike) -> Path:
        """The SB3 zip (and its JSON) of the policy and optimizer state; the zip's path."""
        return self._trainer.export_sb3(path)
