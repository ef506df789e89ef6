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

import numpy as np

from amaze.curriculum.curators import Candidate, CuratorContext, CuratorError, History
from amaze.curriculum.difficulty import difficulty
from amaze.curriculum.distance import maze_distance
from amaze.curriculum.genome import MazeGenome, SignSet
from amaze.curriculum.validation import validation_mazes
from amaze.maze.spec import MAX_SIZE, MIN_SIZE, MazeSpec
from amaze.validation import check_integer

__all__ = ["NEUTRAL_OPERATORS", "EdensCurator", "pareto_front"]

#: Draws of a mutant before settling for one equal to its parent.
_REDRAWS = 8
#: Operators a directed mutation may always draw: they change the walls, not the family.
NEUTRAL_OPERATORS = ("seed", "start")


def pareto_front(
    candidates: Sequence[Candidate], criteria: Callable[[Candidate], tuple[float, ...]]
) -> list[Candidate]:
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

    def __init__(self, context: CuratorContext) -> None:
        self.context = context
        options = dict(context.options)
        unknown = sorted(set(options) - set(self.options))
        if unknown:
            raise CuratorError(
                f"curator 'edens': unknown option(s) {', '.join(unknown)}"
                f" (known: {', '.join(self.options)})"
            )
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

    def select(self, candidates: Sequence[Candidate]) -> Candidate:
        alive = [c for c in candidates if c.success_rate > 0] or list(candidates)
        front = pareto_front(alive, self.criteria)
        rng = self.context.rng(candidates[0].stage + 1, "select")
        return front[int(rng.integers(len(front)))]

    def generate(self, k: int, history: History) -> list[str]:
        parent = history.parent.mazes[0]
        rng = self.context.rng(history.stage, "generate")
        mazes = [parent]
        for _ in range(k - 1):
            for _ in range(_REDRAWS):
                count = int(rng.integers(1, self.mutations + 1))
                mutant = self.mutate(parent, rng, count)
                if mutant != parent:
                    break
            mazes.append(mutant)
        return mazes

    def mutate(self, maze: str, rng: np.random.Generator, count: int) -> str:
        """``maze`` after ``count`` mutation steps (directed ones unless ``directed`` is off)."""
        if not self.directed:
            return self.genome.mutate(maze, rng, n=count).to_string()
        spec = MazeSpec.from_string(maze)
        for _ in range(count):
            spec = self.directed_step(spec, rng)
        return spec.to_string()

    def directed_step(self, spec: MazeSpec, rng: np.random.Generator) -> MazeSpec:
        """One mutation drawn among the neutral ones and those that come closer to the target.

        Every applicable operator is applied (each draws what it needs from
        ``rng``, in the genome's order), then one of the admissible mutants is
        drawn uniformly.
        """
        distance = maze_distance(spec, self.target)
        admissible = []
        for name in self.genome.applicable(spec):
            mutant = self.genome.apply(name, spec, rng)
            if self.target.clue and not mutant.unicursive and not mutant.clue:
                # Intersections come with the target's clues, as the paper's
                # mazes do: an agent shown no clue learns to ignore them.
                mutant = self.genome.apply("add_clue", mutant, rng)
            if name in NEUTRAL_OPERATORS or maze_distance(mutant, self.target) < distance:
                admissible.append(mutant)
        return admissible[int(rng.integers(len(admissible)))]
