"""Scripted curators: the paper's human strategies, domain randomisation and interpolation.

Each curator is a set of rules a person could follow by hand, written down
here and in ``docs/regimes/edhucat.md``, so that curricula are comparable and replayable.

**Challenges.** The paper's three human strategies (*careful*, *moderate*,
*risky*) make a maze harder *toward the target* one challenge at a time. A
challenge changes one field group of the parent's maze (the maze the selected
candidate trained on) to a value closer to the target's, never past it, and
applies only where the parent is easier than the target in that group
(:func:`challenges` lists those that apply, in this order):

==================  ===================  ==========================================
challenge           fields               change
==================  ===================  ==========================================
``size``            width, height        every side below the target's grows by
                                         ``size_step`` cells, up to the target's
``intersections``   unicursive (+ clue)  intersections on; the target's clues
                                         come with them when the parent has none
                                         (the paper's mazes have a clue at every
                                         intersection)
``clue``            clue                 the target's clue signs (the parent has
                                         intersections)
``lure``            lure, p_lure         the target's lure signs; added with the
                                         probability ``min(p, probability_step)``
``trap``            trap, p_trap         the same for traps (the parent has
                                         intersections)
``p_lure``,         p_lure or p_trap     up by ``probability_step`` (the genome's
``p_trap``                               ``p_<kind>_up``), at most the target's
``start``           start, rotated       the target's corner and rotation flag
==================  ===================  ==========================================

A sign challenge applies when the parent's signs of that kind differ from
the target's (none, or other shapes or lightness). Fields where the parent is
already as hard as the target, or harder, are left as they are. Every maze a
strategy generates gets a fresh seed (:func:`~amaze.curriculum.genome.new_seed`):
new walls, so an agent meets a family rather than one maze.

* ``careful``: challenges are integrated slowly, once the previous ones are
  solved. Generate: if the parent solved its maze (success rate on its own
  mazes >= ``threshold``, default 1: every rotation reached), branch ``b``
  gets the parent's maze with one challenge, a different one per branch where
  possible (the challenges that apply, in an order drawn from the stage's
  generator, branch ``b`` taking the ``b mod n``-th); otherwise, and once no
  challenge applies (the parent's maze is the target's family), the parent's
  maze with new seeds (consolidation). Select: the best on its own maze
  (success, then R̄; ties to the lower branch).
* ``moderate``: new challenges even if the previous ones are not solved.
  Generate: every stage, solved or not, as careful's "solved" case (one
  challenge per branch, new seeds; the parent's family once none applies).
  Select: the best on all the stage's mazes (success, then R̄), a generalist.
* ``risky``: unfair conditions, to promote resilience. Generate: each branch
  gets 2 or 3 different challenges at once (drawn one after the other among
  those that apply, as many as there are); then, with probability ``unfair``
  (default 0.3), one or two *unfair* mutations that may go past the target:
  the genome's ``size_up`` (up to ``max_size``, default 1.5 times the
  target's larger side, at most 100), ``add_lure``, ``add_trap``,
  ``p_lure_up``, ``p_trap_up`` or ``clue_lightness_down`` (fainter clues).
  Select: the best on the hardest maze of the stage (by
  :func:`~amaze.curriculum.difficulty.difficulty`; success, then R̄ on its 4
  rotations), the agent that copes best with the harshest conditions; ties
  go to the best overall, then the lower branch.
* ``interpolation``: the paper's interpolation regime as a curator. Stage
  ``s`` trains on stage ``s`` of
  :func:`~amaze.curriculum.interpolation.curriculum` (target, S stages); with
  more than one branch, branch 0 gets that maze and the others the same maze
  with new seeds. Select: the best on its own maze (success, then R̄).
* ``random``: domain randomisation. Every branch of every stage gets a maze of
  the target's family: the target's fields with a fresh seed. Select: the
  best on all the stage's mazes (success, then R̄), a generalist.

**Options** (``curator_options`` of the run config; unknown names are
refused): ``size_step`` (default: a third of the way from the 5x5 start to
the target's larger side, at least 1), ``probability_step`` (default 0.25)
for the three strategies; ``threshold`` (careful); ``unfair`` and
``max_size`` (risky).

Every draw comes from :meth:`~amaze.curriculum.curators.CuratorContext.rng`,
so a curator's decisions depend only on the run's seed and what it is shown.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from functools import lru_cache
from typing import Any, ClassVar

import numpy as np

from amaze.curriculum.curators import (
    Candidate,
    CuratorContext,
    CuratorError,
    History,
    refuse_unknown_options,
)
from amaze.curriculum.difficulty import difficulty
from amaze.curriculum.genome import SEED_RANGE, MazeGenome, SignSet, new_seed
from amaze.curriculum.interpolation import TRIVIAL_SIDE, curriculum
from amaze.maze.spec import MAX_SIZE, MIN_SIZE, MazeSpec
from amaze.validation import check_integer, check_number

__all__ = [
    "CHALLENGES",
    "UNFAIR_OPERATORS",
    "CarefulCurator",
    "InterpolationCurator",
    "ModerateCurator",
    "RandomCurator",
    "RiskyCurator",
    "best_candidate",
    "challenge",
    "challenges",
    "hardest_score",
    "overall_score",
    "own_score",
    "reseeded",
]

#: Each challenge and the fields of the maze spec it may change (see the module docstring).
CHALLENGES: Mapping[str, frozenset[str]] = {
    "size": frozenset({"width", "height"}),
    "intersections": frozenset({"unicursive", "clue"}),
    "clue": frozenset({"clue"}),
    "lure": frozenset({"lure", "p_lure"}),
    "trap": frozenset({"trap", "p_trap"}),
    "p_lure": frozenset({"p_lure"}),
    "p_trap": frozenset({"p_trap"}),
    "start": frozenset({"start", "rotated"}),
}

#: The genome's operators of risky's unfair mutations (they may go past the target).
UNFAIR_OPERATORS = (
    "size_up",
    "add_lure",
    "add_trap",
    "p_lure_up",
    "p_trap_up",
    "clue_lightness_down",
)


def best_candidate(
    candidates: Sequence[Candidate], key: Callable[[Candidate], tuple[float, ...]]
) -> Candidate:
    """The candidate with the largest ``key``; the lowest branch wins ties."""
    return max(candidates, key=lambda c: (*key(c), -c.branch))


def own_score(candidate: Candidate) -> tuple[float, float]:
    """Success, then R̄, on the candidate's own mazes."""
    return candidate.success_rate, candidate.normalized_reward


