"""``follow``: a scripted decider that takes its advisor's proposal with probability ``p``.

A stand-in for a person who listens to an automated curator some of the
time, for studies without a person: ``--curator follow --advisor edens
--curator-option p=0.5``. At every decision it draws, from its own stream
for that decision (:meth:`~amaze.curriculum.curators.CuratorContext.rng`,
purpose ``follow-select`` or ``follow-generate``), whether it follows: with
probability ``p`` it takes the advisor's proposal whole (the pick, or all
``k`` mazes), otherwise its ``base`` curator decides as it would alone (the
base is built on the same context, so with ``p`` 0 a run is the base's
run, decision for decision). It needs an advisor: without one it is refused.

Options (``curator_options``): ``p`` (0..1, default 0.5), ``base`` (an
automated curator, default ``careful``; not ``human`` nor ``follow``), and
any other option is the base's (``threshold`` for careful...).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from amaze.curriculum.advice import NOT_ADVISORS, Proposal
from amaze.curriculum.curators import (
    Candidate,
    CuratorContext,
    CuratorError,
    History,
    make_curator,
)
from amaze.validation import check_number

__all__ = ["FollowCurator"]


class FollowCurator:
    """Follows the advice with probability ``p``, else its base decides (see the module)."""

    name = "follow"
    #: It reads the advisor's proposal (:mod:`amaze.curriculum.advice`).
    takes_advice = True

    def __init__(self, context: CuratorContext) -> None:
        if context.advisor is None:
            raise CuratorError(
                "curator 'follow' follows an advisor's proposals: give it one (--advisor NAME,"
                " e.g. --advisor edens)"
            )
        options = dict(context.options)
        self.context = context
        self.p = check_number(
            "follow p", options.pop("p", 0.5), minimum=0, maximum=1, error=CuratorError
        )
        base = options.pop("base", "careful")
        if not isinstance(base, str) or base in NOT_ADVISORS:
            raise CuratorError(
                f"follow base {base!r}: the base is an automated curator (not"
                f" {' or '.join(NOT_ADVISORS)}), default careful"
            )
        #: The curator that decides when the advice is not followed (the rest of the options).
        self.base = make_curator(base, dataclasses.replace(context, options=options))
        #: The base's validation mazes, if it has any: the loop plays the candidates on them.
        self.validation = list(getattr(self.base, "validation", None) or ())

    def follows(self, stage: int, kind: str) -> bool:
        """Whether the decision ``kind`` of ``stage`` follows the advice (a seeded draw)."""
        return bool(self.context.rng(stage, f"follow-{kind}").random() < self.p)

    def select(self, candidates: Sequence[Candidate], advice: Proposal | None = None) -> Candidate:
        if advice is not None and self.follows(candidates[0].stage + 1, "select"):
            for candidate in candidates:
                if candidate.branch == advice.choice:
                    return candidate
        return self.base.select(candidates)

    def generate(self, k: int, history: History, advice: Proposal | None = None) -> list[str]:
        if advice is not None and self.follows(history.stage, "generate"):
            return list(advice.mazes)
        return self.base.generate(k, history)
