"""A curation session: the curriculum loop in a worker thread, the person on a page.

:class:`CurationSession` is the meeting point of two threads:

* the **worker** runs the EDHuCAT loop (:class:`~amaze.runs.curriculum.CurriculumRun`
  of the chosen trainer, made by :meth:`CurationSession.run_class`). Its
  curator is a :class:`BrowserCurator`: at each decision it posts a
  question to the session and waits for the answer; between decisions the
  loop trains and reports each branch's progress;
* the **server** (:mod:`experiments.curate.server`) reads the session's
  state for the page and hands it the person's answers, checked first.

Everything the page shows comes from the session, so a second tab, or the
same one reopened, sees the same state. Decisions go to the run's
``decisions.jsonl`` as with any curator (``curator`` ``human``, with the
seconds the person took), so a killed server resumes with ``--resume`` and
a finished session replays with ``--replay``.
"""

from __future__ import annotations

import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from amaze.curriculum.advice import Proposal
from amaze.curriculum.curators import Candidate, CuratorContext, CuratorError, History, MazeResults
from amaze.curriculum.human import person_validation, suggested_mazes
from amaze.errors import AmazeError, one_line
from amaze.runs.branches import BranchProgress, branch_folder
from amaze.runs.curriculum import CurriculumRun
from amaze.runs.lifecycle import RunResult
from experiments.curate.design import DesignError, maze_card, strict_maze

__all__ = ["AnswerError", "BrowserCurator", "CurationSession", "Question"]

#: Figures of ``summary.json`` the final page shows.
FINAL_FIGURES = (
    "success_rate",
    "normalized_reward",
    "input_recognition",
    "env_steps",
    "seconds",
    "stages_played",
    "final_lineage",
)


class AnswerError(AmazeError):
    """An answer the session cannot take; ``status`` is the HTTP status to reply with."""

    def __init__(self, message: str, status: int = 400, details: Any = None) -> None:
        super().__init__(message)
        self.status = status
        self.details = details


@dataclass
class Question:
    """A decision the loop waits for: ``select`` a branch or ``generate`` mazes."""

    kind: str
    stage: int
    #: What the page shows to ask it (plain JSON).
    content: dict[str, Any]
    #: What a valid answer may be: the branches (select), the number of mazes (generate).
    choices: tuple[int, ...] = ()
    count: int = 0
    asked: float = field(default_factory=time.time)
    answer: Any = None
    answered: bool = False

    @property
    def id(self) -> str:
        return f"{self.kind}-{self.stage}"


def _results(result: MazeResults, index: int) -> dict[str, Any]:
    return {
        "maze": result.maze,
        "index": index,
        "success": list(result.success),
        "normalized_reward": [round(v, 4) for v in result.normalized_reward],
        "steps": list(result.steps),
        "success_rate": result.success_rate,
        "normalized_reward_mean": round(result.normalized_reward_mean, 4),
    }


def family_view(candidate: Candidate) -> dict[str, Any] | None:
    """A candidate's results on the target's family (its validation mazes), if it has any."""
    if not candidate.validation:
        return None
    return {
        "mazes": len(candidate.validation),
        "success_rate": round(candidate.validation_success_rate, 4),
        "normalized_reward": round(candidate.validation_normalized_reward, 4),
        "solved": sum(r.solved for r in candidate.validation),
    }


def last_result_view(candidate: Candidate) -> dict[str, Any]:
    """How the agent did on the maze it trained on last (the design step shows it)."""
    own = candidate.own[0]
    return {
        **_results(own, candidate.branch),
        "stage": candidate.stage,
        "branch": candidate.branch,
        "converged": candidate.converged,
        "family": family_view(candidate),
    }


def proposal_view(proposal: Proposal | None) -> dict[str, Any] | None:
    """The advisor's proposal as the page shows it: its decision and reasons."""
    if proposal is None:
        return None
    data = proposal.to_dict()
    data["kind"] = proposal.kind
    return data


def candidate_view(candidate: Candidate, stage_mazes: Sequence[str]) -> dict[str, Any]:
    """What the page shows of a candidate: figures, results per maze and on the family, lineage."""
    results = [*candidate.own, *candidate.others]
    by_maze: list[dict[str, Any]] = []
    others = iter(candidate.others)
    for index in range(len(stage_mazes)):
        result = candidate.own[0] if index == candidate.branch else next(others)
        by_maze.append(_results(result, index))
    return {
        "stage": candidate.stage,
        "branch": candidate.branch,
        "maze": candidate.mazes[0],
        "success_rate": candidate.success_rate,
        "normalized_reward": round(candidate.normalized_reward, 4),
        "overall_success_rate": candidate.overall_success_rate,
        "overall_normalized_reward": round(candidate.overall_normalized_reward, 4),
        "solved_mazes": sum(r.solved for r in results),
        "results": by_maze,
        "lineage": list(candidate.lineage),
        "env_steps": candidate.env_steps,
        "lineage_steps": candidate.lineage_steps,
        "seconds": round(candidate.seconds, 2),
        "converged": candidate.converged,
        "family": family_view(candidate),
    }