def overall_score(candidate: Candidate) -> tuple[float, float]:
    """Success, then R̄, on every maze of the stage."""
    return candidate.overall_success_rate, candidate.overall_normalized_reward


def reseeded(spec: MazeSpec, seeds: Sequence[int]) -> list[str]:
    """``spec`` with each of ``seeds`` (new walls, same fields), as canonical strings."""
    return [dataclasses.replace(spec, seed=int(seed)).to_string() for seed in seeds]


@lru_cache(maxsize=1024)
def _difficulty(maze: str) -> float:
    return difficulty(maze)


def hardest_score(candidates: Sequence[Candidate]) -> Callable[[Candidate], tuple[float, ...]]:
    """Risky's key: success and R̄ on the stage's hardest maze, then :func:`overall_score`.

    The hardest maze is the one with the largest
    :func:`~amaze.curriculum.difficulty.difficulty` among every maze the candidates
    were evaluated on (the first in branch order on ties). A candidate without
    results on it scores as its own mazes.
    """
    mazes: list[str] = []
    for candidate in sorted(candidates, key=lambda c: c.branch):
        for result in (*candidate.own, *candidate.others):
            if result.maze not in mazes:
                mazes.append(result.maze)
    hardest = max(mazes, key=_difficulty) if mazes else None

    def key(candidate: Candidate) -> tuple[float, ...]:
        on = [r for r in (*candidate.own, *candidate.others) if r.maze == hardest]
        first = (on[0].success_rate, on[0].normalized_reward_mean) if on else own_score(candidate)
        return (*first, *overall_score(candidate))

    return key


# -- challenges -------------------------------------------------------------------------


def _signs_differ(spec: MazeSpec, target: MazeSpec, kind: str) -> bool:
    return bool(getattr(target, kind)) and getattr(spec, kind) != getattr(target, kind)


def challenges(spec: MazeSpec, target: MazeSpec) -> tuple[str, ...]:
    """The challenges (:data:`CHALLENGES`) that make ``spec`` harder toward ``target``."""
    found = []
    if spec.width < target.width or spec.height < target.height:
        found.append("size")
    if spec.unicursive and not target.unicursive:
        found.append("intersections")
    for kind in ("clue", "lure", "trap"):
        acts = kind == "lure" or not spec.unicursive
        if acts and _signs_differ(spec, target, kind):
            found.append(kind)
    for kind in ("lure", "trap"):
        acts = kind == "lure" or not spec.unicursive
        mine, theirs = getattr(spec, f"p_{kind}"), getattr(target, f"p_{kind}")
        if acts and mine is not None and theirs is not None and mine < theirs:
            found.append(f"p_{kind}")
    if (spec.start, spec.rotated) != (target.start, target.rotated):
        found.append("start")
    return tuple(found)


