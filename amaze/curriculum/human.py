"""The terminal curator: a person makes the curriculum's decisions at the keyboard.

``--curator human`` asks, at every stage:

* **select**: every candidate's numbers (success, R̄ and steps per rotation
  on its own maze; its success and R̄ on the other branches' mazes; its
  lineage, the steps it spent, whether it converged) and the paths of its
  trajectory pictures; then a branch number.
* **generate**: the parent's maze and the target, then ``k`` maze strings, one
  at a time. Each is checked (:meth:`MazeSpec.from_string
  <amaze.maze.spec.MazeSpec.from_string>`; the parser's message is shown and
  the question asked again); an empty line takes the suggestion shown (the
  parent's maze with a new seed).

**Advice** (``--advisor NAME``, :mod:`amaze.curriculum.advice`): the
advisor's proposal is shown before each question, with its reasons (each
maze's operators, distance to the target and difficulty; the pick's front and
every candidate's criteria), and an empty line takes it: the advisor's maze
for each maze asked, the advisor's pick for the branch.

**The target's family.** Every candidate is also played on
:data:`PERSON_VALIDATION` mazes of the target's family (seeds disjoint from
the evaluation suite's; :func:`person_validation`) and its results there are
shown, so that a person can judge generalisation; the same mazes with or
without an advisor (an advisor with validation mazes of its own, such as
``edens``, judges by those: its criteria are in its proposal).

Bad typing never ends the run: the question is asked again. The end of the
input (Ctrl-D) raises :class:`~amaze.curriculum.curators.CuratorError`; the
decisions already made are in ``decisions.jsonl`` and a resumed run asks
only the remaining ones.
"""

from __future__ import annotations

import sys
from collections import Counter
from collections.abc import Sequence
from typing import TextIO

from amaze.curriculum.advice import Proposal
from amaze.curriculum.curators import (
    Candidate,
    CuratorContext,
    CuratorError,
    History,
    refuse_unknown_options,
)
from amaze.curriculum.genome import new_seed
from amaze.curriculum.validation import validation_mazes
from amaze.errors import one_line
from amaze.maze.spec import MazeSpec

__all__ = [
    "PERSON_VALIDATION",
    "TerminalCurator",
    "describe_proposal",
    "person_validation",
    "suggested_mazes",
]

#: Mazes of the target's family every candidate is shown on, for a person without an advisor.
PERSON_VALIDATION = 8


def person_validation(context: CuratorContext) -> list[str]:
    """The validation mazes of a person's curator: the target's family, seeds of their own."""
    seed = int(context.rng(0, "validation").integers(2**31))
    return validation_mazes(MazeSpec.from_string(context.target), PERSON_VALIDATION, seed)


def describe_proposal(proposal: Proposal) -> list[str]:
    """An advisor's proposal as lines of text: the mazes and their reasons, or the pick."""
    if proposal.kind == "generate":
        lines = [f"advisor {proposal.advisor} proposes:"]
        for index, reason in enumerate(proposal.reasons):
            counts = Counter(reason.operators)  # in the order applied, a repeated one counted
            how = ", ".join(f"{op} x{n}" if n > 1 else op for op, n in counts.items())
            how = how or "the parent's maze, unchanged"
            lines.append(
                f"  maze {index + 1}: {reason.maze}  ({how}; distance to the target"
                f" {reason.distance:.2f}, difficulty {reason.difficulty:.2f})"
            )
        return lines
    front = ", ".join(map(str, proposal.front))
    lines = [f"advisor {proposal.advisor} proposes branch {proposal.choice} (front: {front})"]
    for row in proposal.criteria:
        values = ", ".join(
            f"{key} {value:.3f}" if isinstance(value, float) else f"{key} {value}"
            for key, value in row.items()
            if key != "branch"
        )
        lines.append(f"  branch {row.get('branch')}: {values}")
    return lines


def suggested_mazes(context: CuratorContext, history: History, k: int) -> list[str]:
    """What a person is offered for the ``k`` mazes: the parent's maze, each with a new seed.

    Drawn from the context's stream for the stage, so a resumed run offers the same.
    """
    rng = context.rng(history.stage, "suggest")
    parent = MazeSpec.from_string(history.mazes[0])
    return [new_seed(parent, rng).to_string() for _ in range(k)]


def _flags(values: Sequence[bool]) -> str:
    return " ".join("yes" if v else "no " for v in values)


def _numbers(values: Sequence[float], form: str = "+.2f") -> str:
    return " ".join(format(v, form) for v in values)


