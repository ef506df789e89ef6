"""The paper's training regimes, and how a curriculum's budget is shared, for any trainer.

* **direct** (paper §4): the agent trains on
  :data:`~amaze.evaluation.suite.PAPER_TRAINING_MAZE` in its 4 rotations and is
  evaluated on :data:`~amaze.evaluation.suite.PAPER_EVALUATION_MAZE`'s 4 rotations
  (each trainer's own run plays it);
* **interpolation** (paper §4): the 10 stages of
  :func:`~amaze.curriculum.interpolation.curriculum` from a trivial 5x5 maze to
  the training maze, each trained and evaluated on its own 4 rotations; run
  by the curriculum loop (:mod:`amaze.runs.curriculum`) with the
  ``interpolation`` curator and one branch per stage;
* **edhucat** (paper, Algorithm 1): the curriculum loop with K branches per
  stage and a curator (:mod:`amaze.curriculum.curators`) that selects the
  agent that goes on and generates the next mazes;
* **edens**: the same loop with the automated EDEnS-style curator
  (:mod:`amaze.curriculum.edens`), the short form of ``edhucat --curator edens``;
* **coevolution**: no stages: a population of mazes co-evolves with the
  agents (:mod:`amaze.curriculum.coevolution`), leading to the target's
  family; evolution only (``evolution.coevolution``).

:func:`branch_allowance` shares a curriculum's budget between its stages and
branches.
"""

from __future__ import annotations

__all__ = ["CURRICULUM_REGIMES", "REGIMES", "branch_allowance", "branch_seconds"]

REGIMES = ("direct", "interpolation", "edhucat", "edens", "coevolution")
#: The regimes played by the curriculum loop (stages of branches chosen by a curator).
CURRICULUM_REGIMES = ("interpolation", "edhucat", "edens")


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


def branch_seconds(budget: float, spent: float, stage: int, stages: int, branches: int) -> float:
    """Seconds each branch of ``stage`` may train: :func:`branch_allowance` for time.

    ``spent`` is what the finished branches took (training, evaluation and
    pictures), so the loop's own time is paid from the budget too.
    """
    stages_left = stages - stage
    if stages_left < 1:
        raise ValueError(f"stage {stage} is not one of {stages} stages")
    return max(budget - spent, 0.0) / (branches * stages_left)