def challenge(
    name: str,
    spec: MazeSpec,
    target: MazeSpec,
    rng: np.random.Generator,
    *,
    size_step: int,
    genome: MazeGenome,
) -> MazeSpec:
    """``spec`` with the challenge ``name`` toward ``target`` (``spec`` if it does not apply).

    ``genome.probability_step`` is the probability step (and the first
    probability of an added lure or trap); the seed is left as it is.
    """
    if name not in challenges(spec, target):
        return spec
    if name == "size":
        return spec.where(
            width=min(spec.width + size_step, max(spec.width, target.width)),
            height=min(spec.height + size_step, max(spec.height, target.height)),
        )
    if name == "intersections":
        clue = spec.clue or target.clue
        return spec.where(unicursive=False, clue=clue)
    if name in ("clue", "lure", "trap"):
        changes: dict[str, Any] = {name: getattr(target, name)}
        if name != "clue" and not getattr(spec, name):
            step = genome.probability_step
            changes[f"p_{name}"] = min(getattr(target, f"p_{name}"), step)
        return spec.where(**changes)
    if name in ("p_lure", "p_trap"):
        raised = genome.apply(f"{name}_up", spec, rng)
        return raised.where(**{name: min(getattr(raised, name), getattr(target, name))})
    return spec.where(start=target.start, rotated=target.rotated)


# -- the strategies ----------------------------------------------------------------------


class _Strategy:
    """What careful, moderate and risky share: options, challenges, fresh seeds."""

    name: ClassVar[str]
    #: It may be advised (:mod:`amaze.curriculum.advice`); it decides by its own rules.
    takes_advice: ClassVar[bool] = True
    #: The options this curator reads from ``context.options`` (with the shared ones).
    own_options: ClassVar[tuple[str, ...]] = ()

    def __init__(self, context: CuratorContext) -> None:
        self.context = context
        self.target = MazeSpec.from_string(context.target)
        options = dict(context.options)
        known = ("size_step", "probability_step", *self.own_options)
        refuse_unknown_options(context, self.name, known)
        side = max(self.target.width, self.target.height)
        default_step = max(1, math.ceil((side - TRIVIAL_SIDE) / 3))
        self.size_step = check_integer(
            f"{self.name} size_step",
            options.pop("size_step", default_step),
            minimum=1,
            maximum=MAX_SIZE,
            error=CuratorError,
        )
        probability_step = options.pop("probability_step", 0.25)
        self.genome = MazeGenome(
            min_size=MIN_SIZE,
            probability_step=check_number(
                f"{self.name} probability_step",
                probability_step,
                minimum=0.001,
                maximum=1,
                error=CuratorError,
            ),
            signs=SignSet.of(self.target),
        )
        self.options = options

    def parent_spec(self, history: History) -> MazeSpec:
        """The maze the parent trained on (its first, when it had several)."""
        return MazeSpec.from_string(history.parent.mazes[0])

    def challenges(self, spec: MazeSpec) -> tuple[str, ...]:
        return challenges(spec, self.target)

    def challenge(self, name: str, spec: MazeSpec, rng: np.random.Generator) -> MazeSpec:
        return challenge(name, spec, self.target, rng, size_step=self.size_step, genome=self.genome)

    def one_challenge_each(self, k: int, spec: MazeSpec, rng: np.random.Generator) -> list[str]:
        """Branch ``b``: one challenge (a different one per branch where possible), a new seed."""
        names = list(self.challenges(spec))
        if not names:
            return self.consolidate(k, spec, rng)
        order = [names[i] for i in rng.permutation(len(names))]
        return [
            new_seed(self.challenge(order[b % len(order)], spec, rng), rng).to_string()
            for b in range(k)
        ]

    @staticmethod
    def consolidate(k: int, spec: MazeSpec, rng: np.random.Generator) -> list[str]:
        """The same fields, ``k`` new seeds."""
        return [new_seed(spec, rng).to_string() for _ in range(k)]


