"""Anytime evaluations: the agent a run would hand over, played on one fixed set as it trains.

Every run of every trainer and regime (direct, interpolation, EDHuCAT, EDEnS,
co-evolution; CMA-ES, NEAT-like, A2C, PPO) is evaluated the same way while it
trains, so that runs of different methods can be compared over time on one
quantity (SB3's ``EvalCallback`` and jaxued's held-out levels do this for one
method each):

* **when**: at ``evaluation_points`` evenly spaced fractions of the run's
  budget (default 20: 5 %, 10 %, ... 100 %), in env steps when the run has a
  steps budget, else in training seconds (else, for evolution, in
  generations). A point is taken at the end of the first unit of training
  (generation, rollout, curriculum branch) that reaches it, with the steps and
  seconds spent then; the last point is always the run's final agent, taken
  when training ends (so a run that stops early still ends its curve);
* **what**: the agent the run would hand over if it stopped then
  (:meth:`~amaze.runs.lifecycle.Run.current_agent`: the agent rule's choice
  so far, a curriculum's latest selection, a co-evolution's validation
  champion);
* **where**: the :class:`EvaluationSet`: ``evaluation_family`` mazes of the
  training family with new seeds (never the evaluation suite's, nor a run's
  validation or unseen mazes: another seed stream), and the training mazes
  themselves, each in its 4 rotations (a direct run's ``evaluation_maze``,
  if it names one, stands for its training mazes: domain randomisation then
  plays the curricula's set). It depends on the config's family
  maze, counts and robot only, so every run of a study has the same set; its
  digest is in every row;
* **cost**: each evaluation's seconds are measured and kept out of the
  training budget (the trainer's clock does not run meanwhile), and reported
  (``evaluation_seconds`` per row, their sum in ``summary.json``).

``evaluations.csv`` has one row per point (:data:`EVALUATION_FIELDS`); the
points reached by a unit that crosses several share one evaluation (its
cost on the first of their rows, 0 on the others).
On resume, the rows written after the checkpoint resumed are dropped, as for
``progress.csv``, and the points are taken again at the same places: a
steps-budget evolution run killed and resumed writes the same file as an
uninterrupted one (timing columns aside).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from amaze.curriculum.validation import validation_mazes
from amaze.evaluation.protocol import EvaluationReport, Evaluator
from amaze.maze.spec import MazeSpec
from amaze.runs.folder import ProgressLog

__all__ = [
    "EVALUATIONS_FILE",
    "EVALUATION_FIELDS",
    "EVALUATION_SEED",
    "AnytimeEvaluations",
    "EvaluationSet",
    "Spent",
]

EVALUATIONS_FILE = "evaluations.csv"
#: The columns of ``evaluations.csv``.
EVALUATION_FIELDS = (
    "point",  # 1 .. evaluation_points
    "fraction",  # the share of the budget spent when the point was taken
    "position",  # the run's progress.csv position then (generation, round, branches, steps)
    "env_steps",
    "training_seconds",  # the run's training seconds (what the seconds budget counts)
    "elapsed_seconds",  # training seconds plus every anytime evaluation's so far
    "evaluation_seconds",  # this evaluation's cost, not charged to the budget (0 for a
    # point that shares the previous row's evaluation)
    "success_rate",  # on the whole evaluation set
    "normalized_reward",
    "mean_steps",
    "family_success_rate",  # on its family mazes only (none trained on)
    "family_normalized_reward",
    "training_success_rate",  # on its training mazes only
    "training_normalized_reward",
    "evaluation_set",  # the set's digest
)
#: The seed of the evaluation set's family mazes: past every run seed's
#: validation (seed s < 2**32) and unseen (2**32 + s) streams.
EVALUATION_SEED = 2**33
#: Family mazes in the evaluation set by default.
DEFAULT_FAMILY = 24
#: Anytime evaluations of a run by default.
DEFAULT_POINTS = 20


@dataclass(frozen=True)
class Spent:
    """How far a run is: its ``progress.csv`` position, env steps and training seconds."""

    position: int
    env_steps: int
    seconds: float
    #: Generations played, for a run whose only budget counts them (evolution).
    generations: int | None = None


@dataclass(frozen=True)
class EvaluationSet:
    """The mazes every anytime evaluation plays, 4 rotations each.

    ``family``: mazes of the training family with seeds from
    :data:`EVALUATION_SEED`'s stream (:func:`~amaze.curriculum.validation.validation_mazes`:
    none of the suite's nor the paper's seeds); ``training``: the training
    mazes (a direct run's ``mazes``; the target of a curriculum or
    co-evolution). Canonical maze strings.
    """

    family: tuple[str, ...]
    training: tuple[str, ...]
    robot: str

    @classmethod
    def of(cls, training: Sequence[str], robot: str, family: int) -> EvaluationSet:
        """The set of ``family`` mazes of the first training maze's family, and ``training``."""
        canonical = tuple(MazeSpec.from_string(m).to_string() for m in training)
        drawn = validation_mazes(canonical[0], family, EVALUATION_SEED) if family else []
        return cls(tuple(drawn), canonical, robot)

    @classmethod
    def for_config(cls, config: Any) -> EvaluationSet:
        """The set of a run's config: its family maze, ``evaluation_family`` and robot.

        A curriculum's or co-evolution's target; a direct run's
        ``evaluation_maze`` if it names one, else its training mazes (the
        family of the first).
        """
        if config.regime != "direct":
            training = [config.target]
        elif config.evaluation_maze is not None:
            training = [config.evaluation_maze]
        else:
            training = config.mazes
        return cls.of(training, config.robot, config.evaluation_family)

    @cached_property
    def digest(self) -> str:
        """The first 16 hex digits of the SHA-256 of the set (mazes, rotations, robot)."""
        data = {"family": self.family, "training": self.training, "robot": self.robot}
        text = json.dumps({**data, "rotations": 4}, sort_keys=True)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]

    @cached_property
    def evaluator(self) -> Evaluator:
        """The evaluation protocol on the set (built on first use: it generates the mazes)."""
        return Evaluator(self.robot, [*self.family, *self.training], rotations=4, inputs=False)

    def scores(self, report: EvaluationReport) -> dict[str, float]:
        """The row's figures of a report on the set: whole set, family part, training part."""
        episodes = report.episodes
        family = set(self.family)

        def rates(kept: Sequence[Any]) -> tuple[float, float]:
            if not kept:
                return float("nan"), float("nan")
            return (
                float(np.mean([e.success for e in kept])),
                float(np.mean([e.normalized_reward for e in kept])),
            )

        whole = rates(episodes)
        own = rates([e for e in episodes if e.column in family])
        trained = rates([e for e in episodes if e.column not in family])
        return {
            "success_rate": whole[0],
            "normalized_reward": whole[1],
            "mean_steps": float(np.mean([e.steps for e in episodes])),
            "family_success_rate": own[0],
            "family_normalized_reward": own[1],
            "training_success_rate": trained[0],
            "training_normalized_reward": trained[1],
        }


