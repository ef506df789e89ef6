"""The ``coevolution`` regime with ``--framework jax``: a JAX trainer and a maze population.

``amaze-train --framework jax --algo ppo --regime coevolution --budget-steps 3000000``
runs the rounds of :class:`~rl_baselines.coevolution.RLCoevolutionRun` (the
population proposes ``n_envs / 4`` mazes, the learner trains on their rotations
for as many rollouts as their longest episode may last, the round's own
episodes score them, the agent plays the validation mazes every
``validation_every`` rounds, the best there is the champion) with a
:class:`~rl_baselines.jax.trainer.JaxTrainer` as the learner.

What is the JAX learner's own:

* **one compiled function for every round.** The trainer's maze tables are
  padded to the population's largest maze (``max_size`` squared cells, the
  target's larger side by default); their observation codes to a power of two
  (:mod:`amaze.envs.jax.params`), so a run compiles once or twice, whatever
  mazes the population proposes, and a round changes only the arrays;
* **per-environment episode sums** (:class:`~rl_baselines.jax.rollout.EpisodeSums`)
  score the round's mazes, as SB3's ``infos`` do for SB3;
* **a bit-identical resume on one machine**: the checkpoint holds the whole
  training state (parameters, optimizer, random key) in
  ``checkpoints/trainer-<round>/`` (written whole, atomically, before
  ``state.npz`` names it); every round resets the environments into its mazes,
  so a run killed and resumed ends with the same agent as one never
  interrupted (SB3 saves neither its random generators nor its environments).

No ``tensorboard/`` (the config refuses ``--tensorboard`` with this framework).
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from amaze.curriculum.maze_population import MazePopulation
from amaze.maze import Maze, MazeSpec, as_mazes, rotations
from amaze.runs.checkpoint import StateCodec, curriculum_classes
from amaze.runs.coevolution import CoevolutionRun, CoevolutionState
from rl_baselines.coevolution import EndedEpisodes, RLCoevolutionRun, named_checkpoint
from rl_baselines.config import TrainConfig
from rl_baselines.jax.agent import JaxAgent, NetworkRunFiles
from rl_baselines.jax.storage import save_trainer
from rl_baselines.jax.trainer import JaxTrainer, load_trainer

__all__ = ["JaxCoevolutionRun"]


@dataclass(kw_only=True)
class _JaxState(CoevolutionState):
    """The run state of ``checkpoints/state.npz``: the loop's, and the trainer folder it names."""

    VERSION: ClassVar[int] = 1

    #: Env steps of the episodes that scored the batches.
    scoring_steps: int = 0
    trainer_folder: str = ""


class JaxCoevolutionRun(NetworkRunFiles, RLCoevolutionRun):
    """The co-evolution rounds of a JAX trainer (see the module docstring)."""

    state: _JaxState
    state_class = _JaxState
    outputs: ClassVar[tuple[str, ...]] = ("agent.zip", "agent.npz", *CoevolutionRun.outputs)

    def __init__(self, out: str | os.PathLike, config: TrainConfig) -> None:
        super().__init__(out, config)
        self.trainer: JaxTrainer | None = None

    @property
    def rollout(self) -> int:
        assert self.trainer is not None
        return self.trainer.hyperparameters.rollout_size

    @property
    def n_steps(self) -> int:
        assert self.trainer is not None
        return self.trainer.hyperparameters.n_steps

    def max_cells(self) -> int:
        """Cells of the population's largest maze: its tables' padded size."""
        target = MazeSpec.from_string(self.config.target)
        side = self.options.max_size or max(target.width, target.height)
        return max(side * side, target.width * target.height)

    # -- the framework's part ---------------------------------------------------

    def new_state(self, mazes: MazePopulation) -> _JaxState:
        c = self.config
        self.trainer = JaxTrainer(
            c.algo,
            c.robot,
            as_mazes(rotations(c.target)) * (c.n_envs // 4),
            c.hyperparameters,
            seed=c.seed,
            n_envs=c.n_envs,
            max_cells=self.max_cells(),
            network=c.network,
            progress_reward=c.progress_reward,
        )
        return _JaxState(mazes)

    def state_codec(self) -> StateCodec:
        """The run state and the maze population's classes."""
        return StateCodec([_JaxState, *curriculum_classes()])

    def restore_learner(self, state: CoevolutionState) -> None:
        """The trainer the state names, and a look at the champion (a damaged one is refused)."""
        assert isinstance(state, _JaxState)
        trainer = load_trainer(named_checkpoint(self, state.trainer_folder))
        c = self.config
        expected = {
            "algo": c.algo,
            "robot": c.robot,
            "n_envs": c.n_envs,
            "network": c.network,
            "progress_reward": c.progress_reward,
        }
        trainer.check_settings(expected, f"checkpoint {str(self.checkpoint)!r}")
        self.trainer = trainer
        self.check_champion()

    def set_round_mazes(self, mazes: list[Maze]) -> int:
        assert self.trainer is not None
        self.trainer.set_mazes(mazes)
        return int(np.max(np.asarray(self.trainer.maze_params.deadline)))

    def train_round(self, rollouts: int) -> EndedEpisodes:
        assert self.trainer is not None
        before = self.trainer.num_timesteps
        stats = self.trainer.run(rollouts)
        # added, not copied: in edens-populations the trainer's counter goes back with the
        # parent's state at every alternative, while every alternative's steps count
        self.state.steps += self.trainer.num_timesteps - before
        return EndedEpisodes(
            stats.episodes.sum(axis=0),
            stats.successes.sum(axis=0).astype(np.float64),
            stats.normalized_reward.sum(axis=0).astype(np.float64),
        )

    def rollouts_per_piece(self) -> int:
        """One compiled call of the trainer (:attr:`JaxTrainer.chunk` rollouts)."""
        assert self.trainer is not None
        return self.trainer.chunk

    def agent_now(self) -> JaxAgent:
        assert self.trainer is not None
        return JaxAgent(self.trainer)

    def save_learner(self) -> None:
        """The trainer as ``trainer-<round>/``, which the state then names."""
        assert self.trainer is not None
        name = f"trainer-{self.state.round}"
        save_trainer(self.trainer, self.checkpoints / name)
        self.state.trainer_folder = name

    def learner_saved(self) -> None:
        """The trainer folders the state no longer names go."""
        for old in (*self.checkpoints.glob("trainer-*"), *self.checkpoints.glob(".trainer-*")):
            if old.name != self.state.trainer_folder and old.is_dir():
                shutil.rmtree(old)  # older trainers, and what a killed save left aside

    def own_figures(self) -> dict[str, Any]:
        return {**super().own_figures(), "max_cells": self.max_cells(), **self.network_figures()}
