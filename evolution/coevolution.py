"""Evolution in the ``coevolution`` regime: agents and a maze population evolve together.

``amaze-evolve --regime coevolution --budget-seconds 300 --out runs/co`` runs
the shared co-evolution loop (:class:`~amaze.runs.coevolution.CoevolutionRun`:
the population, the champion on validation mazes, budgets, checkpoints,
``mazes.csv``, ``population.png``, ``coevolution.png``) with a search
algorithm as its learner; a round is a *generation*::

    batch = mazes.propose()                      # the loop
    result = play(algorithm.ask(), batch)        # every agent, every maze, 4 rotations (slips)
    algorithm.tell(candidates, result.fitness)   # fitness: mean over the batch
    mazes.update(batch, per-maze results)        # the loop
    validate(the generation's best agents)       # the loop, every validation_every-th

What is evolution's own here: the generation on a batch, the validation of
the ``validation_candidates`` best agents of the batch (the run's
``fitness`` measure on the validation mazes), the champion kept in the
checkpoint's state as a :class:`~evolution.generations.ChosenAgent` (written
at the end as ``agent.npz``), the CMA-ES options of the regime
(:func:`evolution.config.coevolution_cmaes`), and the figures
``generations``, ``champion_fitness``, ``policy_steps_per_second``. Env steps
count every episode played, validation included; ``summary.json``'s
``time`` splits the seconds into evaluation, breeding, mazes, validation,
logging and checkpoints. A checkpoint is written every
``checkpoint_seconds`` of run time.

**Backends.** With ``--backend ray`` the agents are played on Ray actors
(:mod:`evolution.backends`): each generation's batch of mazes is compiled
here and put in the object store once, and the actors read it at their
first part of that generation; the results, and so the run, are
bit-identical to the local backend's.

**Resume.** The checkpoint holds the algorithm, the maze population (its
members, records, scores and random generator) and the champion, so a run
resumed after a kill goes on bit-identically (seconds budgets aside).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from amaze.curriculum.maze_population import MazePopulation
from amaze.maze import Maze
from amaze.runs.branches import Clock
from amaze.runs.checkpoint import StateCodec
from amaze.runs.coevolution import BatchResults, CoevolutionRun, CoevolutionState, Validation
from amaze.runs.coevolution_picture import Curve
from evolution.algorithms import SearchAlgorithm, make_algorithm, population_size
from evolution.backends import current_backend
from evolution.checkpoint import evolution_codec
from evolution.config import EvolveConfig
from evolution.generations import ChosenAgent, chosen_policy, save_chosen, search_stop_reason
from evolution.population import EvaluationBackend
from evolution.slip import SlippingPopulation

__all__ = ["EvolutionCoevolutionRun"]

PROGRESS_FIELDS = (
    "generation", "steps", "seconds", "best", "mean", "champion", "eval_seconds",
    *CoevolutionRun.population_fields, "diversity",
)  # fmt: skip


@dataclass(kw_only=True)
class _State(CoevolutionState):
    """The run state saved in every checkpoint: the loop's, the algorithm and the champion."""

    #: Version 2 names rounds as the shared loop does (version 1: ``generation``...).
    VERSION: ClassVar[int] = 2

    algorithm: SearchAlgorithm
    #: Seconds spent playing the batches.
    eval_seconds: float = 0.0
    #: The champion: the best agent on the validation mazes so far.
    agent: ChosenAgent | None = None

    @classmethod
    def upgrade(cls, attributes: dict[str, Any]) -> dict[str, Any]:
        """A version 1 state counted ``generation`` and ``champion_generation``."""
        if attributes.get("version") == 1:
            attributes["round"] = attributes.pop("generation", 0)
            attributes["champion_round"] = attributes.pop("champion_generation", 0)
            attributes["champion_steps"] = getattr(attributes.get("agent"), "steps", 0)
            attributes["version"] = cls.VERSION
        return attributes