class CarefulCurator(_Strategy):
    """Careful: one challenge once the previous ones are solved (see the module docstring)."""

    name = "careful"
    own_options = ("threshold",)

    def __init__(self, context: CuratorContext) -> None:
        super().__init__(context)
        self.threshold = check_number(
            "careful threshold",
            self.options.pop("threshold", 1.0),
            minimum=0,
            maximum=1,
            error=CuratorError,
        )

    def select(self, candidates: Sequence[Candidate], advice: Any = None) -> Candidate:
        return best_candidate(candidates, own_score)

    def generate(self, k: int, history: History, advice: Any = None) -> list[str]:
        rng = self.context.rng(history.stage, "generate")
        spec = self.parent_spec(history)
        if history.parent.success_rate >= self.threshold:
            return self.one_challenge_each(k, spec, rng)
        return self.consolidate(k, spec, rng)


class ModerateCurator(_Strategy):
    """Moderate: one challenge every stage, solved or not (see the module docstring)."""

    name = "moderate"

    def select(self, candidates: Sequence[Candidate], advice: Any = None) -> Candidate:
        return best_candidate(candidates, overall_score)

    def generate(self, k: int, history: History, advice: Any = None) -> list[str]:
        rng = self.context.rng(history.stage, "generate")
        return self.one_challenge_each(k, self.parent_spec(history), rng)


class RiskyCurator(_Strategy):
    """Risky: several challenges at once, sometimes unfair ones (see the module docstring)."""

    name = "risky"
    own_options = ("unfair", "max_size")

    def __init__(self, context: CuratorContext) -> None:
        super().__init__(context)
        self.unfair = check_number(
            "risky unfair", self.options.pop("unfair", 0.3), minimum=0, maximum=1,
            error=CuratorError,
        )  # fmt: skip
        side = max(self.target.width, self.target.height)
        self.max_size = check_integer(
            "risky max_size",
            self.options.pop("max_size", min(MAX_SIZE, math.ceil(1.5 * side))),
            minimum=MIN_SIZE,
            maximum=MAX_SIZE,
            error=CuratorError,
        )
        self.genome = dataclasses.replace(
            self.genome, max_size=self.max_size, size_step=self.size_step
        )

    def select(self, candidates: Sequence[Candidate], advice: Any = None) -> Candidate:
        return best_candidate(candidates, hardest_score(candidates))

    def generate(self, k: int, history: History, advice: Any = None) -> list[str]:
        rng = self.context.rng(history.stage, "generate")
        parent = self.parent_spec(history)
        mazes = []
        for _ in range(k):
            spec, taken = parent, set()
            for _ in range(int(rng.integers(2, 4))):
                names = [name for name in self.challenges(spec) if name not in taken]
                if not names:
                    break
                taken.add(name := names[int(rng.integers(len(names)))])
                spec = self.challenge(name, spec, rng)
            if rng.random() < self.unfair:
                n = int(rng.integers(1, 3))
                spec = self.genome.mutate(spec, rng, UNFAIR_OPERATORS, n=n)
            mazes.append(new_seed(spec, rng).to_string())
        return mazes


class InterpolationCurator:
    """The interpolation regime as a curator (see the module docstring)."""

    name = "interpolation"
    takes_advice = True

    def __init__(self, context: CuratorContext) -> None:
        refuse_unknown_options(context, self.name)
        self.context = context
        self.plan = curriculum(context.target, max(context.stages, 2))

    def select(self, candidates: Sequence[Candidate], advice: Any = None) -> Candidate:
        return best_candidate(candidates, own_score)

    def generate(self, k: int, history: History, advice: Any = None) -> list[str]:
        spec = self.plan[min(history.stage, len(self.plan) - 1)]
        seeds = self.context.rng(history.stage, "generate").integers(0, SEED_RANGE, k - 1)
        return [spec.to_string(), *reseeded(spec, seeds)]


class RandomCurator:
    """Domain randomisation: the target's family with fresh seeds (see the module docstring)."""

    name = "random"
    takes_advice = True

    def __init__(self, context: CuratorContext) -> None:
        refuse_unknown_options(context, self.name)
        self.context = context
        self.target = MazeSpec.from_string(context.target)

    def select(self, candidates: Sequence[Candidate], advice: Any = None) -> Candidate:
        return best_candidate(candidates, overall_score)

    def generate(self, k: int, history: History, advice: Any = None) -> list[str]:
        seeds = self.context.rng(history.stage, "generate").integers(0, SEED_RANGE, k)
        return reseeded(self.target, seeds)
