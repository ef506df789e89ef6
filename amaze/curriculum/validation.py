"""Validation mazes: the target's family, never the evaluation suite.

Automated curators judge agents on mazes they did not train on. Those mazes
must not be the standard evaluation suite's (nor the paper's suite, nor the
paper's training and evaluation mazes): a curator that selected agents on the
suite would be tuned for the 18 mazes the results are reported on.
:func:`validation_mazes` draws the target's fields with fresh seeds, disjoint
from every seed of both suites and of the paper's two mazes, from a seeded
generator.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache

import numpy as np

from amaze.curriculum.genome import SEED_RANGE
from amaze.evaluation.suite import (
    PAPER_EVALUATION_MAZE,
    PAPER_TRAINING_MAZE,
    paper_suite,
    standard_suite,
)
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer

__all__ = ["UNSEEN_MAZES", "reserved_seeds", "unseen_mazes", "validation_mazes"]

#: Family mazes a run reports its final agent on (never played before the end).
UNSEEN_MAZES = 32


@lru_cache(maxsize=1)
def reserved_seeds() -> frozenset[int]:
    """The seeds a validation maze never has: both suites' and the paper's two mazes'."""
    mazes = [*standard_suite().maze_strings(rotations=False)]
    mazes += paper_suite().maze_strings(rotations=False)
    mazes += [PAPER_TRAINING_MAZE, PAPER_EVALUATION_MAZE]
    return frozenset(MazeSpec.from_string(maze).seed for maze in mazes)


def validation_mazes(target: str | MazeSpec, n: int, seed: int) -> list[str]:
    """``n`` mazes of ``target``'s family (its fields, new seeds), canonical strings.

    The seeds come from ``numpy.random.default_rng(seed)``, distinct, and
    none of :func:`reserved_seeds`; the same arguments give the same mazes.
    """
    n = check_integer("n", n, minimum=1)
    spec = target if isinstance(target, MazeSpec) else MazeSpec.from_string(target)
    rng = np.random.default_rng(check_integer("seed", seed, minimum=0))
    reserved, seeds = reserved_seeds(), []
    while len(seeds) < n:
        drawn = int(rng.integers(0, SEED_RANGE))
        if drawn not in reserved and drawn not in seeds:
            seeds.append(drawn)
    return [dataclasses.replace(spec, seed=s).to_string() for s in seeds]


def unseen_mazes(target: str | MazeSpec, seed: int, n: int = UNSEEN_MAZES) -> list[str]:
    """``n`` family mazes of ``target`` drawn apart from :func:`validation_mazes` of ``seed``.

    A run that selects on its validation mazes reports its final agent on
    these: mazes of the same family that no part of the run trained or
    selected on.
    """
    return validation_mazes(target, n, (1 << 32) + check_integer("seed", seed, minimum=0))