class EvolutionCoevolutionRun(CoevolutionRun):
    """Generations of agents on batches of a co-evolving maze population."""

    config_class = EvolveConfig
    config: EvolveConfig
    state: _State
    state_class = _State
    agent_file = "agent.npz"
    position_field = "generation"
    progress_fields = PROGRESS_FIELDS
    outputs: ClassVar[tuple[str, ...]] = ("agent.npz", *CoevolutionRun.outputs)
    time_parts = ("evaluation", "breeding")
    validated_before_learning = True  # a generation validates the candidates it asked
    batch_plot = (
        "fitness",
        (
            Curve("mean", "mean on the batch", ":"),
            Curve("best", "best on the batch", "-", 0.8),
        ),
    )

    @cached_property
    def validation(self) -> EvaluationBackend:
        """The validation mazes in their rotations, for a few agents at once."""
        c = self.config
        return current_backend().evaluator(
            self.validation_mazes,
            c.robot,
            fitness=c.fitness,
            rotations=True,
            n_policies=self.options.validation_candidates,
        )

    # -- the loop's hooks -----------------------------------------------------

    def new_state(self, mazes: MazePopulation) -> _State:
        c = self.config
        state = _State(mazes=mazes, algorithm=make_algorithm(c.algo, c.algorithm, c.robot, c.seed))
        self.validation  # noqa: B018 (the validation mazes are compiled before the folder is written)
        return state

    def state_codec(self) -> StateCodec:
        return evolution_codec(_State)

    def restore_learner(self, state: CoevolutionState) -> None:
        self.validation  # noqa: B018

    def smallest_unit(self) -> tuple[int, str, str]:
        """The population on a batch's episodes (4 rotations each), at least a step each.

        The population's size (:func:`~evolution.algorithms.population_size`)
        needs no sampling: CMA-ES samples in :meth:`learn`, timed as breeding.
        """
        population = population_size(self.state.algorithm)
        episodes = 4 * self.options.batch
        detail = f"{population} individuals on {episodes} episodes, a step each at least"
        return population * episodes, "generation", detail

    def goes_on(self) -> bool:
        return not self.state.algorithm.stopped

    def round_limit(self) -> int | None:
        return self.config.max_generations

    def checkpoint_due(self, steps: int, seconds: float) -> bool:
        return seconds >= self.config.checkpoint_seconds

    def learn(self, mazes: list[Maze], clock: Clock) -> BatchResults:
        """One generation on the batch: ask, play every candidate on every maze, tell."""
        c, s = self.config, self.state
        algorithm = s.algorithm
        candidates = algorithm.ask()
        clock.lap("breeding")
        evaluator = current_backend().evaluator(
            mazes, c.robot, fitness=c.fitness, n_policies=len(candidates)
        )
        clock.lap("mazes")
        policy = algorithm.population_policy(candidates)
        if c.slip:  # generation g of seed s slips as (s, g) says: a resumed run slips alike
            policy = SlippingPopulation(policy, c.slip, [c.seed, s.round])
        clock.lap("breeding")
        result = evaluator.evaluate(policy)
        clock.lap("evaluation")
        algorithm.tell(candidates, result.fitness)
        clock.lap("breeding")
        s.steps += result.env_steps
        s.eval_seconds += result.seconds
        top = np.argsort(-result.fitness, kind="stable")[: self.options.validation_candidates]
        figures = {
            "best": float(np.max(result.fitness)),
            "mean": float(np.mean(result.fitness)),
            "eval_seconds": round(result.seconds, 4),
        }
        return BatchResults(
            result.per_episode("success"),
            result.per_episode("normalized_reward"),
            [candidates[i] for i in top],
            figures,
        )

    def validate(self, candidates: Sequence[Any]) -> Validation:
        """The generation's best candidates, together, on the validation mazes."""
        checked = self.validation.evaluate(self.state.algorithm.population_policy(candidates))
        return Validation(checked.fitness, checked.success_rate, checked.env_steps)

    def keep_champion(self, candidates: Sequence[Any], index: int) -> None:
        """The champion's arrays, kept in the state (written at the end as ``agent.npz``)."""
        c, s = self.config, self.state
        arrays, architecture = s.algorithm.candidate_arrays(candidates[index])
        extra = {
            "regime": c.regime,
            "target": c.target,
            "validation_mazes": self.validation_mazes,
            "fitness": s.champion_fitness,
        }
        s.agent = ChosenAgent(
            {k: np.array(v) for k, v in arrays.items()},
            dict(architecture),
            s.champion_round,
            s.steps,
            (s.champion_fitness,),
            extra,
        )

    def shown_figures(self, row: Mapping[str, Any]) -> dict[str, Any]:
        rate = self.state.steps / max(self.state.eval_seconds, 1e-9)
        return {"best": f"{row['best']:.3f}", "steps_s": f"{rate / 1e6:.2f}M"}

    # -- the lifecycle's hooks ------------------------------------------------

    def final_agent(self) -> Any:
        return chosen_policy(self.state.agent, self.config)

    def save_agent(self, agent: Any, path: Path) -> None:
        assert self.state.agent is not None
        save_chosen(self.state.agent, self.config, path)

    def stop_reason(self) -> str:
        s = self.state
        return search_stop_reason(s.algorithm, self.config, s.round) or super().stop_reason()

    def own_figures(self) -> dict[str, Any]:
        c, s = self.config, self.state
        return {
            "fitness_measure": c.fitness,
            "champion_fitness": s.champion_fitness,
            "evaluation_seconds": round(s.eval_seconds, 3),
            "policy_steps_per_second": round(s.steps / max(s.eval_seconds, 1e-9)),
        }
