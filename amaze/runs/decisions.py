"""The decisions of a curriculum run: ``decisions.jsonl``, read with every line checked.

Every decision the curriculum loop (:mod:`amaze.runs.curriculum`) makes is
one JSON object per line, appended (atomically) before the loop acts on it:
``stage``, ``kind`` (``generate`` with the ``mazes``, canonical strings;
``select`` with the ``choice``, a branch index, and the ``candidates``'
figures), the ``curator``'s name, the ``time`` (UTC, ISO 8601) and the
``seconds`` the decision took; ``forced`` when there was one candidate,
``replayed`` when it came from another run (``replay.jsonl``). A run with an
advisor (:mod:`amaze.curriculum.advice`) adds, to every decision its curator
was asked, the advisor's ``proposal`` and ``accepted`` (select: the choice is
the advisor's pick; generate: for each proposed maze, whether it was kept).
Lines without them (older runs, runs without an advisor) read as before.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from amaze.curriculum.advice import (
    Proposal,
    check_advice,
    make_advisor,
    propose_generate,
    propose_select,
    seen_by,
)
from amaze.curriculum.curators import (
    Candidate,
    Curator,
    CuratorError,
    History,
    check_mazes,
    make_curator,
)
from amaze.curriculum.regimes import (
    MAX_OPEN_STAGES,
    OPEN_STAGES,
)
from amaze.runs.branches import branch_folder
from amaze.runs.folder import read_text, write_bytes
from amaze.validation import parse_json

__all__ = [
    "DECISIONS_FILE",
    "REPLAY_FILE",
    "Decision",
    "DecisionLog",
    "Decisions",
    "advice_taken",
    "check_against_decisions",
    "decision_index",
    "decision_sequence",
    "utc_now",
]

DECISIONS_FILE = "decisions.jsonl"
REPLAY_FILE = "replay.jsonl"


def utc_now() -> str:
    """Now, in UTC, as a decision records its time (ISO 8601, to the second)."""
    return datetime.now(UTC).isoformat(timespec="seconds")


@dataclass(frozen=True)
class Decision:
    """One line of ``decisions.jsonl`` (see the module docstring)."""

    stage: int
    kind: str
    curator: str
    time: str
    seconds: float
    choice: int | None = None
    candidates: tuple[dict[str, Any], ...] | None = None
    mazes: tuple[str, ...] | None = None
    forced: bool = False
    replayed: bool = False
    #: The advisor's proposal, and whether the decision took it (a flag per maze for generate).
    proposal: Proposal | None = None
    accepted: bool | tuple[bool, ...] | None = None

    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "stage": self.stage,
            "kind": self.kind,
            "curator": self.curator,
            "time": self.time,
            "seconds": round(self.seconds, 6),
        }
        if self.kind == "select":
            data["choice"] = self.choice
            data["candidates"] = list(self.candidates or ())
        else:
            data["mazes"] = list(self.mazes or ())
        if self.forced:
            data["forced"] = True
        if self.replayed:
            data["replayed"] = True
        if self.proposal is not None:
            data["proposal"] = self.proposal.to_dict()
            accepted = self.accepted
            data["accepted"] = list(accepted) if isinstance(accepted, tuple) else accepted
        return data


def advice_taken(decisions: Sequence[Decision]) -> dict[str, Any] | None:
    """How often the decider took its advisor's proposals (None: no decision was advised).

    ``selections`` advised and ``selections_taken`` (the proposed branch was
    chosen); ``mazes_proposed`` and ``mazes_kept`` (proposed mazes the
    generate decisions kept), and the two shares.
    """
    advised = [d for d in decisions if d.proposal is not None]
    if not advised:
        return None
    picks = [bool(d.accepted) for d in advised if d.kind == "select"]
    mazes = [kept for d in advised if d.kind != "select" for kept in d.accepted or ()]
    return {
        "selections": len(picks),
        "selections_taken": sum(picks),
        "selections_taken_share": sum(picks) / len(picks) if picks else None,
        "mazes_proposed": len(mazes),
        "mazes_kept": sum(mazes),
        "mazes_kept_share": sum(mazes) / len(mazes) if mazes else None,
    }


def _advice(data: Mapping[str, Any], kind: str) -> dict[str, Any]:
    """A decision line's ``proposal`` and ``accepted``, checked (none: an unadvised line)."""
    if "proposal" not in data:
        return {}
    proposal = Proposal.from_dict(data["proposal"], kind)
    accepted = data.get("accepted")
    if kind == "select":
        if not isinstance(accepted, bool):
            raise ValueError(f"accepted {accepted!r} is not true or false")
        return {"proposal": proposal, "accepted": accepted}
    if not (
        isinstance(accepted, list)
        and len(accepted) == len(proposal.mazes)
        and all(isinstance(a, bool) for a in accepted)
    ):
        raise ValueError(f"accepted {accepted!r} is not a true or false per proposed maze")
    return {"proposal": proposal, "accepted": tuple(accepted)}