class BrowserCurator:
    """The ``human`` curator whose person answers on the page (see the module docstring).

    With an advisor (``--advisor``), its proposal is on the page, marked, with
    its reasons and one button to take it; the mazes' editors start from it.
    Candidates are shown on the person's validation mazes of the target's
    family (:func:`~amaze.curriculum.human.person_validation`).
    """

    name = "human"
    #: It shows the advisor's proposal (:mod:`amaze.curriculum.advice`).
    takes_advice = True

    def __init__(self, session: CurationSession, context: CuratorContext) -> None:
        self.session = session
        self.context = context
        #: The target's family mazes the candidates are shown on (the terminal curator's).
        self.validation = person_validation(context)

    def select(self, candidates: Sequence[Candidate], advice: Proposal | None = None) -> Candidate:
        stage = candidates[0].stage + 1
        mazes = [c.mazes[0] for c in sorted(candidates, key=lambda c: c.branch)]
        content = {
            "candidates": [candidate_view(c, mazes) for c in candidates],
            "mazes": mazes,
            "advice": proposal_view(advice),
        }
        choices = tuple(c.branch for c in candidates)
        branch = self.session.ask(Question("select", stage, content, choices=choices))
        return next(c for c in candidates if c.branch == branch)

    def generate(self, k: int, history: History, advice: Proposal | None = None) -> list[str]:
        parent = history.mazes[0]
        previous = history.stages[-1].mazes if history.stages else (parent,)
        suggestions = suggested_mazes(self.context, history, k)
        if advice is not None and len(advice.mazes) == k:
            suggestions = list(advice.mazes)
        content = {
            "k": k,
            "parent": maze_card(parent),
            "last_result": last_result_view(history.parent),
            # how far the target still is from the parent's maze
            "target": maze_card(self.context.target, parent),
            "previous": list(previous),
            "suggestions": suggestions,
            "lineage": list(history.parent.lineage),
            "advice": proposal_view(advice),
        }
        return self.session.ask(Question("generate", history.stage, content, count=k))


