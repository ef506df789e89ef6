"""An EDEnS-style automated curator: alternatives, no outside feedback, a Pareto pick.

EDEnS (Environment-Driven Evolutionary Selection; Godin-Dubois, Cussat-Blanc
and Duthen, IEEE SSCI 2020), which the paper says EDHuCAT is loosely inspired
by, copies the current state into m alternatives: the first keeps the
current environment unchanged (insurance against collapse), the others get a
mutated one; each runs one epoch; one alternative is then kept by a Pareto
front over several criteria, with a seeded random pick from the front, and
alternatives that went extinct are rejected.

Here the alternatives are the branches of the curriculum loop:

* **generate** (``k`` mazes): branch 0 keeps the parent's maze, the very
  same string; every other branch gets the parent's maze mutated by the maze
  genome (:class:`~amaze.curriculum.genome.MazeGenome`, sides up to
  ``max_size``, signs added as the target has them), by 1 to ``mutations``
  operators drawn at random (never the same maze as the parent: a mutant
  equal to it is drawn again, a few times). By default the mutations are
  *directed*, as MCC's grow its mazes: each step is drawn among the
  operators that bring the maze closer to the target
  (:func:`~amaze.curriculum.distance.maze_distance` falls: a larger side up to
  the target's, the target's signs and probabilities, intersections) and the
  neutral ones (:data:`NEUTRAL_OPERATORS`: other walls, another start
  corner); when the target has clues, a maze that gets intersections gets
  the target's clue with them (without, a lineage measured at 300 s, seed 2,
  was selected on mazes with traps and no clues, learnt to ignore clues and
  never solved a validation maze). Undirected, every operator may apply and
  mazes drift both ways: measured at 60 s (CMA-ES, seed 7), they stayed at
  5x5 to 6x6 over 45 stages, far from a 20x20 target. Once a maze has the target's fields, its
  mutants are the target's family with new walls or corners, and with the
  loop's rehearsal the lineage trains on a batch of them;
* **select**: candidates that reached the goal in none of their own maze's
  rotations are *extinct* and rejected (unless all are); the others are
  compared on three criteria, all maximised:

  1. success rate on the validation mazes,
  2. mean R̄ on the validation mazes,
  3. difficulty reached: :func:`~amaze.curriculum.difficulty.difficulty` of its
     own maze times its success rate there;

  the Pareto front (the candidates no other one beats on every criterion)
  is kept and one of its members drawn at random, from the stage's own
  stream (:meth:`~amaze.curriculum.curators.CuratorContext.rng`).

**Validation mazes** (:attr:`EdensCurator.validation`): ``validation``
(default 8) mazes of the target's family, with seeds disjoint from the
evaluation suite's (:func:`~amaze.curriculum.validation.validation_mazes`);
the loop plays every candidate on their 4 rotations. They judge
generalisation to the family without ever looking at the suite.

Options (``curator_options``): ``validation`` (number of mazes, 1..64),
``mutations`` (most operators per mutant, 1..8, default 4), ``max_size``
(largest side of a mutant, default the target's larger side) and
``directed`` (default true).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np

from amaze.curriculum.advice import changed_fields
from amaze.curriculum.curators import (
    Candidate,
    CuratorContext,
    CuratorError,
    History,
    refuse_unknown_options,
)
from amaze.curriculum.difficulty import difficulty
from amaze.curriculum.distance import maze_distance
from amaze.curriculum.genome import MazeGenome, SignSet
from amaze.curriculum.validation import validation_mazes
from amaze.maze.spec import MAX_SIZE, MIN_SIZE, MazeSpec
from amaze.validation import check_integer

__all__ = ["CRITERIA", "NEUTRAL_OPERATORS", "EdensCurator", "pareto_front"]

#: Draws of a mutant before settling for one equal to its parent.
_REDRAWS = 8
#: Operators a directed mutation may always draw: they change the walls, not the family.
NEUTRAL_OPERATORS = ("seed", "start")
#: The selection criteria, all maximised (see the module docstring).
CRITERIA = ("validation_success_rate", "validation_normalized_reward", "difficulty_reached")


_Item = TypeVar("_Item")


def pareto_front(
    candidates: Sequence[_Item], criteria: Callable[[_Item], tuple[float, ...]]
) -> list[_Item]:
    """The candidates that no other one matches or beats on every criterion and beats on one.

    Criteria are maximised; candidates with equal criteria are all kept. The
    front keeps the candidates' order.
    """
    scores = [criteria(c) for c in candidates]

    def dominated(mine: tuple[float, ...]) -> bool:
        return any(
            all(o >= m for o, m in zip(other, mine, strict=True)) and other != mine
            for other in scores
        )

    return [c for c, score in zip(candidates, scores, strict=True) if not dominated(score)]


class EdensCurator:
    """EDEnS-style selection of branches (see the module docstring)."""

    name = "edens"
    options = ("validation", "mutations", "max_size", "directed")
    #: It may be advised (:mod:`amaze.curriculum.advice`); it decides by its own rules.
    takes_advice = True

    def __init__(self, context: CuratorContext) -> None:
        self.context = context
        options = dict(context.options)
        refuse_unknown_options(context, self.name, self.options)
        target = MazeSpec.from_string(context.target)
        count = check_integer(
            "edens validation", options.get("validation", 8), minimum=1, maximum=64,
            error=CuratorError,
        )  # fmt: skip
        self.mutations = check_integer(
            "edens mutations", options.get("mutations", 4), minimum=1, maximum=8,
            error=CuratorError,
        )  # fmt: skip
        max_size = check_integer(
            "edens max_size", options.get("max_size", max(target.width, target.height)),
            minimum=MIN_SIZE, maximum=MAX_SIZE, error=CuratorError,
        )  # fmt: skip
        self.directed = options.get("directed", True)
        if not isinstance(self.directed, bool):
            raise CuratorError(f"edens directed {self.directed!r} is not true or false")
        self.target = target
        self.genome = MazeGenome(max_size=max_size, signs=SignSet.of(target))
        seed = int(context.rng(0, "validation").integers(2**31))
        #: The validation mazes the loop plays every candidate on.
        self.validation = validation_mazes(target, count, seed)

    @staticmethod
    def criteria(candidate: Candidate) -> tuple[float, float, float]:
        """Validation success, validation R̄, difficulty reached (all maximised)."""
        reached = difficulty(candidate.mazes[0]) * candidate.success_rate
        return (
            candidate.validation_success_rate,
            candidate.validation_normalized_reward,
            reached,
        )

    def select(self, candidates: Sequence[Candidate], advice: Any = None) -> Candidate:
        """The seeded pick from the Pareto front (``advice``, a proposal, is not read)."""
        return self.explain_select(candidates)[0]

    def explain_select(
        self, candidates: Sequence[Candidate]
    ) -> tuple[Candidate, list[Candidate], list[dict[str, Any]]]:
        """The pick, the Pareto front it was drawn from, and every candidate's criteria.

        As an advisor, this is its account (:mod:`amaze.curriculum.advice`):
        each candidate's :data:`CRITERIA` values, and ``extinct`` when it was
        rejected for reaching no goal on its own maze.
        """
        alive = [c for c in candidates if c.success_rate > 0] or list(candidates)
        front = pareto_front(alive, self.criteria)
        rng = self.context.rng(candidates[0].stage + 1, "select")
        chosen = front[int(rng.integers(len(front)))]
        living = {id(c) for c in alive}
        rows = [
            {
                "branch": c.branch,
                **dict(zip(CRITERIA, self.criteria(c), strict=True)),
                "extinct": id(c) not in living,
            }
            for c in candidates
        ]
        return chosen, front, rows

    def generate(self, k: int, history: History, advice: Any = None) -> list[str]:
        """Branch 0 the parent's maze, the others mutants (``advice`` is not read)."""
        return [maze for maze, _ in self.explain_generate(k, history)]

    def explain_generate(self, k: int, history: History) -> list[tuple[str, tuple[str, ...]]]:
        """The ``k`` mazes, each with the genome operators that made it from the parent's maze.

        Branch 0's maze is the parent's (no operator). Undirected mutants name
        the fields that changed (:func:`~amaze.curriculum.advice.changed_fields`).
        """
        parent = history.parent.mazes[0]
        rng = self.context.rng(history.stage, "generate")
        made: list[tuple[str, tuple[str, ...]]] = [(parent, ())]
        for _ in range(k - 1):
            for _ in range(_REDRAWS):
                count = int(rng.integers(1, self.mutations + 1))
                mutant, operators = self.mutate_explained(parent, rng, count)
                if mutant != parent:
                    break
            made.append((mutant, operators))
        return made

    def mutate(self, maze: str, rng: np.random.Generator, count: int) -> str:
        """``maze`` after ``count`` mutation steps (directed ones unless ``directed`` is off)."""
        return self.mutate_explained(maze, rng, count)[0]

    def mutate_explained(
        self, maze: str, rng: np.random.Generator, count: int
    ) -> tuple[str, tuple[str, ...]]:
        """:meth:`mutate`, with the operators applied, in order."""
        if not self.directed:
            mutant = self.genome.mutate(maze, rng, n=count)
            return mutant.to_string(), changed_fields(maze, mutant)
        spec, operators = MazeSpec.from_string(maze), []
        for _ in range(count):
            names, spec = self._directed(spec, rng)
            operators.extend(names)
        return spec.to_string(), tuple(operators)

    def directed_step(self, spec: MazeSpec, rng: np.random.Generator) -> MazeSpec:
        """One mutation drawn among the neutral ones and those that come closer to the target.

        Every applicable operator is applied (each draws what it needs from
        ``rng``, in the genome's order), then one of the admissible mutants is
        drawn uniformly.
        """
        return self._directed(spec, rng)[1]

    def _directed(
        self, spec: MazeSpec, rng: np.random.Generator
    ) -> tuple[tuple[str, ...], MazeSpec]:
        """:meth:`directed_step` with the operators of the mutant drawn."""
        distance = maze_distance(spec, self.target)
        admissible = []
        for name in self.genome.applicable(spec):
            names, mutant = (name,), self.genome.apply(name, spec, rng)
            if self.target.clue and not mutant.unicursive and not mutant.clue:
                # Intersections come with the target's clues, as the paper's
                # mazes do: an agent shown no clue learns to ignore them.
                names, mutant = (name, "add_clue"), self.genome.apply("add_clue", mutant, rng)
            if name in NEUTRAL_OPERATORS or maze_distance(mutant, self.target) < distance:
                admissible.append((names, mutant))
        return admissible[int(rng.integers(len(admissible)))]