def decision_sequence(stages: int) -> list[tuple[int, str]]:
    """The (stage, kind) of every decision of a finished run, in order.

    An open-ended run (``stages`` = :data:`~amaze.curriculum.regimes.OPEN_STAGES`)
    makes a prefix of the longest one's, ending with a select.
    """
    if stages == OPEN_STAGES:
        stages = MAX_OPEN_STAGES
    sequence = [(0, "generate")]
    for stage in range(1, stages):
        sequence += [(stage, "select"), (stage, "generate")]
    return [*sequence, (stages, "select")]


def decision_index(stage: int, kind: str) -> int:
    """Where the ``kind`` decision of ``stage`` comes in :func:`decision_sequence`."""
    return 2 * stage if kind == "generate" else 2 * stage - 1


class DecisionLog:
    """``decisions.jsonl``: read with every line checked, appended atomically."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def read(
        self, stages: int, branches: int, error: type[ValueError], what: str = "decisions file"
    ) -> list[Decision]:
        """The decisions, checked against the run's ``stages`` and ``branches``.

        Every line must be the JSON object of the next decision the loop
        makes (:func:`decision_sequence`), with valid mazes (as many as the
        stage has branches) or a choice among the previous stage's branches;
        anything else raises ``error`` naming the file and the line.
        """
        where = repr(str(self.path))
        if not (self.path.exists() or self.path.is_symlink()):
            return []
        text = read_text(self.path, error, what)
        expected = decision_sequence(stages)
        decisions: list[Decision] = []
        for number, line in enumerate(text.splitlines(), start=1):
            if not line.strip():
                continue

            def bad(problem: str, number: int = number) -> ValueError:
                return error(f"{what} {where}, line {number}: {problem}")

            try:
                data = parse_json(line, "the line", error=ValueError)
            except ValueError as problem:
                raise bad(str(problem).removeprefix("the line ")) from None
            if not isinstance(data, dict):
                raise bad("not a JSON object")
            index = len(decisions)
            if index >= len(expected):
                raise bad(f"one decision too many (a run of {stages} stages makes {index})")
            stage, kind = expected[index]
            if data.get("stage") != stage or data.get("kind") != kind:
                raise bad(
                    f"stage {data.get('stage')!r} kind {data.get('kind')!r}, where the"
                    f" loop's next decision is the {kind} of stage {stage}"
                )
            for key, types in (("curator", str), ("time", str), ("seconds", int | float)):
                if not isinstance(data.get(key), types) or isinstance(data.get(key), bool):
                    raise bad(f"{key} {data.get(key)!r} is missing or of the wrong type")
            common = {
                "stage": stage,
                "kind": kind,
                "curator": data["curator"],
                "time": data["time"],
                "seconds": float(data["seconds"]),
                "forced": data.get("forced") is True,
                "replayed": data.get("replayed") is True,
            }
            try:
                common.update(_advice(data, kind))
            except ValueError as problem:
                raise bad(str(problem)) from None
            if kind == "generate":
                count = 1 if stage == 0 else branches
                try:
                    mazes = check_mazes(data.get("mazes"), count, data["curator"])
                except CuratorError as problem:
                    raise bad(str(problem)) from None
                decisions.append(Decision(**common, mazes=tuple(mazes)))
            else:
                count = 1 if stage == 1 else branches
                choice = data.get("choice")
                if not isinstance(choice, int) or isinstance(choice, bool):
                    raise bad(f"choice {choice!r} is not a branch number")
                if not 0 <= choice < count:
                    raise bad(f"choice {choice} is not one of the {count} branches")
                candidates = data.get("candidates", [])
                if not isinstance(candidates, list) or not all(
                    isinstance(c, dict) for c in candidates
                ):
                    raise bad("candidates is not a list of JSON objects")
                decisions.append(Decision(**common, choice=choice, candidates=tuple(candidates)))
        return decisions

    def append(self, decision: Decision) -> None:
        """Add one decision: the whole file is rewritten atomically (it holds 2 S lines)."""
        old = self.path.read_bytes() if self.path.exists() else b""
        if old and not old.endswith(b"\n"):
            old += b"\n"
        line = json.dumps(decision.to_dict(), sort_keys=True) + "\n"
        write_bytes(self.path, old + line.encode("utf-8"))


def check_against_decisions(
    candidate: Candidate,
    finished: Mapping[tuple[int, int], Candidate],
    recorded: Sequence[Decision],
    path: Path,
    error: type[ValueError],
) -> None:
    """A finished branch agrees with the decisions (``recorded``, of the file ``path``).

    It is of the maze its stage's generate decision gave it, descends from the
    branch of ``finished`` that the stage's select decision chose, and its
    lineage's steps add up: a result that does not was made under other
    decisions (the file edited since).
    """
    stage, branch = candidate.stage, candidate.branch
    where = repr(str(branch_folder(path.parent, stage, branch) / "result.json"))
    generate = decision_index(stage, "generate")
    mazes = recorded[generate].mazes if generate < len(recorded) else None
    if mazes is None or branch >= len(mazes) or candidate.mazes != (mazes[branch],):
        raise error(
            f"branch result {where} is of maze {candidate.mazes[0]!r}, which"
            f" {str(path)!r} does not give branch {branch} of stage {stage}"
        )
    if stage == 0:
        return
    select = decision_index(stage, "select")
    choice = recorded[select].choice if select < len(recorded) else None
    parent = finished.get((stage - 1, choice)) if choice is not None else None
    if parent is None or candidate.lineage[:-1] != parent.lineage:
        raise error(
            f"branch result {where} descends from lineage {list(candidate.lineage[:-1])},"
            f" but {str(path)!r} chose branch {choice} of stage {stage - 1}"
            + ("" if parent is None else f" (lineage {list(parent.lineage)})")
        )
    if candidate.lineage_steps != parent.lineage_steps + candidate.env_steps:
        raise error(
            f"branch result {where}: lineage_steps {candidate.lineage_steps} is not its"
            f" parent's {parent.lineage_steps} plus its env_steps {candidate.env_steps}"
        )


class Decisions:
    """The decisions of a curriculum run: recorded already, replayed, or asked and recorded.

    A resumed run finds its decisions ``recorded`` in the log (a person is
    never asked twice); a replay takes another run's (``replayed``); any other
    is asked of the ``curator`` now, after its ``advisor``'s proposal if it has
    one (:mod:`amaze.curriculum.advice`), checked and appended to the log
    before the loop acts on it. Whatever a curator raises (a plug-in's bug, an
    ``OSError``, even ``SystemExit``) ends the run with one error naming it.
    """

    def __init__(self, log: DecisionLog, config: Any) -> None:
        self.log = log
        #: The run's config (a :class:`~amaze.runs.regime.RegimeConfig`).
        self.config = config
        self.recorded: list[Decision] = []
        self.replayed: list[Decision] = []
        self.curator: Curator | None = None
        self.advisor: Curator | None = None

    def build(self) -> list[str]:
        """Build the curator and its advisor; the validation mazes to play candidates on.

        A bad name, plug-in, option or pairing (an advisor for a curator that
        takes no advice) fails here, as the config's error. The validation
        mazes are the curator's, then the advisor's (canonical, each once).
        """
        c = self.config
        advisor = getattr(c, "advisor", None)
        self.curator = self.call_curator(
            "being built", lambda: make_curator(c.curator, c.curator_context())
        )
        if advisor is not None:
            self.advisor = self.call_curator(
                "being built", lambda: make_advisor(advisor, c.advisor_context()), "advisor"
            )
        self.call_curator("taking advice", lambda: check_advice(self.curator, c.curator, advisor))
        mazes: list[str] = []
        for role, curator in (("curator", self.curator), ("advisor", self.advisor)):
            given = self.call_curator(
                "giving its validation mazes",
                lambda curator=curator: list(getattr(curator, "validation", None) or ()),
                role,
            )
            if given:
                given = self.call_curator(
                    "giving its validation mazes",
                    lambda given=given, role=role: check_mazes(given, len(given), self._name(role)),
                    role,
                )
            mazes += [maze for maze in given if maze not in mazes]
        return mazes

    def _name(self, role: str) -> str:
        return str(self.config.advisor if role == "advisor" else self.config.curator)

    def call_curator(self, doing: str, call: Callable[[], Any], role: str = "curator") -> Any:
        """``call()``, a call into the curator or advisor: whatever it raises is the config's error.

        A curator may be a plug-in: its exceptions end the run with one line
        naming the curator and what it was doing, never a traceback or an exit
        status that hides the failure.
        """
        name, error = self._name(role), self.config.error
        try:
            return call()
        except KeyboardInterrupt:
            raise
        except CuratorError as problem:
            raise error(str(problem)) from None
        except (Exception, SystemExit) as problem:
            detail = f"{type(problem).__name__}: {problem}".rstrip(": ")
            raise error(f"{role} {name!r} failed {doing} ({detail})") from None

    def generate(self, stage: int, history: History | Callable[[], list[str]]) -> list[str]:
        """The mazes of ``stage``: the curator's for ``history`` (or what the callable gives)."""
        if callable(history):
            given = history
            return self.decide(stage, "generate", lambda _: given())
        curator, advisor, branches = self.curator, self.advisor, self.config.branches
        assert curator is not None

        def propose() -> Proposal | None:
            if advisor is None:
                return None
            seen = dataclasses.replace(history, parent=seen_by(advisor, [history.parent])[0])
            target, name = self.config.target, self._name("advisor")
            return self.call_curator(
                "proposing mazes",
                lambda: propose_generate(advisor, name, branches, seen, target),
                "advisor",
            )

        def ask(proposal: Proposal | None) -> list[str]:
            seen = dataclasses.replace(history, parent=seen_by(curator, [history.parent])[0])
            if proposal is None:
                return self.call_curator(
                    "generating mazes", lambda: curator.generate(branches, seen)
                )
            return self.call_curator(
                "generating mazes", lambda: curator.generate(branches, seen, advice=proposal)
            )

        return self.decide(stage, "generate", ask, propose=propose)

    def select(self, stage: int, candidates: Sequence[Candidate]) -> int:
        """The branch of ``candidates`` (the previous stage's) chosen before ``stage``."""
        curator, advisor, error = self.curator, self.advisor, self.config.error
        assert curator is not None

        def propose() -> Proposal | None:
            if advisor is None:
                return None
            seen, name = seen_by(advisor, candidates), self._name("advisor")
            return self.call_curator(
                "proposing a choice", lambda: propose_select(advisor, name, seen), "advisor"
            )

        def ask(proposal: Proposal | None) -> int:
            seen = seen_by(curator, candidates)
            if proposal is None:
                chosen = self.call_curator("selecting", lambda: curator.select(seen))
            else:
                chosen = self.call_curator(
                    "selecting", lambda: curator.select(seen, advice=proposal)
                )
            for index, candidate in enumerate(seen):
                if chosen is candidate or chosen == candidate:
                    return index
            raise error(
                f"curator {self.config.curator!r} selected {chosen!r}, not one of the candidates"
            )

        return self.decide(stage, "select", ask, candidates, propose)

    def decide(
        self,
        stage: int,
        kind: str,
        ask: Callable[[Proposal | None], Any],
        candidates: Sequence[Candidate] = (),
        propose: Callable[[], Proposal | None] | None = None,
    ) -> Any:
        """A decision: recorded already (resume), replayed, or asked now and recorded."""
        index = decision_index(stage, kind)
        if index < len(self.recorded):
            decision = self.recorded[index]
        else:
            if index < len(self.replayed):
                decision = dataclasses.replace(
                    self.replayed[index], time=utc_now(), seconds=0.0, replayed=True
                )
            else:
                decision = self._asked(stage, kind, ask, candidates, propose)
            self.log.append(decision)
            self.recorded.append(decision)
        if kind == "generate":
            return list(decision.mazes or ())
        if decision.choice is None or not 0 <= decision.choice < len(candidates):
            raise self.config.error(
                f"decision of stage {stage}: choice {decision.choice!r} is out of range"
            )
        return decision.choice

    def _asked(
        self,
        stage: int,
        kind: str,
        ask: Callable[[Proposal | None], Any],
        candidates: Sequence[Candidate],
        propose: Callable[[], Proposal | None] | None,
    ) -> Decision:
        """The decision ``ask()`` gives now, after the advisor's proposal (one candidate: forced).

        ``seconds`` is the decider's time; the advisor's is in its proposal.
        """
        c = self.config
        forced = kind == "select" and len(candidates) == 1
        proposal = None if forced or propose is None else propose()
        started = time.perf_counter()
        answer = 0 if forced else ask(proposal)
        seconds = time.perf_counter() - started
        common: dict[str, Any] = {
            "stage": stage,
            "kind": kind,
            "curator": c.curator,
            "time": utc_now(),
            "seconds": seconds,
            "forced": forced,
        }
        if kind == "select":
            figures = tuple(candidate.figures() for candidate in candidates)
            if proposal is not None:
                accepted = proposal.accepted(candidates[int(answer)].branch)
                common.update(proposal=proposal, accepted=accepted)
            return Decision(**common, choice=int(answer), candidates=figures)
        count = 1 if stage == 0 else c.branches
        try:
            mazes = check_mazes(answer, count, c.curator)
        except CuratorError as problem:
            raise c.error(str(problem)) from None
        if proposal is not None:
            common.update(proposal=proposal, accepted=tuple(proposal.accepted(mazes)))
        return Decision(**common, mazes=tuple(mazes))