class AnytimeEvaluations:
    """A run's anytime evaluations: when they are due, playing them, ``evaluations.csv``.

    ``config`` is the run's (its ``evaluation_points``, ``evaluation_family``
    and budgets); ``error`` its config error, for a damaged file.
    """

    def __init__(self, folder: Path, config: Any) -> None:
        self.config = config
        self.points = int(getattr(config, "evaluation_points", 0) or 0)
        self.log = ProgressLog(
            folder / EVALUATIONS_FILE, EVALUATION_FIELDS, text_fields=("evaluation_set",)
        )
        #: Points taken so far, and the seconds their evaluations cost.
        self.taken = 0
        self.cost = 0.0

    @property
    def active(self) -> bool:
        return self.points > 0

    @cached_property
    def evaluation_set(self) -> EvaluationSet:
        return EvaluationSet.for_config(self.config)

    @cached_property
    def basis(self) -> tuple[str, float]:
        """What the points divide: ``("steps" | "seconds" | "generations", the budget)``."""
        c = self.config
        for unit, budget in (
            ("steps", c.budget_steps),
            ("seconds", getattr(c, "budget_seconds", None)),
            ("generations", getattr(c, "max_generations", None)),
        ):
            if budget is not None:
                return unit, float(budget)
        raise c.error("a run needs a budget of steps, seconds or generations")

    def fraction(self, spent: Spent) -> float:
        """The share of the budget that ``spent`` is."""
        unit, budget = self.basis
        used = {"steps": spent.env_steps, "seconds": spent.seconds}.get(unit)
        if used is None:
            used = spent.generations if spent.generations is not None else spent.position
        return float(used) / budget

    # -- resume -------------------------------------------------------------------

    def check(self) -> list[dict[str, str]]:
        """The rows of ``evaluations.csv``, checked (the config's error names a bad file)."""
        if not self.active:
            return []
        rows = self.log.checked_rows("position", self.config.error)
        digest = self.evaluation_set.digest
        for row in rows:
            if row["evaluation_set"] != digest:
                raise self.config.error(
                    f"evaluations {str(self.log.path)!r} played the evaluation set"
                    f" {row['evaluation_set']!r}, not this run's {digest!r}"
                )
        return rows

    def restore(self, position: int | None, rows: Sequence[Mapping[str, str]]) -> None:
        """Keep :meth:`check`'s ``rows`` up to ``position`` (the checkpoint; ``None``: none)."""
        if not self.active:
            return
        kept = [row for row in rows if position is not None and int(row["position"]) <= position]
        self.log.keep(lambda row: position is not None and int(row["position"]) <= position)
        self.taken = int(kept[-1]["point"]) if kept else 0
        self.cost = sum(float(row["evaluation_seconds"]) for row in kept)

    # -- points -------------------------------------------------------------------

    def due(self, spent: Spent) -> list[int]:
        """The points reached by ``spent`` and not taken yet, the last one aside."""
        if not self.active:
            return []
        reached = min(int(np.floor(self.fraction(spent) * self.points + 1e-9)), self.points - 1)
        return list(range(self.taken + 1, reached + 1))

    def take(self, spent: Spent, agent: Callable[[], Any]) -> float:
        """Play ``agent()`` on the set if points are due; return the seconds it took (or 0)."""
        points = self.due(spent)
        if not points:
            return 0.0
        return self._play(points, spent, agent())

    def finish(self, spent: Spent, agent: Any) -> float:
        """The last point, the run's final ``agent``, unless a resumed run took it already."""
        if not self.active or self.taken >= self.points:
            return 0.0
        return self._play([self.points], spent, agent)

    def _play(self, points: Sequence[int], spent: Spent, agent: Any) -> float:
        started = time.perf_counter()
        scores = self.evaluation_set.scores(self.evaluation_set.evaluator.evaluate(agent))
        seconds = time.perf_counter() - started
        self.cost += seconds
        for point in points:  # the cost on the first row only: the column sums to the total
            self.log.append(self._row(point, spent, scores, seconds if point == points[0] else 0))
        self.taken = points[-1]
        return seconds

    def _row(
        self, point: int, spent: Spent, scores: Mapping[str, float], seconds: float
    ) -> dict[str, Any]:
        return {
            "point": point,
            "fraction": round(self.fraction(spent), 4),
            "position": spent.position,
            "env_steps": spent.env_steps,
            "training_seconds": round(spent.seconds, 3),
            "elapsed_seconds": round(spent.seconds + self.cost, 3),
            "evaluation_seconds": round(seconds, 4),
            **scores,
            "evaluation_set": self.evaluation_set.digest,
        }

    def figures(self) -> dict[str, Any]:
        """The summary's ``anytime`` entry: points taken, their cost, the set's digest."""
        if not self.active:
            return {"points": 0}
        return {
            "points": self.taken,
            "seconds": round(self.cost, 3),
            "evaluation_set": self.evaluation_set.digest,
            "family_mazes": len(self.evaluation_set.family),
            "training_mazes": list(self.evaluation_set.training),
        }
