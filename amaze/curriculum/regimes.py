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
  (:mod:`amaze.curriculum.edens`), the short form of ``edhucat --curator edens``,
  with EDEnS's own defaults: open-ended stages and a rehearsal of the
  lineage's earlier mazes (:mod:`amaze.runs.curriculum`);
* **coevolution**: no stages: a population of mazes co-evolves with the
  agents (:mod:`amaze.curriculum.maze_population`), leading to the target's
  family; one loop for every trainer (``amaze.runs.coevolution``), each
  trainer giving its batch step (a generation, an RL rollout);
* **edens-populations**: EDEnS over co-evolved maze populations
  (:mod:`amaze.curriculum.population_selector`): every epoch, alternatives
  of the co-evolution loop's whole state, each with a mutated controller of
  its maze population, play one epoch; one is kept from a Pareto front.

:func:`branch_allowance` shares a curriculum's budget between its stages and
branches, and :func:`curriculum_over` says when it is spent.

**Open-ended curricula** (``stages`` = :data:`OPEN_STAGES`, EDEnS's 1+λ
loop): stages follow one another until the budget is spent, each branch
allowed an *epoch* of ``budget / (K * epochs)`` (or what is left, if less;
``epochs`` defaults to :data:`OPEN_EPOCHS`). A stage whose branches
converged early spends less than its epochs, so the run plays more stages,
never fewer steps: the budget is spent on training, not left over. At
most :data:`MAX_OPEN_STAGES` stages.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = [
    "COEVOLUTION_REGIMES",
    "CURRICULUM_REGIMES",
    "MAX_OPEN_STAGES",
    "OPEN_EPOCHS",
    "OPEN_STAGES",
    "REGIMES",
    "branch_allowance",
    "branch_seconds",
    "curriculum_over",
]

REGIMES = ("direct", "interpolation", "edhucat", "edens", "coevolution", "edens-populations")
#: The regimes played by the curriculum loop (stages of branches chosen by a curator).
CURRICULUM_REGIMES = ("interpolation", "edhucat", "edens")
#: The regimes played by the co-evolution loop (a maze population beside the learner).
COEVOLUTION_REGIMES = ("coevolution", "edens-populations")
#: ``stages`` of an open-ended curriculum: stages until the budget is spent.
OPEN_STAGES = 0
#: The default ``epochs`` of an open-ended curriculum: an epoch is ``budget / (K * epochs)``.
OPEN_EPOCHS = 100
#: Most stages of an open-ended curriculum (its pictures and decision file stay readable).
MAX_OPEN_STAGES = 400
#: An open-ended curriculum ends once less than this share of its budget is left.
OPEN_REMAINDER = 0.01


def _check_stage(stage: int, stages: int) -> None:
    """``stage`` is one a curriculum of ``stages`` stages (or an open-ended one) may play."""
    last = MAX_OPEN_STAGES if stages == OPEN_STAGES else stages
    if not 0 <= stage < last:
        raise ValueError(f"stage {stage} is not one of {last} stages")


def _stage_shares(stage: int, stages: int, branches: int) -> int:
    """Into how many shares what is left is cut: each branch of the stage gets one."""
    if stages == OPEN_STAGES:
        return branches
    return branches * (stages - stage)


def branch_allowance(
    budget: int, used: int, stage: int, stages: int, branches: int, epochs: int | None = None
) -> int:
    """Env steps each branch of ``stage`` may spend: the paper's split, with hand-on.

    The paper gives every agent of every stage at most ``budget / (K * S)``
    steps (3 M steps, K = 3, S = 10: 100 k). Here each branch of a stage gets
    an equal share of what is left, ``(budget - used) // (K * stages_left)``:
    the paper's figure when every earlier branch spent its share, more when
    earlier stages converged early or had fewer branches (the first stage
    trains one agent), since their unused steps are handed on to the stages
    still to come. Branches of one stage always get the same allowance (they
    compete with each other), and the last stage shares all that is left.
    An open-ended curriculum (``stages`` = :data:`OPEN_STAGES`) gives each
    branch an epoch, ``budget // (branches * epochs)`` (``None``:
    :data:`OPEN_EPOCHS`), or its share of what is left when that is less.
    """
    _check_stage(stage, stages)
    share = max(budget - used, 0) // _stage_shares(stage, stages, branches)
    if stages == OPEN_STAGES and stage < MAX_OPEN_STAGES - 1:
        return min(budget // (branches * (epochs or OPEN_EPOCHS)), share)
    return share


def branch_seconds(
    budget: float,
    spent: float,
    stage: int,
    stages: int,
    branches: int,
    epochs: int | None = None,
) -> float:
    """Seconds each branch of ``stage`` may train: :func:`branch_allowance` for time.

    ``spent`` is what the finished branches took (training, evaluation and
    pictures), so the loop's own time is paid from the budget too.
    """
    _check_stage(stage, stages)
    share = max(budget - spent, 0.0) / _stage_shares(stage, stages, branches)
    if stages == OPEN_STAGES and stage < MAX_OPEN_STAGES - 1:
        return min(budget / (branches * (epochs or OPEN_EPOCHS)), share)
    return share


def curriculum_over(
    stage: int,
    stages: int,
    spent: Sequence[tuple[float | None, float]] = (),
) -> bool:
    """True when the curriculum plays no ``stage`` (its final choice is made before it).

    A curriculum of ``stages`` stages plays stages 0 to ``stages - 1``. An
    open-ended one (:data:`OPEN_STAGES`) always plays stage 0 and goes on
    while every budget of ``spent`` (``(budget, used)`` pairs, steps and/or
    seconds; ``None`` budgets are ignored) has at least
    :data:`OPEN_REMAINDER` of itself left, up to :data:`MAX_OPEN_STAGES`.
    """
    if stages != OPEN_STAGES:
        return stage >= stages
    if stage == 0:
        return False
    if stage >= MAX_OPEN_STAGES:
        return True
    return any(
        budget is not None and budget - used < OPEN_REMAINDER * budget for budget, used in spent
    )
