"""Scripted curators: the paper's human strategies, domain randomisation and interpolation.

Each curator is a set of rules a person could follow by hand, written down
here and in the README, so that curricula are comparable and replayable:

* ``interpolation``: the paper's interpolation regime as a curator. Stage
  ``s`` trains on stage ``s`` of
  :func:`~amaze.curriculum.interpolation.curriculum` (target, S stages); with
  more than one branch, branch 0 gets that maze and the others the same maze
  with new seeds. Select: the best on its own maze (success, then R̄).
* ``random``: domain randomisation. Every branch of every stage gets a maze of
  the target's family: the target's fields with a fresh seed. Select: the
  best on all the stage's mazes (success, then R̄), a generalist.

Every draw comes from :meth:`~amaze.curriculum.curators.CuratorContext.rng`,
so a curator's decisions depend only on the run's seed and what it is shown.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

from amaze.curriculum.curators import Candidate, CuratorContext, History
from amaze.curriculum.genome import SEED_RANGE
from amaze.curriculum.interpolation import curriculum
from amaze.maze.spec import MazeSpec

__all__ = ["InterpolationCurator", "RandomCurator", "best_candidate"]


def best_candidate(
    candidates: Sequence[Candidate], key: Callable[[Candidate], tuple[float, ...]]
) -> Candidate:
    """The candidate with the largest ``key``; the lowest branch wins ties."""
    return max(candidates, key=lambda c: (*key(c), -c.branch))


def own_score(candidate: Candidate) -> tuple[float, float]:
    """Success, then R̄, on the candidate's own mazes."""
    return candidate.success_rate, candidate.mean_reward


def overall_score(candidate: Candidate) -> tuple[float, float]:
    """Success, then R̄, on every maze of the stage."""
    return candidate.overall_success_rate, candidate.overall_mean_reward


def reseeded(spec: MazeSpec, seeds: Sequence[int]) -> list[str]:
    """``spec`` with each of ``seeds`` (new walls, same fields), as canonical strings."""
    return [dataclasses.replace(spec, seed=int(seed)).to_string() for seed in seeds]


class InterpolationCurator:
    """The interpolation regime as a curator (see the module docstring)."""

    name = "interpolation"

    def __init__(self, context: CuratorContext) -> None:
        self.context = context
        self.plan = curriculum(context.target, max(context.stages, 2))

    def select(self, candidates: Sequence[Candidate]) -> Candidate:
        return best_candidate(candidates, own_score)

    def generate(self, k: int, history: History) -> list[str]:
        spec = self.plan[min(history.stage, len(self.plan) - 1)]
        seeds = self.context.rng(history.stage, "generate").integers(0, SEED_RANGE, k - 1)
        return [spec.to_string(), *reseeded(spec, seeds)]


class RandomCurator:
    """Domain randomisation: the target's family with fresh seeds (see the module docstring)."""

    name = "random"

    def __init__(self, context: CuratorContext) -> None:
        self.context = context
        self.target = MazeSpec.from_string(context.target)

    def select(self, candidates: Sequence[Candidate]) -> Candidate:
        return best_candidate(candidates, overall_score)

    def generate(self, k: int, history: History) -> list[str]:
        seeds = self.context.rng(history.stage, "generate").integers(0, SEED_RANGE, k)
        return reseeded(self.target, seeds)