class TerminalCurator:
    """A person at a terminal (see the module docstring); streams injectable for tests."""

    name = "human"
    #: It shows the advisor's proposal and takes it on an empty line.
    takes_advice = True

    def __init__(
        self,
        context: CuratorContext,
        input: TextIO | None = None,
        output: TextIO | None = None,
    ) -> None:
        refuse_unknown_options(context, self.name)
        self.context = context
        self.input = input if input is not None else sys.stdin
        self.output = output if output is not None else sys.stdout
        #: The target's family mazes the candidates are shown on.
        self.validation = person_validation(context)

    # -- the protocol -------------------------------------------------------------

    def select(self, candidates: Sequence[Candidate], advice: Proposal | None = None) -> Candidate:
        stage = candidates[0].stage if candidates else "?"
        self._say(f"\n== stage {stage}: choose the branch that goes on ==")
        for candidate in candidates:
            self._say(self.describe(candidate))
        by_branch = {c.branch: c for c in candidates}
        choices = ", ".join(str(b) for b in by_branch)
        default = ""
        if advice is not None:
            for line in describe_proposal(advice):
                self._say(line)
            default = f" [empty: {advice.choice}, the advisor's]"
        while True:
            answer = self._ask(f"branch ({choices}){default}: ").strip()
            if not answer and advice is not None and advice.choice in by_branch:
                return by_branch[advice.choice]
            try:
                return by_branch[int(answer)]
            except (ValueError, KeyError):
                self._say(f"  {answer!r} is not one of the branches {choices}")

    def generate(self, k: int, history: History, advice: Proposal | None = None) -> list[str]:
        parent = history.mazes[0]
        self._say(f"\n== stage {history.stage}: {k} maze(s) for the next branches ==")
        self._say(f"parent's maze: {parent}")
        self._say(f"target:        {self.context.target}")
        suggestions = suggested_mazes(self.context, history, k)
        if advice is not None and len(advice.mazes) == k:
            for line in describe_proposal(advice):
                self._say(line)
            suggestions = list(advice.mazes)
        return [self._maze(branch, k, suggestion) for branch, suggestion in enumerate(suggestions)]

    # -- helpers --------------------------------------------------------------------

    @staticmethod
    def describe(candidate: Candidate) -> str:
        """What a person sees of a candidate, as lines of text."""
        lines = [
            f"branch {candidate.branch}: success {candidate.success_rate:.2f},"
            f" R̄ {candidate.normalized_reward:+.3f} on its own maze;"
            f" overall success {candidate.overall_success_rate:.2f},"
            f" R̄ {candidate.overall_normalized_reward:+.3f}"
        ]
        for result in candidate.own:
            lines.append(f"  own {result.maze}")
            lines.append(f"    reached {_flags(result.success)}")
            lines.append(f"    R̄       {_numbers(result.normalized_reward)}")
            lines.append(f"    steps   {' '.join(str(s) for s in result.steps)}")
        for result in candidate.others:
            lines.append(
                f"  on {result.maze}: success {result.success_rate:.2f},"
                f" R̄ {result.normalized_reward_mean:+.3f}"
            )
        if candidate.validation:
            lines.append(
                f"  target's family ({len(candidate.validation)} validation mazes): success"
                f" {candidate.validation_success_rate:.2f},"
                f" R̄ {candidate.validation_normalized_reward:+.3f}"
            )
        lines.append(
            f"  lineage {list(candidate.lineage)}, {candidate.env_steps} steps"
            f" ({candidate.lineage_steps} with its lineage), {candidate.seconds:.1f} s,"
            f" {'converged' if candidate.converged else 'not converged'}"
        )
        lines.extend(f"  picture {path}" for path in candidate.pictures)
        return "\n".join(lines)

    def _maze(self, branch: int, k: int, suggestion: str) -> str:
        while True:
            answer = self._ask(f"maze {branch + 1}/{k} [empty: {suggestion}]: ").strip()
            if not answer:
                return suggestion
            try:
                return MazeSpec.from_string(answer).to_string()
            except (ValueError, TypeError) as problem:
                self._say(f"  bad maze {answer!r}: {one_line(problem)}")

    def _say(self, text: str) -> None:
        print(text, file=self.output, flush=True)

    def _ask(self, prompt: str) -> str:
        self.output.write(prompt)
        self.output.flush()
        line = self.input.readline()
        if not line:
            raise CuratorError(
                "the human curator's input ended (end of file) before the decision was made;"
                " the decisions made so far are recorded: resume the run to go on"
            )
        return line
