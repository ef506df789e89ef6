"""The learner protocol: what a curriculum needs from a trainer, whatever the trainer.

A curriculum (the EDHuCAT loop of :mod:`amaze.runs.curriculum`) never looks
inside an agent: it asks a :class:`Learner` to train on mazes for a number of
environment steps, to copy itself into independent branches, to hand over
its agent for evaluation, and to save itself. Both trainers implement it:

* ``evolution.learner.EvolutionLearner``: the search algorithm's whole state
  (population, strategy, random generators), its champion of the current
  mazes as the agent;
* ``rl_baselines.learner.SB3Learner``: an SB3 A2C/PPO model with its
  optimiser state, the model itself as the agent.

**Random streams.** A branch draws from its own random stream, derived from
the run's seed, the stage and the branch by :func:`branch_seed`, so branches
never share draws and a run replays identically from its seed.

**Training sessions.** ``train(mazes, budget_steps, budget_seconds=...,
checkpoint=...)`` is one session: the learner trains on ``mazes`` (as given:
a curriculum passes the 4 rotations of its mazes) until it has spent
``budget_steps`` environment steps in the session (``None``: no step limit)
or ``budget_seconds`` seconds of training (``None``: no time limit; a
learner that cannot keep time refuses it), or earlier once it has converged
(every training episode optimal). A session is spent in the learner's own units (whole
generations, whole rollouts), so it may end a little past its budget; the
outcome says what it spent. During a session the learner calls
``checkpoint()`` at safe points (after a generation, at the start of a
rollout), at the pace its own settings ask for; the caller saves the learner
there. A learner saved that way and loaded again is *inside* its session:
calling ``train`` with the same mazes and budget continues the session where
it was saved instead of starting another one, which is how a killed run
resumes mid-stage. It also calls ``progress(steps)``, when given, with the
env steps the session has spent so far, after every generation or rollout:
what a live display (the browser curator's progress bars) shows.

**Watched sessions** (:class:`SessionWatch`, RL learners). A session may be
judged on other mazes than it trains on, as the paper's training scripts did
with SB3's ``EvalCallback``: every ``every`` steps the agent is evaluated on
the watch's mazes, the best one so far is kept (``keep_best()``), and the
session stops once every episode there is optimal; the training mazes are then
not evaluated at all.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from amaze.validation import check_integer, check_number

__all__ = [
    "EVALUATION_RULES",
    "Learner",
    "SessionWatch",
    "TrainingOutcome",
    "branch_seed",
    "checked_session_budget",
    "evaluation_score",
]

#: How an agent is ranked among the evaluations of a run or a session:
#: ``best-eval`` by success rate, then R̄; ``best-eval-reward`` by R̄ alone (the
#: mean reward SB3's ``EvalCallback`` ranks by: rotations of one maze share
#: their optimal reward, so mean R̄ orders as mean reward does).
EVALUATION_RULES = ("best-eval", "best-eval-reward")


def evaluation_score(rule: str, summary: Any) -> list[float]:
    """The score ``rule`` ranks an evaluation by (higher is better), from its summary."""
    reward = float(summary["normalized_reward"])
    if rule == "best-eval":
        return [float(summary["success_rate"]), reward]
    if rule == "best-eval-reward":
        return [reward]
    raise ValueError(f"unknown evaluation rule {rule!r} (choose from {EVALUATION_RULES})")


@dataclass(frozen=True)
class SessionWatch:
    """The mazes a session is judged on, instead of its own (see the module docstring).

    The agent is evaluated on ``mazes`` (as given: pass the rotations) at the
    learner's first safe point (a rollout start) at least ``every`` env steps
    after the previous evaluation, never at the session's start, and once more
    at its end if one is due; ``rule`` (:data:`EVALUATION_RULES`) ranks the
    evaluations, and a strictly better one calls ``keep_best()`` (so the
    earliest wins ties, as SB3's ``EvalCallback``). The session stops once
    every episode on ``mazes`` is optimal.
    """

    mazes: tuple[str, ...]
    every: int
    rule: str = "best-eval-reward"
    keep_best: Callable[[], None] | None = None

    def __post_init__(self) -> None:
        if not self.mazes:
            raise ValueError("a session watch needs at least one maze")
        if isinstance(self.every, bool) or not isinstance(self.every, int) or self.every < 1:
            raise ValueError(f"a session watch's every {self.every!r} is not an integer >= 1")
        evaluation_score(self.rule, {"normalized_reward": 0.0, "success_rate": 0.0})


@dataclass(frozen=True)
class TrainingOutcome:
    """What one training session spent and reached."""

    #: Environment steps of the session (over every resumed part of it).
    env_steps: int
    #: Wall-clock seconds of the session (over every resumed part of it).
    seconds: float
    #: True if the session stopped early because every training episode (or, in a
    #: watched session, every episode on the watch's mazes) was optimal.
    converged: bool


@runtime_checkable
class Learner(Protocol):
    """An agent in training, as a curriculum drives it (see the module docstring)."""

    def train(
        self,
        mazes: Sequence[str],
        budget_steps: int | None,
        *,
        budget_seconds: float | None = None,
        checkpoint: Callable[[], None] | None = None,
        progress: Callable[[int], None] | None = None,
        watch: SessionWatch | None = None,
    ) -> TrainingOutcome:
        """Train on ``mazes`` for ``budget_steps`` env steps or ``budget_seconds`` seconds.

        ``watch``: judge the session on other mazes (a learner that cannot refuses it).
        """
        ...

    def branch(self, seed: int) -> Learner:
        """An independent copy that draws from a random stream seeded with ``seed``."""
        ...

    def agent(self) -> Any:
        """The agent to evaluate: a policy of :mod:`amaze.evaluation.policy`."""
        ...

    def save(self, folder: Path) -> None:
        """Write the learner into ``folder`` (created if needed), every file atomically."""
        ...


def branch_seed(run_seed: int, stage: int, branch: int) -> int:
    """The seed of the random stream of ``branch`` at ``stage`` of a run seeded ``run_seed``.

    Derived with :class:`numpy.random.SeedSequence`, so that the streams of
    different (seed, stage, branch) triples are independent; in ``[0, 2**31)``.
    """
    state = np.random.SeedSequence([int(run_seed), int(stage), int(branch)]).generate_state(1)
    return int(state[0]) & 0x7FFF_FFFF


def checked_session_budget(
    budget_steps: Any, budget_seconds: Any, error: type[ValueError]
) -> tuple[int | None, float | None]:
    """A session's budget as the protocol has it: steps and/or seconds, not neither.

    Each is ``None`` (no limit of that kind) or a number >= 0; bad values raise
    ``error`` naming them.
    """
    if budget_steps is not None:
        budget_steps = check_integer("budget_steps", budget_steps, minimum=0, error=error)
    if budget_seconds is not None:
        budget_seconds = check_number("budget_seconds", budget_seconds, minimum=0, error=error)
    if budget_steps is None and budget_seconds is None:
        raise error("a training session needs budget_steps or budget_seconds (both are None)")
    return budget_steps, budget_seconds
