"""Advice: an automated curator proposes, the deciding curator decides.

An EDHuCAT run may give its curator (the *decider*) an *advisor*
(``--advisor NAME``, with its own ``advisor_options``): any automated curator,
built-in or a plug-in's (not ``human``, a person, nor ``follow``, which
needs advice itself). At every decision the decider is asked (not the
trivial first maze, nor a select with one candidate), the advisor makes its
:class:`Proposal` first:

* **generate**: its ``k`` mazes, each with its reason (:class:`MazeReason`):
  the operators that made it from the parent's maze (the advisor's own
  account when it gives one, :meth:`explain_generate`; else the fields that
  changed, :func:`changed_fields`), its distance to the target
  (:func:`~amaze.curriculum.distance.maze_distance`) and its expected
  difficulty (:func:`~amaze.curriculum.difficulty.difficulty`);
* **select**: its pick, the front it picked from and the criteria values of
  every candidate (its own account, :meth:`explain_select`; else its pick
  alone and the candidates' figures).

The advisor is built on the run's context with ``role`` ``"advisor"``:
its random streams are its own, derived from the run's seed apart from the
decider's, and it sees the candidates' results on its own validation mazes
only, so with or without a person deciding it makes the same proposal for
the same curriculum.

**How the proposal reaches the decider.** A curator class that declares
``takes_advice = True`` is called ``select(candidates, advice=proposal)``
and ``generate(k, history, advice=proposal)``; any other curator is called as
always, and giving it an advisor is refused (:func:`check_advice`): it would
never see the advice. The shipped curators take it: the scripted strategies
and ``edens`` keep deciding by their own rules (the proposal is recorded
beside each decision: how often they agree), ``human`` shows it and takes it
on an empty line, ``follow`` (:mod:`amaze.curriculum.follow`) takes it with
probability ``p``. A curator's context says whether it is advised
(:attr:`~amaze.curriculum.curators.CuratorContext.advisor`).

**Recorded.** The decision line of ``decisions.jsonl`` keeps the
``proposal`` (:meth:`Proposal.to_dict`) and ``accepted``
(:meth:`Proposal.accepted`: for a select, whether the choice is the
advisor's pick; for a generate, for each proposed maze, whether the decision
kept it).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from amaze.curriculum.curators import (
    BUILTIN_CURATORS,
    Candidate,
    Curator,
    CuratorContext,
    CuratorError,
    History,
    check_mazes,
    curator_class,
    make_curator,
)
from amaze.curriculum.difficulty import difficulty
from amaze.curriculum.distance import maze_distance
from amaze.maze.spec import MazeSpec

__all__ = [
    "NOT_ADVISORS",
    "MazeReason",
    "Proposal",
    "changed_fields",
    "check_advice",
    "make_advisor",
    "propose_generate",
    "propose_select",
    "seen_by",
]

#: Curators that cannot advise: a person, and the curator that follows advice.
NOT_ADVISORS = ("human", "follow")
#: Digits kept of a proposal's numbers in ``decisions.jsonl``.
_DIGITS = 6


def _number(value: Any) -> float | None:
    """A finite number rounded for the record; ``None`` for NaN and infinities."""
    value = float(value)
    return round(value, _DIGITS) if math.isfinite(value) else None


def changed_fields(before: str | MazeSpec, after: str | MazeSpec) -> tuple[str, ...]:
    """The field groups of the maze string that differ from ``before`` to ``after``.

    Among ``size``, ``start``, ``unicursive``, ``clue``, ``lure``,
    ``p_lure``, ``trap``, ``p_trap`` and ``seed`` (new walls), in that
    order; empty for the same maze.
    """
    a = before if isinstance(before, MazeSpec) else MazeSpec.from_string(before)
    b = after if isinstance(after, MazeSpec) else MazeSpec.from_string(after)
    changed = []
    if (a.width, a.height) != (b.width, b.height):
        changed.append("size")
    if (a.start, a.rotated) != (b.start, b.rotated):
        changed.append("start")
    for name in ("unicursive", "clue", "lure", "p_lure", "trap", "p_trap", "seed"):
        if getattr(a, name) != getattr(b, name):
            changed.append(name)
    return tuple(changed)


@dataclass(frozen=True)
class MazeReason:
    """Why an advisor proposes a maze: how it was made, how far and how hard it is."""

    maze: str
    #: The operators that made it from the parent's maze (none: the parent's maze itself).
    operators: tuple[str, ...]
    #: :func:`~amaze.curriculum.distance.maze_distance` to the target.
    distance: float
    #: :func:`~amaze.curriculum.difficulty.difficulty`, the expected difficulty.
    difficulty: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "maze": self.maze,
            "operators": list(self.operators),
            "distance": _number(self.distance),
            "difficulty": _number(self.difficulty),
        }


@dataclass(frozen=True)
class Proposal:
    """An advisor's proposal for one decision (see the module docstring)."""

    advisor: str
    kind: str
    #: Seconds the advisor took.
    seconds: float = 0.0
    #: generate: the proposed mazes (canonical strings) and why each.
    mazes: tuple[str, ...] = ()
    reasons: tuple[MazeReason, ...] = ()
    #: select: the branch picked, the branches of the front it was picked from,
    #: and each candidate's criteria (``branch`` and the advisor's values).
    choice: int | None = None
    front: tuple[int, ...] = ()
    criteria: tuple[Mapping[str, Any], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``proposal`` of a decision line."""
        data: dict[str, Any] = {
            "advisor": self.advisor,
            "seconds": round(self.seconds, _DIGITS),
        }
        if self.kind == "select":
            data["choice"] = self.choice
            data["front"] = list(self.front)
            data["criteria"] = [dict(row) for row in self.criteria]
        else:
            data["mazes"] = list(self.mazes)
            data["reasons"] = [reason.to_dict() for reason in self.reasons]
        return data

    @classmethod
    def from_dict(cls, data: Any, kind: str) -> Proposal:
        """The proposal of a decision line of ``kind``; ``ValueError`` naming what is wrong."""
        if not isinstance(data, dict):
            raise ValueError(f"proposal {data!r} is not a JSON object")
        advisor, seconds = data.get("advisor"), data.get("seconds", 0.0)
        if not isinstance(advisor, str):
            raise ValueError(f"proposal advisor {advisor!r} is not a name")
        if not isinstance(seconds, int | float) or isinstance(seconds, bool):
            raise ValueError(f"proposal seconds {seconds!r} is not a number")
        if kind == "select":
            choice, front, criteria = data.get("choice"), data.get("front"), data.get("criteria")
            if not isinstance(choice, int) or isinstance(choice, bool):
                raise ValueError(f"proposal choice {choice!r} is not a branch number")
            if not isinstance(front, list) or not all(isinstance(b, int) for b in front):
                raise ValueError(f"proposal front {front!r} is not a list of branches")
            if not isinstance(criteria, list) or not all(isinstance(r, dict) for r in criteria):
                raise ValueError("proposal criteria is not a list of JSON objects")
            return cls(advisor, kind, float(seconds), choice=choice, front=tuple(front),
                       criteria=tuple(criteria))  # fmt: skip
        mazes, reasons = data.get("mazes"), data.get("reasons")
        if not isinstance(mazes, list) or not all(isinstance(m, str) for m in mazes):
            raise ValueError(f"proposal mazes {mazes!r} is not a list of maze strings")
        if not isinstance(reasons, list) or len(reasons) != len(mazes):
            raise ValueError("proposal reasons is not a list with one reason per maze")
        read = []
        for maze, reason in zip(mazes, reasons, strict=True):
            if not isinstance(reason, dict) or not isinstance(reason.get("operators"), list):
                raise ValueError(f"proposal reason {reason!r} is not a reason")
            numbers = [reason.get("distance"), reason.get("difficulty")]
            distance, hard = (float("nan") if v is None else float(v) for v in numbers)
            read.append(MazeReason(maze, tuple(map(str, reason["operators"])), distance, hard))
        return cls(advisor, kind, float(seconds), mazes=tuple(mazes), reasons=tuple(read))

    def accepted(self, answer: int | Sequence[str]) -> bool | list[bool]:
        """Whether the decision took the proposal.

        ``answer`` is the chosen branch (select: true when it is the pick) or
        the decided mazes (generate: for each proposed maze, whether the
        decision kept it, at any branch).
        """
        if self.kind == "select":
            return answer == self.choice
        kept = set(answer)  # type: ignore[arg-type]
        return [maze in kept for maze in self.mazes]


def seen_by(curator: Any, candidates: Sequence[Candidate]) -> list[Candidate]:
    """``candidates`` as ``curator`` sees them: its own validation mazes' results only.

    The loop plays every candidate on the decider's and the advisor's
    validation mazes; a curator with validation mazes of its own sees its
    results alone (an advisor's proposal never depends on the decider), one
    without sees all of them. Candidates that change nothing are the same objects.
    """
    own = getattr(curator, "validation", None) or ()
    if not own:
        return list(candidates)
    keep = {MazeSpec.from_string(str(maze)).to_string() for maze in own}
    seen = []
    for candidate in candidates:
        kept = tuple(r for r in candidate.validation if r.maze in keep)
        same = len(kept) == len(candidate.validation)
        seen.append(candidate if same else dataclasses.replace(candidate, validation=kept))
    return seen


def make_advisor(name: str, context: CuratorContext) -> Curator:
    """The automated curator ``name`` as an advisor, on ``context`` with its own streams."""
    if name in NOT_ADVISORS:
        raise CuratorError(
            f"advisor {name!r} cannot advise: an advisor is an automated curator that makes"
            f" its proposal alone (not {' or '.join(NOT_ADVISORS)})"
        )
    return make_curator(name, dataclasses.replace(context, role="advisor", advisor=None))


def check_advice(curator: Any, name: str, advisor: str | None) -> None:
    """Refuse an ``advisor`` for a curator that would never see its advice."""
    if advisor is None or getattr(curator, "takes_advice", False) is True:
        return
    taking = [n for n in BUILTIN_CURATORS if getattr(curator_class(n), "takes_advice", False)]
    raise CuratorError(
        f"curator {name!r} takes no advice: --advisor {advisor} would have no effect (curators"
        f" that take advice: {', '.join(taking)}; a plug-in declares takes_advice = True)"
    )


def _reason(maze: str, operators: Sequence[str], target: MazeSpec) -> MazeReason:
    spec = MazeSpec.from_string(maze)
    return MazeReason(maze, tuple(operators), maze_distance(spec, target), difficulty(spec))


def propose_generate(advisor: Any, name: str, k: int, history: History, target: str) -> Proposal:
    """``advisor``'s ``k`` mazes for the stage of ``history``, each with its reason.

    An advisor with ``explain_generate(k, history)`` (a list of ``(maze,
    operators)``) gives its own operators; for any other, the operators are
    the fields that changed from the parent's maze (:func:`changed_fields`).
    """
    started = time.perf_counter()
    parent = history.mazes[0]
    explain = getattr(advisor, "explain_generate", None)
    if callable(explain):
        made = list(explain(k, history))
        if not all(isinstance(item, tuple) and len(item) == 2 for item in made):
            raise CuratorError(f"advisor {name!r} explained {made!r}, not (maze, operators) pairs")
        mazes = check_mazes([maze for maze, _ in made], k, name)
        operators = [tuple(map(str, ops)) for _, ops in made]
    else:
        mazes = check_mazes(advisor.generate(k, history), k, name)
        operators = [changed_fields(parent, maze) for maze in mazes]
    spec = MazeSpec.from_string(target)
    reasons = tuple(_reason(m, ops, spec) for m, ops in zip(mazes, operators, strict=True))
    seconds = time.perf_counter() - started
    return Proposal(name, "generate", seconds, mazes=tuple(mazes), reasons=reasons)


def _criteria(candidate: Candidate, values: Mapping[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {"branch": candidate.branch}
    for key, value in values.items():
        is_number = isinstance(value, int | float) and not isinstance(value, bool)
        row[key] = _number(value) if is_number else value
    return row


def propose_select(advisor: Any, name: str, candidates: Sequence[Candidate]) -> Proposal:
    """``advisor``'s pick among ``candidates``, with its front and criteria.

    An advisor with ``explain_select(candidates)`` returns ``(chosen, front,
    criteria)``: the candidate it picks, the candidates it picked from and
    one mapping of criteria values per candidate; for any other, the front is
    its pick alone and the criteria the candidates' figures.
    """
    started = time.perf_counter()
    explain = getattr(advisor, "explain_select", None)
    if callable(explain):
        chosen, front, values = explain(list(candidates))
    else:
        chosen = advisor.select(list(candidates))
        front, values = [chosen], [c.figures() for c in candidates]
    branch = next((c.branch for c in candidates if c is chosen or c == chosen), None)
    if branch is None:
        raise CuratorError(f"advisor {name!r} picked {chosen!r}, not one of the candidates")
    criteria = tuple(
        _criteria(c, {k: v for k, v in row.items() if k != "branch"})
        for c, row in zip(candidates, values, strict=True)
    )
    seconds = time.perf_counter() - started
    return Proposal(name, "select", seconds, choice=branch,
                    front=tuple(c.branch for c in front), criteria=criteria)  # fmt: skip
