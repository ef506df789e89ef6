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
  genome (:class:`~amaze.curriculum.genome.MazeGenome`, every operator,
  sides up to ``max_size``), by 1 to ``mutations`` operators drawn at random
  (never the same maze as the parent: a mutant equal to it is drawn again,
  a few times);
* **select**: candidates that reached the goal in none of their own maze's
  rotations are *extinct* and rejected (unless all are); the others are
  compared on three criteria, all maximised:

  1. success rate on the validation mazes,
  2. mean R̄ on the validation mazes,
  3. difficulty reached: :func:`~amaze.curriculum.genome.difficulty` of its
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
``mutations`` (most operators per mutant, 1..8, default 2) and ``max_size``
(largest side of a mutant, default the target's larger side).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from amaze.curriculum.curators import Candidate, CuratorContext, CuratorError, History
from amaze.curriculum.genome import MazeGenome, difficulty
from amaze.curriculum.validation import validation_mazes
from amaze.maze.spec import MAX_SIZE, MIN_SIZE, MazeSpec
from amaze.validation import check_integer

__all__ = ["EdensCurator", "pareto_front"]

#: Draws of a mutant before settling for one equal to its parent.
_REDRAWS = 8


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
    options = ("validation", "mutations", "max_size")

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
            "edens mutations", options.get("mutations", 2), minimum=1, maximum=8,
            error=CuratorError,
        )  # fmt: skip
        max_size = check_integer(
            "edens max_size", options.get("max_size", max(target.width, target.height)),
            minimum=MIN_SIZE, maximum=MAX_SIZE, error=CuratorError,
        )  # fmt: skip
        self.genome = MazeGenome(max_size=max_size)
        seed = int(context.rng(0, "validation").integers(2**31))
        #: The validation mazes the loop plays every candidate on.
        self.validation = validation_mazes(target, count, seed)

    @staticmethod
    def criteria(candidate: Candidate) -> tuple[float, float, float]:
        """Validation success, validation R̄, difficulty reached (all maximised)."""
        reached = difficulty(candidate.mazes[0]) * candidate.success_rate
        return (
            candidate.validation_success_rate,
            candidate.validation_mean_reward,
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
                mutant = self.genome.mutate(parent, rng, n=count).to_string()
                if mutant != parent:
                    break
            mazes.append(mutant)
        return mazes