class CurationSession:
    """The state both threads share (see the module docstring); every method is thread-safe."""

    def __init__(self, out: Path, description: dict[str, Any]) -> None:
        self.out = Path(out)
        #: What the page's header says of the run (algorithm, robot, stages...).
        self.description = dict(description)
        self._changed = threading.Condition(threading.RLock())
        self.version = 0
        self.phase = "starting"
        self.question: Question | None = None
        self.run: CurriculumRun | None = None
        self.final: dict[str, Any] | None = None
        self.error: str | None = None
        self.closed = False
        #: (stage, branch) -> the branch's latest progress and when it came.
        self._branches: dict[tuple[int, int], tuple[BranchProgress, float]] = {}
        self._training = [0, 0.0]  # steps and seconds of training seen live (for the ETA)
        self._thread: threading.Thread | None = None

    # -- the worker's side ----------------------------------------------------------

    def run_class(self, base: type[CurriculumRun]) -> type[CurriculumRun]:
        """``base`` (a trainer's curriculum run) with this session as curator and audience."""
        session = self

        class BrowserCurriculumRun(base):  # type: ignore[misc, valid-type]
            def start(self) -> None:
                super().start()
                if self.config.curator != BrowserCurator.name:
                    raise self.config.error(
                        f"curator {self.config.curator!r}: a browser session's curator is human"
                    )
                self.decided.curator = BrowserCurator(session, self.config.curator_context())
                session._attach(self)

            def branch_progress(self, progress: BranchProgress) -> None:
                session._hear(progress)

        BrowserCurriculumRun.__name__ = BrowserCurriculumRun.__qualname__ = (
            f"Browser{base.__name__}"
        )
        return BrowserCurriculumRun

    def start(self, body: Callable[[], RunResult]) -> threading.Thread:
        """Run ``body`` (a fresh or resumed run of :meth:`run_class`) in a daemon thread."""
        self._thread = threading.Thread(
            target=self._work, args=(body,), name="curation", daemon=True
        )
        self._thread.start()
        return self._thread

    def ask(self, question: Question) -> Any:
        """Post ``question`` and wait for the page's answer (the curator's side)."""
        with self._changed:
            self.question = question
            self.phase = "question"
            self._bump()
            while not question.answered:
                if self.closed:
                    raise CuratorError(
                        "the page's server stopped before the decision was made; the decisions"
                        " made so far are recorded: resume the run to go on"
                    )
                self._changed.wait(timeout=1.0)
            return question.answer

    def close(self) -> None:
        """Stop waiting for answers (the server is going away)."""
        with self._changed:
            self.closed = True
            self._changed.notify_all()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the worker to end; True if it has."""
        if self._thread is None:
            return True
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def wait_for(self, phase: str, timeout: float) -> bool:
        """Wait until the session is in ``phase`` (for tests and scripts); True if it is."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while self.phase != phase:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._changed.wait(timeout=left)
            return True

    def _attach(self, run: CurriculumRun) -> None:
        with self._changed:
            self.run = run
            if self.phase == "starting":
                self.phase = "training"
            self._bump()

    def _hear(self, progress: BranchProgress) -> None:
        now = time.monotonic()
        with self._changed:
            key = (progress.stage, progress.branch)
            previous = self._branches.get(key)
            if previous is not None and not previous[0].done:
                self._training[0] += progress.steps - previous[0].steps
                self._training[1] += now - previous[1]
            self._branches[key] = (progress, now)
            self._bump()

    def _work(self, body: Callable[[], RunResult]) -> None:
        try:
            result = body()
        except (AmazeError, OSError) as problem:
            self._fail(one_line(problem))
            return
        except Exception as problem:  # a bug: show it on the page and in the terminal
            traceback.print_exc(file=sys.stderr)
            self._fail(f"{type(problem).__name__}: {one_line(problem)}")
            return
        summary = result.summary
        files = sorted(
            str(path.relative_to(result.out))
            for name in result.outputs
            for path in result.out.glob(name.rstrip("/"))
            if path.is_file()
        )
        files += sorted(
            str(path.relative_to(result.out)) for path in result.out.glob("trajectories/*.png")
        )
        with self._changed:
            self.final = {
                "headline": result.headline,
                "figures": {name: summary.get(name) for name in FINAL_FIGURES},
                "files": files,
            }
            self.phase = "finished"
            self._bump()
        print(f"session finished: {result.headline}", file=sys.stderr, flush=True)

    def _fail(self, message: str) -> None:
        with self._changed:
            self.error = message
            self.phase = "failed"
            self._bump()
            if self.closed:  # the server stopped it: nothing went wrong
                return
        print(f"error: {message}", file=sys.stderr, flush=True)

    def _bump(self) -> None:
        self.version += 1
        self._changed.notify_all()

    # -- the page's side ------------------------------------------------------------

    def answer(self, question_id: Any, value: Any) -> None:
        """Take the page's answer to the question ``question_id``, checked.

        A stale answer (another tab answered first) raises :class:`AnswerError`
        with status 409; a bad one (no such branch, a bad maze) status 400,
        with one message per maze in ``details`` for a generate question.
        """
        with self._changed:
            question = self.question
            if question_id is None:
                raise AnswerError("the answer names no question")
            if question is None or question.id != question_id:
                raise AnswerError(
                    f"question {question_id!r} is not the one waiting for an answer"
                    f" ({question.id if question else 'none is'})",
                    status=409,
                )
            if question.kind == "select":
                answer = self._checked_branch(value, question)
            else:
                answer = self._checked_mazes(value, question)
            question.answer = answer
            question.answered = True
            # answered: the page shows training at once, whenever the worker wakes
            self.question = None
            self.phase = "training"
            self._bump()

    @staticmethod
    def _checked_branch(value: Any, question: Question) -> int:
        choices = ", ".join(map(str, question.choices))
        if value is None:
            raise AnswerError(f"the answer names no branch (one of {choices})")
        if isinstance(value, bool) or not isinstance(value, int) or value not in question.choices:
            raise AnswerError(f"branch {value!r} is not one of {choices}")
        return value

    @staticmethod
    def _checked_mazes(value: Any, question: Question) -> list[str]:
        if not isinstance(value, list) or len(value) != question.count:
            raise AnswerError(f"the answer must be a list of {question.count} maze strings")
        mazes: list[str] = []
        problems: list[str | None] = []
        for text in value:
            try:
                mazes.append(strict_maze(text).to_string())
                problems.append(None)
            except DesignError as problem:
                problems.append(str(problem))
        if any(problems):
            bad = sum(p is not None for p in problems)
            raise AnswerError(f"{bad} of the mazes cannot be built", details=problems)
        return mazes

    def state(self) -> dict[str, Any]:
        """Everything the page shows, as plain JSON."""
        with self._changed:
            question = self.question
            return {
                "version": self.version,
                "phase": self.phase,
                "run": {**self.description, "out": str(self.out)},
                "question": None
                if question is None
                else {
                    "id": question.id,
                    "kind": question.kind,
                    "stage": question.stage,
                    "waiting": round(time.time() - question.asked, 1),
                    **question.content,
                },
                "training": self._training_state(),
                "history": self._history(),
                "final": self.final,
                "error": self.error,
            }

    def _training_state(self) -> dict[str, Any]:
        rate = self._training[0] / self._training[1] if self._training[1] > 0 else None
        stage = max((s for s, _ in self._branches), default=None)
        branches = []
        for (s, branch), (progress, _) in sorted(self._branches.items()):
            if s != stage:
                continue
            left = None
            if progress.budget_steps and rate and not progress.done:
                left = max(0, progress.budget_steps - progress.steps) / rate
            branches.append(
                {
                    "branch": branch,
                    "steps": progress.steps,
                    "budget_steps": progress.budget_steps,
                    "done": progress.done,
                    "eta_seconds": None if left is None else round(left, 1),
                }
            )
        spent = sum(p.steps for p, _ in self._branches.values())
        budget = self.description.get("budget_steps")
        left = None
        if budget and rate:
            left = round(max(0, budget - spent) / rate, 1)
        return {
            "stage": stage,
            "branches": branches,
            "steps": spent,
            "budget_steps": budget,
            "steps_per_second": None if rate is None else round(rate),
            "eta_seconds": left,
        }

    def _history(self) -> dict[str, Any]:
        run = self.run
        if run is None:
            return {"decisions": [], "stages": []}
        decisions = [
            {
                "stage": d.stage,
                "kind": d.kind,
                "time": d.time,
                "seconds": round(d.seconds, 1),
                "choice": d.choice,
                "mazes": list(d.mazes or ()),
                "forced": d.forced,
                "replayed": d.replayed,
                "advisor": None if d.proposal is None else d.proposal.advisor,
                "accepted": list(d.accepted) if isinstance(d.accepted, tuple) else d.accepted,
            }
            for d in list(run.decided.recorded)
        ]
        stages = [
            {
                "stage": record.stage,
                "mazes": list(record.mazes),
                "selected": record.selected,
                "success": [round(c.success_rate, 3) for c in record.candidates],
                "normalized_reward": [round(c.normalized_reward, 3) for c in record.candidates],
            }
            for record in list(run.records)
        ]
        return {"decisions": decisions, "stages": stages}

    # -- what the server reads -------------------------------------------------------

    def records(self) -> list[Any]:
        """The finished stages so far (:class:`~amaze.curriculum.curators.StageRecord`)."""
        run = self.run
        return [] if run is None else list(run.records)

    def finished_branch(self, stage: int, branch: int) -> Path:
        """The folder of a finished branch of a finished stage (404 for any other).

        ``branch`` is checked against the stage's branches before any path is
        built from it, so that no number from a request reaches the file system.
        """
        mazes = self.stage_mazes(stage)
        folder = branch_folder(self.out, stage, branch)
        if not 0 <= branch < len(mazes) or not (folder / "result.json").is_file():
            raise AnswerError(f"stage {stage} has no finished branch {branch}", status=404)
        return folder

    def agent(self, stage: int, branch: int) -> Any:
        """The trained agent of a finished branch, loaded from its folder.

        A learner that cannot be read (damaged, tampered with, of another
        version) is a 409 naming the problem: trainers refuse such files with a
        ``ValueError`` (an :class:`~amaze.errors.AmazeError` subclass as a rule),
        whatever their format.
        """
        folder = self.finished_branch(stage, branch)
        run = self.run
        assert run is not None  # the stage is finished: the run is attached
        try:
            return run.load_learner(folder / "agent").agent()
        except (ValueError, OSError) as problem:
            raise AnswerError(
                f"this branch's agent cannot be read: {one_line(problem)}", status=409
            ) from None

    def stage_mazes(self, stage: int) -> list[str]:
        """The mazes of a finished stage (its record is written before its select question)."""
        for record in self.records():
            if record.stage == stage:
                return list(record.mazes)
        raise AnswerError(f"stage {stage} has no finished branches yet", status=404)
