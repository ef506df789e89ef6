"""The paper's training regimes as lists of stages, for any trainer.

A regime says which mazes an agent trains on, stage after stage, and which
mazes it is evaluated on meanwhile; how a budget is shared between stages is
:func:`stage_end`. Trainers (``rl_baselines.train``; evolution next) play the
stages; curators of later regimes produce stages the same way.

* **direct** (paper §4): one stage, the training maze
  :data:`~amaze.evaluation.suite.PAPER_TRAINING_MAZE` in its 4 rotations,
  evaluated on :data:`~amaze.evaluation.suite.PAPER_EVALUATION_MAZE`'s 4 rotations;
* **interpolation** (paper §4): the 10 stages of
  :func:`~amaze.curriculum.interpolation.curriculum` from a trivial 5x5 maze to
  the training maze, each trained and evaluated on its own 4 rotations; run
  by the curriculum loop (:mod:`amaze.runs.curriculum`) with the
  ``interpolation`` curator and one branch per stage;
* **edhucat** (paper, Algorithm 1): the curriculum loop with K branches per
  stage and a curator (:mod:`amaze.curriculum.curators`) that selects the
  agent that goes on and generates the next mazes.

:func:`branch_allowance` shares a curriculum's budget between its stages and
branches.
"""

from __future__ import annotations

from dataclasses import dataclass

from amaze.curriculum.interpolation import curriculum
from amaze.errors import AmazeError
from amaze.evaluation.suite import PAPER_EVALUATION_MAZE, PAPER_TRAINING_MAZE
from amaze.maze import rotations

__all__ = [
    "CURRICULUM_REGIMES",
    "REGIMES",
    "Stage",
    "branch_allowance",
    "regime_stages",
    "stage_end",
]

REGIMES = ("direct", "interpolation", "edhucat")
#: The regimes played by the curriculum loop (stages of branches chosen by a curator).
CURRICULUM_REGIMES = ("interpolation", "edhucat")


@dataclass(frozen=True)
class Stage:
    """One stage of a regime: canonical maze strings, rotations included."""

    training: tuple[str, ...]
    evaluation: tuple[str, ...]


def regime_stages(regime: str) -> list[Stage]:
    """The stages of ``regime`` (see the module docstring)."""
    if regime == "direct":
        return [
            Stage(tuple(rotations(PAPER_TRAINING_MAZE)), tuple(rotations(PAPER_EVALUATION_MAZE)))
        ]
    if regime == "interpolation":
        stages = [tuple(rotations(spec)) for spec in curriculum(PAPER_TRAINING_MAZE)]
        return [Stage(mazes, mazes) for mazes in stages]
    raise AmazeError(f"unknown regime {regime!r} (choose from {', '.join(REGIMES)})")


def stage_end(budget: int, used: int, stages_left: int) -> int:
    """Where the current stage stops: an equal share of what is left (all of it at the end).

    Steps that earlier stages did not use (they converged early) are shared among
    the stages still to come.
    """
    if stages_left <= 1:
        return budget
    return used + max(budget - used, 0) // stages_left


def branch_allowance(budget: int, used: int, stage: int, stages: int, branches: int) -> int:
    """Env steps each branch of ``stage`` may spend: the paper's split, with hand-on.

    The paper gives every agent of every stage at most ``budget / (K * S)``
    steps (3 M steps, K = 3, S = 10: 100 k). Here each branch of a stage gets
    an equal share of what is left, ``(budget - used) // (K * stages_left)``:
    the paper's figure when every earlier branch spent its share, more when
    earlier stages converged early or had fewer branches (the first stage
    trains one agent), since their unused steps are handed on to the stages
    still to come. Branches of one stage always get the same allowance (they
    compete with each other), and the last stage shares all that is left.
    """
    stages_left = stages - stage
    if stages_left < 1:
        raise ValueError(f"stage {stage} is not one of {stages} stages")
    return max(budget - used, 0) // (branches * stages_left)
