"""The curriculum loop as a run: EDHuCAT (paper, Algorithm 1) for any trainer.

::

    a <- a new agent, trained on a trivial maze
    for stage 1 .. S-1:
        a <- select(candidates of the previous stage)      # the curator
        mazes <- generate(K)                               # the curator
        candidates <- K copies of a, each trained on one maze (its 4 rotations)
    return select(candidates of the last stage)            # the curator

:class:`CurriculumRun` is that loop on the shared run lifecycle
(:mod:`amaze.runs.lifecycle`); a trainer supplies its learner
(:class:`~amaze.curriculum.learner.Learner`) through :meth:`CurriculumRun.new_learner`
and :meth:`CurriculumRun.load_learner`, and a curator
(:mod:`amaze.curriculum.curators`) makes the decisions. The interpolation
regime is the same loop with the ``interpolation`` curator and one branch.

**Budget.** ``budget_steps`` env steps in all (and/or ``budget_seconds``
seconds, where the trainer's config has it, shared the same way by
:func:`~amaze.curriculum.regimes.branch_seconds`: a run on a seconds budget
depends on the machine's speed, so its replay is not identical), shared
between stages and branches by
:func:`~amaze.curriculum.regimes.branch_allowance` (the paper's
``budget / (K * S)`` per agent per stage, the steps a stage leaves unspent
handed on to the next ones). Branches of a stage are copies of the selected
agent, each with its own random stream (:func:`~amaze.curriculum.learner.branch_seed`).
A steps budget is a hard limit: a run whose first branch could not pay the
learner's smallest unit of training (:meth:`CurriculumRun.smallest_unit`: a
rollout, a generation on the trivial maze) is refused before its folder is
written, and a stage whose branches could not pay it is not played (the run
ends, its last stage's candidates compete for the final choice).

**Open-ended stages** (``stages`` 0, the ``edens`` regime's default): the
loop plays stages until the budget is spent (less than 1 % left), each
branch allowed an epoch of the budget (:mod:`amaze.curriculum.regimes`); a
stage whose branches converge early leaves its steps to more stages instead
of ending the run with its budget unspent. The final choice comes after the
last stage played.

**Rehearsal** (``rehearsal`` R; the ``edens`` regime's default is 7, the
paper's loop has none): a branch trains on its own maze and on the last R
distinct mazes of its lineage (the selected branches' own mazes, newest
first), each in its 4 rotations: a batch that grows with the curriculum and
keeps the agent from forgetting what the lineage learnt. It is evaluated as
before, on the stage's mazes and the validation mazes.

**Run folder** (besides ``config.json``, ``summary.json``, ``trajectories/``):

* ``decisions.jsonl``: every decision, one JSON object per line, appended
  (atomically) before the loop acts on it: ``stage``, ``kind`` (``generate``
  with the ``mazes``, canonical strings; ``select`` with the ``choice``, a
  branch index, and the ``candidates``' figures), the ``curator``'s name, the
  ``time`` (UTC, ISO 8601) and the ``seconds`` the decision took; ``forced``
  when there was one candidate, ``replayed`` when it came from another run;
* ``stages/stage-<s>/branch-<b>/``: ``agent/`` (the learner after its
  training, saved by the trainer), ``result.json`` (the candidate: mazes,
  results per maze and rotation on every maze of the stage, in branch order,
  lineage, steps,
  seconds, the ``training_mazes`` (its own and the rehearsed ones), and its
  results on the curator's validation mazes if it has any; written last, so
  a branch with a result is finished),
  ``trajectory.png`` (the agent on its maze) and, while it trains,
  ``checkpoint/`` (the learner mid-session);
* ``progress.csv``: one row per finished branch;
* ``curriculum.png``: the curriculum at a glance (stage x branch thumbnails
  with success and R̄, the selected branches and the lineage);
* ``progress.png``: the selected branches' success (own maze, the stage's
  mazes, validation mazes) and their mazes' difficulty against env steps.

**Resume and replay.** The folder is the loop's state: a resumed run reads
the decisions already made (a human is never asked twice), skips the
finished branches, continues the branch in training from its checkpoint,
and goes on. ``--replay RUN_DIR`` starts a new run with RUN_DIR's config and
its decisions (copied to ``replay.jsonl``) in place of the curator: with a
deterministic trainer (evolution) it reaches the same agents, bit for bit.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import shutil
import time
from abc import abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, ClassVar

from amaze.agents.trajectories import save_trajectory_png
from amaze.curriculum.coevolution import CoevolutionError, MazePopulationConfig
from amaze.curriculum.curators import (
    Candidate,
    Curator,
    CuratorContext,
    CuratorError,
    History,
    MazeResults,
    StageRecord,
    check_mazes,
    curator_names,
    make_curator,
)
from amaze.curriculum.interpolation import MAX_STAGES
from amaze.curriculum.learner import Learner, branch_seed
from amaze.curriculum.regimes import (
    CURRICULUM_REGIMES,
    MAX_OPEN_STAGES,
    OPEN_EPOCHS,
    OPEN_STAGES,
    REGIMES,
    branch_allowance,
    branch_seconds,
    curriculum_over,
)
from amaze.evaluation.policy import record_episode
from amaze.evaluation.protocol import Evaluator
from amaze.evaluation.suite import PAPER_TRAINING_MAZE
from amaze.maze import rotations
from amaze.maze.spec import MazeSpec
from amaze.runs.config import RunConfig, option
from amaze.runs.folder import read_text, write_bytes, write_json
from amaze.runs.lifecycle import SPENT_ENOUGH, Run
from amaze.runs.progress import Progress
from amaze.validation import check_integer, check_number, parse_json

__all__ = [
    "DECISIONS_FILE",
    "MAX_BRANCHES",
    "BranchProgress",
    "CurriculumConfig",
    "CurriculumRun",
    "Decision",
    "DecisionLog",
    "branch_folder",
]

DECISIONS_FILE = "decisions.jsonl"
REPLAY_FILE = "replay.jsonl"
#: Most branches per stage.
MAX_BRANCHES = 64
#: About the side, in pixels, of a branch's trajectory picture.
PICTURE_SIDE = 320
#: The default numbers of stages and branches (the paper's S and K; EDEnS: open-ended).
DEFAULT_STAGES = {"edhucat": 10, "interpolation": 10, "edens": OPEN_STAGES}
DEFAULT_BRANCHES = {"edhucat": 3, "interpolation": 1, "edens": 3}
DEFAULT_CURATOR = {"edhucat": "careful", "interpolation": "interpolation", "edens": "edens"}
#: The default rehearsal: earlier lineage mazes a branch also trains on (the paper: none).
DEFAULT_REHEARSAL = {"edhucat": 0, "interpolation": 0, "edens": 7}
#: Most rehearsed mazes.
MAX_REHEARSAL = 64
PROGRESS_FIELDS = (
    "branches",
    "stage",
    "branch",
    "steps",
    "seconds",
    "success",
    "rbar",
    "converged",
    "maze",
)


@dataclass
class CurriculumConfig(RunConfig):
    """The regime fields of a trainer's config (``regime``, ``curator``, ``stages``...).

    Each field acts in some regimes (its ``regimes``, :func:`~amaze.runs.config.option`):
    set in another one, it is refused. In the direct regime ``curator``,
    ``stages`` and ``branches`` stay unset; in a curriculum regime
    :meth:`validate` fills them with the regime's defaults, so ``config.json``
    records what ran; in the direct regime it fills ``agent_rule`` and
    ``eval_mazes`` with the trainer's defaults.
    """

    #: The regimes this trainer runs: the direct and curriculum ones; a trainer
    #: with a loop of its own for another regime (``coevolution``) adds it.
    supported_regimes: ClassVar[tuple[str, ...]] = ("direct", *CURRICULUM_REGIMES)
    #: The trainer's default ``epochs`` of an open-ended curriculum.
    default_epochs: ClassVar[int] = OPEN_EPOCHS
    #: The rules that may choose a direct run's agent, the trainer's default first.
    agent_rules: ClassVar[tuple[str, ...]] = ("final", "best-eval")
    #: The evaluation mazes of a direct run when the config gives none.
    default_eval_mazes: ClassVar[tuple[str, ...]] = ()

    regime: str = option("direct", "training regime", choices=REGIMES)
    curator: str | None = option(
        None,
        "who selects agents and generates mazes in the edhucat regime: careful, moderate,"
        " risky, random, edens, human, interpolation or a plug-in's name (default: careful)",
        metavar="NAME",
        regimes=CURRICULUM_REGIMES,
    )
    stages: int | None = option(
        None,
        "curriculum stages S, the trivial first one included; 0: open-ended, stages until"
        " the budget is spent (default: 10; 0 for edens)",
        metavar="S",
        regimes=CURRICULUM_REGIMES,
    )
    branches: int | None = option(
        None,
        "branches K per stage (default: 3 for edhucat and edens, 1 for interpolation)",
        metavar="K",
        regimes=CURRICULUM_REGIMES,
    )
    epochs: int | None = option(
        None,
        "an open-ended curriculum's epochs: each branch may spend budget / (K * epochs)"
        " (default: 100 for evolution, 10 for RL)",
        metavar="E",
        regimes=CURRICULUM_REGIMES,
    )
    rehearsal: int | None = option(
        None,
        "earlier mazes of the lineage each branch also trains on, besides its own"
        " (default: 7 for edens, 0 otherwise)",
        metavar="R",
        regimes=CURRICULUM_REGIMES,
    )
    target: str = option(
        PAPER_TRAINING_MAZE,
        "the maze a curriculum or a co-evolution leads to (interpolation's end, the"
        " curators' target, the family of the co-evolved mazes)",
        metavar="MAZE",
        regimes=(*CURRICULUM_REGIMES, "coevolution"),
    )
    mazes: list[str] = option(
        default_factory=lambda: [PAPER_TRAINING_MAZE],
        help="training mazes of the direct regime, each played in its 4 rotations"
        " (default: the paper's)",
        regimes=("direct",),
    )
    eval_mazes: list[str] | None = option(
        None,
        "mazes a direct run evaluates its agent on as it trains, 4 rotations each"
        " (default: the paper's evaluation maze for RL, none for evolution)",
        regimes=("direct",),
    )
    agent_rule: str | None = option(
        None,
        "which agent a direct run hands over: final (the agent when training stops),"
        " best-eval (the best on eval_mazes among the evaluations), best-fitness"
        " (evolution: the best training fitness) (default: final for RL, best-fitness"
        " for evolution; curricula hand over the curator's final choice, co-evolution"
        " the best on its validation mazes)",
        metavar="RULE",
        regimes=("direct",),
    )
    final_training: bool = option(
        True,
        "spend what the stages leave of the budget on the final agent, trained on its"
        " lineage's mazes (off: the paper's protocol, the final choice as it is)",
        regimes=CURRICULUM_REGIMES,
    )
    curator_options: dict[str, Any] = option(
        default_factory=dict,
        help="the curator's own options",
        command_line=False,
        regimes=CURRICULUM_REGIMES,
    )
    replay: str | None = option(
        None,
        "the run whose recorded decisions this run replays",
        command_line=False,
        regimes=CURRICULUM_REGIMES,
    )
    coevolution: dict[str, Any] = option(
        default_factory=dict,
        help="the maze population's options in the coevolution regime (MazePopulationConfig)",
        command_line=False,
        regimes=("coevolution",),
    )

    @property
    def is_curriculum(self) -> bool:
        """True for the regimes the curriculum loop plays."""
        return self.regime in CURRICULUM_REGIMES

    @property
    def open_ended(self) -> bool:
        """True for a curriculum whose stages go on until the budget is spent."""
        return self.is_curriculum and self.stages == OPEN_STAGES

    def validate(self) -> CurriculumConfig:
        """Check the regime fields (and the shared ones); fill a curriculum's defaults."""
        super().validate()
        if self.regime not in self.supported_regimes:
            known = "is not run by this trainer" if self.regime in REGIMES else "is unknown"
            raise self.error(
                f"regime {self.regime!r} {known} (choose from {', '.join(self.supported_regimes)})"
            )
        self.refuse_options_without_effect(self.regime)  # before anything is normalised
        if self.regime != "direct":
            self.target = self._maze("target", self.target)
        self.mazes = self._maze_list("mazes", self.mazes)
        if self.eval_mazes is not None:
            self.eval_mazes = self._maze_list("eval_mazes", self.eval_mazes, empty=True)
        self._check_coevolution()
        if self.regime == "direct":
            self._direct_defaults()
        if not self.is_curriculum:
            return self
        if self.curator is None:
            self.curator = DEFAULT_CURATOR[self.regime]
        own = DEFAULT_CURATOR[self.regime]
        if self.regime != "edhucat" and self.curator != own:
            raise self.error(
                f"curator {self.curator!r}: the {self.regime} regime's curator is {own}"
                " (use --regime edhucat for another curator)"
            )
        if not isinstance(self.curator, str) or self.curator not in curator_names():
            raise self.error(
                f"unknown curator {self.curator!r} (choose from {', '.join(curator_names())})"
            )
        if self.stages is None:
            self.stages = DEFAULT_STAGES[self.regime]
        if self.branches is None:
            self.branches = DEFAULT_BRANCHES[self.regime]
        if self.rehearsal is None:
            self.rehearsal = DEFAULT_REHEARSAL[self.regime]
        self.stages = check_integer(
            "stages", self.stages, minimum=0, maximum=MAX_STAGES, error=self.error
        )
        if self.regime == "interpolation" and self.stages < 2:
            raise self.error(
                f"stages {self.stages}: an interpolation has a fixed number of stages, 2 or"
                " more (its first maze and its target)"
            )
        if self.stages != OPEN_STAGES and self.epochs is not None:
            raise self.error(
                f"epochs {self.epochs!r} is for open-ended curricula (stages 0), not"
                f" {self.stages} stages"
            )
        if self.stages == OPEN_STAGES:
            if self.epochs is None:
                self.epochs = self.default_epochs
            self.epochs = check_integer(
                "epochs", self.epochs, minimum=1, maximum=MAX_OPEN_STAGES, error=self.error
            )
        self.rehearsal = check_integer(
            "rehearsal", self.rehearsal, minimum=0, maximum=MAX_REHEARSAL, error=self.error
        )
        self.branches = check_integer(
            "branches", self.branches, minimum=1, maximum=MAX_BRANCHES, error=self.error
        )
        if not isinstance(self.curator_options, dict):
            raise self.error(f"curator_options {self.curator_options!r} is not a JSON object")
        if self.replay is not None and not isinstance(self.replay, str):
            raise self.error(f"replay {self.replay!r} is not a run folder")
        return self

    def _maze(self, name: str, value: Any) -> str:
        """``value``'s canonical maze string; the config's error naming ``name`` otherwise."""
        try:
            return MazeSpec.from_string(str(value)).to_string()
        except ValueError as problem:
            raise self.error(f"{name} {value!r}: {problem}") from None

    def _maze_list(self, name: str, value: Any, empty: bool = False) -> list[str]:
        """A list of maze strings, each checked (a comma-separated string is split).

        The strings are kept as given (``config.json`` records what the user
        wrote; the trainers parse them).
        """
        if isinstance(value, str):
            value = [m.strip() for m in value.split(",") if m.strip()]
        if not isinstance(value, list) or (not value and not empty):
            raise self.error(f"{name} {value!r} is not a non-empty list of maze strings")
        for maze in value:
            self._maze(name, maze)
        return list(value)

    def _direct_defaults(self) -> None:
        """A direct run's agent rule and evaluation mazes: the config's or the trainer's."""
        if self.agent_rule is None:
            self.agent_rule = self.agent_rules[0]
        if self.agent_rule not in self.agent_rules:
            raise self.error(
                f"agent_rule {self.agent_rule!r} is not one of {', '.join(self.agent_rules)}"
            )
        if self.eval_mazes is None:
            self.eval_mazes = list(self.default_eval_mazes)
        if self.agent_rule == "best-eval" and not self.eval_mazes:
            raise self.error("agent_rule 'best-eval' needs eval_mazes (--eval-mazes A,B,...)")

    @classmethod
    def adjust_command_line(cls, data: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
        """``--budget-seconds`` without ``--budget-steps`` is a wall-clock budget alone.

        (A trainer's default ``budget_steps`` would otherwise limit it too.) A
        ``--config`` file that sets ``budget_steps`` keeps it: both budgets apply.
        """
        if getattr(args, "budget_seconds", None) is not None and args.budget_steps is None:
            data.setdefault("budget_steps", None)
        return data

    def _check_coevolution(self) -> None:
        """``coevolution`` is a valid maze population config, and only in that regime."""
        if not isinstance(self.coevolution, dict):
            raise self.error(f"coevolution {self.coevolution!r} is not a JSON object")
        if self.regime != "coevolution":
            if self.coevolution:
                raise self.error(
                    f"coevolution options {self.coevolution!r} are for the coevolution regime,"
                    f" not {self.regime}"
                )
            return
        try:
            MazePopulationConfig.from_dict(self.coevolution)
        except CoevolutionError as problem:
            raise self.error(str(problem)) from None

    def curator_context(self) -> CuratorContext:
        """What the curator is built from."""
        assert self.stages is not None and self.branches is not None
        return CuratorContext(
            target=self.target,
            seed=self.seed,
            stages=self.stages,
            branches=self.branches,
            robot=self.robot,
            options=dict(self.curator_options),
        )


@dataclass(frozen=True)
class BranchProgress:
    """How far a branch's training is, as :meth:`CurriculumRun.branch_progress` hears it."""

    stage: int
    branch: int
    #: Env steps the branch has spent in its session so far.
    steps: int
    #: Its allowance: env steps and/or seconds (``None``: no limit of that kind).
    budget_steps: int | None
    budget_seconds: float | None
    #: True once the branch is finished (trained, evaluated, its result written).
    done: bool = False


# -- decisions ------------------------------------------------------------------------


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
        return data


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


# -- the run --------------------------------------------------------------------------


#: A branch folder, relative to the run folder.
_BRANCH_FOLDER = re.compile(r"stages/stage-(0|[1-9][0-9]*)/branch-(0|[1-9][0-9]*)")
#: What a branch in training records when it starts (its ``checkpoint/`` continues only that).
BRANCH_FILE = "branch.json"
#: The folder of the final training (``final_training``), relative to the run folder.
FINAL_FOLDER = "stages/final"


def branch_folder(out: Path, stage: int, branch: int) -> Path:
    """Where the loop keeps a branch of the run in ``out``: ``stages/stage-<s>/branch-<b>``."""
    return Path(out) / "stages" / f"stage-{stage}" / f"branch-{branch}"


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _maze_results(evaluator: Evaluator, agent: Any, mazes: Sequence[str]) -> list[MazeResults]:
    """``agent`` on ``mazes``, each in its 4 rotations (``evaluator`` holds those, in order)."""
    episodes = evaluator.evaluate(agent).episodes
    return [
        MazeResults(
            maze=maze,
            success=tuple(e.success for e in episodes[4 * index : 4 * index + 4]),
            paper_reward=tuple(e.paper_reward for e in episodes[4 * index : 4 * index + 4]),
            steps=tuple(e.steps for e in episodes[4 * index : 4 * index + 4]),
        )
        for index, maze in enumerate(mazes)
    ]


def _count(data: Mapping[str, Any], key: str) -> int:
    """``data[key]``, a non-negative integer (``ValueError`` otherwise)."""
    return check_integer(key, data[key], minimum=0)


def _candidate_from_dict(data: Mapping[str, Any], folder: Path) -> Candidate:
    """A candidate read from ``result.json`` (any missing, ill-typed or impossible value raises)."""
    if not isinstance(data["mazes"], list) or len(data["mazes"]) != 1:
        raise ValueError(f"mazes {data['mazes']!r} is not a list of one maze")
    mazes = tuple(str(m) for m in data["mazes"])
    results = [MazeResults.from_dict(r) for r in data["results"]]
    branch = int(data["branch"])  # results come in branch order: two branches may share a maze
    if not 0 <= branch < len(results) or results[branch].maze not in mazes:
        raise ValueError(f"branch {branch} has no results of its own maze")
    lineage = tuple(check_integer("lineage", b, minimum=0) for b in data["lineage"])
    stage = _count(data, "stage")
    if len(lineage) != stage + 1 or lineage[-1] != branch:
        raise ValueError(f"lineage {list(lineage)} is not that of branch {branch} of stage {stage}")
    env_steps, lineage_steps = _count(data, "env_steps"), _count(data, "lineage_steps")
    if lineage_steps < env_steps:
        raise ValueError(f"lineage_steps {lineage_steps} is less than env_steps {env_steps}")
    if not isinstance(data["converged"], bool):
        raise ValueError(f"converged {data['converged']!r} is not true or false")
    time = data.get("time", {})
    if not isinstance(time, dict):
        raise ValueError(f"time {time!r} is not an object")
    for part, seconds in time.items():
        check_number(f"time {part}", seconds, minimum=0)
    return Candidate(
        stage=stage,
        branch=branch,
        mazes=mazes,
        own=(results[branch],),
        others=tuple(r for i, r in enumerate(results) if i != branch),
        lineage=lineage,
        env_steps=env_steps,
        seconds=check_number("seconds", data["seconds"], minimum=0),
        converged=data["converged"],
        lineage_steps=lineage_steps,
        pictures=tuple(folder / str(p) for p in data.get("pictures", [])),
        validation=tuple(MazeResults.from_dict(r) for r in data.get("validation", [])),
    )


def _candidate_to_dict(candidate: Candidate, results: Sequence[MazeResults]) -> dict[str, Any]:
    return {
        "stage": candidate.stage,
        "branch": candidate.branch,
        "mazes": list(candidate.mazes),
        "results": [r.to_dict() for r in results],
        "lineage": list(candidate.lineage),
        "env_steps": candidate.env_steps,
        "seconds": round(candidate.seconds, 3),
        "converged": candidate.converged,
        "lineage_steps": candidate.lineage_steps,
        "pictures": [p.name for p in candidate.pictures],
        "validation": [r.to_dict() for r in candidate.validation],
        "success_rate": candidate.success_rate,
        "mean_reward": candidate.mean_reward,
    }


class CurriculumRun(Run):
    """The curriculum loop of a trainer; subclasses supply the trainer's learner."""

    progress_fields = PROGRESS_FIELDS
    progress_text_fields = ("converged", "maze")
    position_field = "branches"
    checkpoint_files = ()
    outputs: ClassVar[tuple[str, ...]] = (
        "summary.json",
        "decisions.jsonl",
        "curriculum.png",
        "progress.png",
        "stages/",
        "progress.csv",
    )
    config: Any  # a CurriculumConfig subclass with budget_steps (and maybe budget_seconds)

    def __init__(self, out: Any, config: Any) -> None:
        super().__init__(out, config)
        self.decisions = DecisionLog(self.out / DECISIONS_FILE)
        self.recorded: list[Decision] = []
        self.replayed: list[Decision] = []
        self.curator: Curator | None = None
        self.records: list[StageRecord] = []
        self.final: Candidate | None = None
        #: The final agent trained on its lineage's mazes (``final_training``), if it was.
        self.finishing: Candidate | None = None
        #: Why the loop played no more stages, when a budget ended it.
        self.ended_because = ""
        #: What shows the loop's progress while it trains.
        self.shown: Progress | None = None
        #: The curator's validation mazes and their evaluator, if it has any.
        self.validation: tuple[Evaluator, list[str]] | None = None

    # -- the trainer's part ---------------------------------------------------

    @abstractmethod
    def new_learner(self, seed: int) -> Learner:
        """A fresh learner for the run's robot and options, drawing from ``seed``."""

    @abstractmethod
    def load_learner(self, folder: Path) -> Learner:
        """The learner saved in ``folder``; a damaged one raises the config's error naming it."""

    def learner_figures(self) -> dict[str, Any]:
        """The trainer's entries of ``summary.json`` (algorithm, robot...)."""
        return {}

    def smallest_unit(self) -> tuple[int, str]:
        """The env steps of the learner's smallest unit of training, and what that unit is.

        A rollout for RL, a generation on the trivial first maze for
        evolution: a branch allowed fewer steps could not train at all, so the
        loop plays no stage whose branches it would give fewer (the trainer's
        learner itself never starts a unit its session cannot pay).
        """
        return 1, "one env step"

    def branch_progress(self, progress: BranchProgress) -> None:
        """Hear how far the branch in training is (a live display overrides this).

        Called when a branch starts (0 steps), after every generation or
        rollout of its training, and when it is finished (``done``; also for
        the branches a resumed run finds finished). It runs in the loop's
        thread: it must return quickly.
        """

    # -- the lifecycle's hooks --------------------------------------------------

    @classmethod
    def replay_config(cls, source: Path, config: RunConfig) -> RunConfig:
        """``source``'s config, marked as a replay of ``source``, once its decisions check."""
        c: Any = config
        if not c.is_curriculum:
            return super().replay_config(source, config)
        decisions = DecisionLog(source / DECISIONS_FILE).read(c.stages, c.branches, c.error)
        if c.open_ended:
            # Its length depends on the budget: a finished run wrote its summary.
            if not (source / "summary.json").exists() or not decisions:
                raise c.error(
                    f"{str(source)!r} is an unfinished open-ended run with {len(decisions)}"
                    " decisions (resume it first)"
                )
        elif len(decisions) < len(decision_sequence(c.stages)):
            raise c.error(
                f"{str(source)!r} holds {len(decisions)} of the {2 * c.stages} decisions of its"
                " run (it is unfinished: resume it first)"
            )
        return dataclasses.replace(c, replay=str(source))

    def start(self) -> None:
        """Build the curator (a bad name or plug-in fails here) and read a replay's decisions.

        A steps budget that cannot give the first branch the learner's
        smallest unit of training is refused here too, before anything is written.
        """
        c = self.config
        self._check_budget()
        self.curator = self._curator_call(
            "being built", lambda: make_curator(c.curator, c.curator_context())
        )
        validation = self._curator_call(
            "giving its validation mazes",
            lambda: list(getattr(self.curator, "validation", None) or ()),
        )
        if validation:
            validation = self._curator_call(
                "giving its validation mazes",
                lambda: check_mazes(validation, len(validation), c.curator),
            )
        self.validation = (
            (Evaluator(c.robot, rotations(validation), inputs=False), validation)
            if validation
            else None
        )
        if c.replay is not None:
            # The run's own copy once it has one (the replayed run may be gone since).
            copy = DecisionLog(self.out / REPLAY_FILE)
            if copy.path.exists():
                self.replayed = copy.read(c.stages, c.branches, c.error, "replayed decisions")
            else:
                source = DecisionLog(Path(c.replay) / DECISIONS_FILE)
                self.replayed = source.read(c.stages, c.branches, c.error)

    def restore(self) -> int | None:
        """Check every file the resumed loop will read; count the finished branches.

        The decisions (and a replay's), every finished branch's result, that
        the results agree with the decisions (each branch of the maze its
        stage's generate decision gave it, descending from the branch the
        select decision chose), and every learner the loop and the summary
        will load: the finished branches' agents and the checkpoint of a
        branch in training. Anything wrong is refused here, by name, before
        training goes on.
        """
        c = self.config
        self.start()
        self.recorded = self.decisions.read(c.stages, c.branches, c.error)
        finished: dict[tuple[int, int], Candidate] = {}
        for folder in self._branch_folders():
            if (folder / "result.json").exists():
                candidate = self._read_candidate(folder)
                finished[candidate.stage, candidate.branch] = candidate
        for candidate in finished.values():
            self._check_against_decisions(candidate, finished)
        final = self.out / FINAL_FOLDER
        for folder in [*self._branch_folders(), final]:
            has_result = (folder / "result.json").exists()
            if folder == final and has_result:
                self._read_candidate(final, len(self._stages_of(finished)), 0)
            if has_result or (folder / "checkpoint").exists():
                self.load_learner(folder / ("agent" if has_result else "checkpoint"))
        return len(finished) + (final / "result.json").exists() or None

    @staticmethod
    def _stages_of(finished: Mapping[tuple[int, int], Candidate]) -> set[int]:
        """The stages of which ``finished`` holds a branch."""
        return {stage for stage, _ in finished}

    def _branch_folders(self) -> list[Path]:
        """The folders ``stages/stage-<s>/branch-<b>`` (other names are not the loop's)."""
        folders = []
        for folder in self.out.glob("stages/stage-*/branch-*"):
            if _BRANCH_FOLDER.fullmatch(folder.relative_to(self.out).as_posix()):
                folders.append(folder)
        return sorted(folders, key=lambda f: (int(f.parent.name[6:]), int(f.name[7:])))

    def _check_against_decisions(
        self, candidate: Candidate, finished: Mapping[tuple[int, int], Candidate]
    ) -> None:
        """A finished branch agrees with the decisions recorded before it was trained."""
        c, stage, branch = self.config, candidate.stage, candidate.branch
        where = repr(str(self._branch_folder(candidate) / "result.json"))
        recorded = self.recorded
        generate = decision_index(stage, "generate")
        mazes = recorded[generate].mazes if generate < len(recorded) else None
        if mazes is None or branch >= len(mazes) or candidate.mazes != (mazes[branch],):
            raise c.error(
                f"branch result {where} is of maze {candidate.mazes[0]!r}, which"
                f" {str(self.decisions.path)!r} does not give branch {branch} of stage {stage}"
            )
        if stage == 0:
            return
        select = decision_index(stage, "select")
        choice = recorded[select].choice if select < len(recorded) else None
        parent = finished.get((stage - 1, choice)) if choice is not None else None
        if parent is None or candidate.lineage[:-1] != parent.lineage:
            raise c.error(
                f"branch result {where} descends from lineage {list(candidate.lineage[:-1])},"
                f" but {str(self.decisions.path)!r} chose branch {choice} of stage {stage - 1}"
                + ("" if parent is None else f" (lineage {list(parent.lineage)})")
            )
        if candidate.lineage_steps != parent.lineage_steps + candidate.env_steps:
            raise c.error(
                f"branch result {where}: lineage_steps {candidate.lineage_steps} is not its"
                f" parent's {parent.lineage_steps} plus its env_steps {candidate.env_steps}"
            )

    def train(self, progress: str) -> None:
        """The loop (see the module docstring), skipping what the folder says is done."""
        c = self.config
        if self.replayed and not (self.out / REPLAY_FILE).exists():
            text = "".join(json.dumps(d.to_dict(), sort_keys=True) + "\n" for d in self.replayed)
            write_bytes(self.out / REPLAY_FILE, text.encode("utf-8"))
        self.records = []
        budget_seconds = getattr(c, "budget_seconds", None)
        total, unit = (c.budget_steps, "steps") if c.budget_steps else (budget_seconds, "s")
        desc = f"{c.regime} {c.curator} seed {c.seed}"
        with Progress(total, unit, desc, mode=progress) as self.shown:
            stage = 0
            while not self._over(stage):
                self.records.append(self._stage(stage))
                stage += 1
            self.final = self._select(stage)
            self._final_training(self.final)

    def _stage(self, stage: int) -> StageRecord:
        """Play ``stage``: its decisions (or the recorded ones), then each of its branches."""
        c = self.config
        parent: Candidate | None = None
        if stage == 0:
            trivial = [c.curator_context().trivial_maze()]
            mazes = self._decide(0, "generate", lambda: trivial)
        else:
            parent = self._select(stage)
            history = History(stage=stage, parent=parent, stages=tuple(self.records))
            mazes = self._decide(stage, "generate", lambda: self._generate(history))
        allowance = self._allowance(stage)
        evaluator = Evaluator(c.robot, rotations(mazes), inputs=False)
        lineage = self._lineage_mazes()
        candidates: list[Candidate] = []
        for branch in range(len(mazes)):
            own = mazes[branch]
            rehearsed = [maze for maze in lineage if maze != own][: c.rehearsal]
            steps_before = self._steps(candidates)
            training = [own, *rehearsed]
            candidate = self._branch(
                stage, branch, mazes, training, parent, allowance, evaluator, steps_before
            )
            candidates.append(candidate)
        return StageRecord(stage, tuple(mazes), tuple(candidates))

    def _allowance(self, stage: int) -> tuple[int | None, float | None]:
        """What each branch of ``stage`` may spend: env steps and/or seconds (``None``: none)."""
        c = self.config
        budget_seconds = getattr(c, "budget_seconds", None)
        steps = seconds = None
        if c.budget_steps is not None:
            steps = branch_allowance(
                c.budget_steps, self._steps(), stage, c.stages, c.branches, c.epochs
            )
        if budget_seconds is not None:
            seconds = branch_seconds(
                budget_seconds, self._seconds(), stage, c.stages, c.branches, c.epochs
            )
        return steps, seconds

    def final_agent(self) -> Any:
        assert self.final is not None
        return self.load_learner(self._final_folder() / "agent").agent()

    def _final_folder(self) -> Path:
        """The folder of the agent the run hands over: its final training's or final choice's."""
        assert self.final is not None
        if self.finishing is not None:
            return self.out / FINAL_FOLDER
        return self._branch_folder(self.final)

    def agent_figures(self) -> dict[str, Any]:
        assert self.final is not None
        last = self.finishing or self.final
        done = [k for record in self.records for k in record.candidates]
        found = sum(k.env_steps for k in done if (k.stage, k.branch) <= (last.stage, last.branch))
        rule = f"the curator's final choice ({self.config.curator})"
        if self.finishing is not None:
            rule += ", then trained on its lineage's mazes"
            found += self.finishing.env_steps
        untrained = last.lineage_steps == 0
        return {"agent_rule": rule, "agent_steps": found, "agent_untrained": untrained}

    def stop_reason(self) -> str:
        c = self.config
        if self.ended_because:
            return self.ended_because
        if self.finishing is not None and self.finishing.converged:
            return (
                "the final agent converged on its lineage's mazes (every episode optimal) after"
                f" {self.finishing.env_steps:,} steps of final training"
            )
        converged = sum(k.converged for record in self.records for k in record.candidates)
        played = sum(len(record.candidates) for record in self.records)
        why = f"every stage played, {converged} of {played} branches converged early"
        if not c.final_training:
            why += "; final_training is off"
        return why

    def figures(self) -> dict[str, Any]:
        c = self.config
        budget_seconds = getattr(c, "budget_seconds", None)
        assert self.final is not None
        stages = []
        for record in self.records:
            chosen = record.candidates[record.selected] if record.selected is not None else None
            stages.append(
                {
                    "stage": record.stage,
                    "mazes": list(record.mazes),
                    "selected": record.selected,
                    "success_rate": None if chosen is None else chosen.success_rate,
                    "mean_reward": None if chosen is None else chosen.mean_reward,
                    "env_steps": sum(candidate.env_steps for candidate in record.candidates),
                }
            )
        return {
            **self.learner_figures(),
            "robot": c.robot,
            "seed": c.seed,
            "regime": c.regime,
            "curator": c.curator,
            "stages": c.stages,
            "stages_played": len(self.records),
            "branches": c.branches,
            "epochs": c.epochs,
            "rehearsal": c.rehearsal,
            "target": c.target,
            "replay_of": c.replay,
            "budget_steps": c.budget_steps,
            "budget_seconds": budget_seconds,
            "env_steps": self._steps(),
            "seconds": round(self._seconds(), 3),
            "time": self._time_spent(),
            "final_lineage": list(self.final.lineage),
            "final_mazes": list(self.final.mazes),
            "final_training": None
            if self.finishing is None
            else {
                "mazes": list(self._lineage_mazes()),
                "env_steps": self.finishing.env_steps,
                "converged": self.finishing.converged,
                "success_rate": self.finishing.success_rate,
                "mean_reward": self.finishing.mean_reward,
            },
            "curriculum": stages,
        }

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        """The final agent in the 4 rotations of the target maze."""
        mazes = rotations(self.config.target)
        return [(f"target-rotation-{index}", maze) for index, maze in enumerate(mazes)]

    def extra_outputs(self) -> None:
        from amaze.curriculum.picture import save_curriculum_png, save_curriculum_progress

        save_curriculum_png(self.records, self.out / "curriculum.png", title=self._title())
        save_curriculum_progress(
            self.records, self.config.target, self.out / "progress.png", title=self._title()
        )

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        played = summary.get("stages_played", summary["stages"])
        stages = f"{played} stages" + (" (open-ended)" if summary["stages"] == OPEN_STAGES else "")
        lineage = summary["final_lineage"]
        if len(lineage) > 12:
            lineage = (
                f"[{', '.join(map(str, lineage[:3]))}, ... {', '.join(map(str, lineage[-3:]))}]"
            )
        return (
            f"{summary['regime']} ({summary['curator']}, {stages} x"
            f" {summary['branches']} branches), final lineage {lineage};"
            f" {super().headline(summary)}"
        )

    # -- the loop's own ---------------------------------------------------------

    def _title(self) -> str:
        c = self.config
        stages = "open-ended stages" if c.open_ended else f"{c.stages} stages"
        return f"{c.regime} / {c.curator}, seed {c.seed}: {stages} x {c.branches}"

    def _check_budget(self) -> None:
        """Refuse a steps budget whose first branch could not pay the smallest unit of training."""
        c = self.config
        if c.budget_steps is None:
            return
        unit, what = self.smallest_unit()
        allowance = branch_allowance(c.budget_steps, 0, 0, c.stages, c.branches, c.epochs)
        if allowance >= unit:
            return
        if c.open_ended:
            shares, count = f"{c.branches} branches x {c.epochs} epochs", c.branches * c.epochs
        else:
            shares, count = f"{c.branches} branches x {c.stages} stages", c.branches * c.stages
        raise c.error(
            f"budget_steps {c.budget_steps} gives each branch {allowance} steps"
            f" ({c.budget_steps} / ({shares})), less than {what} ({unit} steps): give"
            f" budget_steps >= {unit * count}, or fewer stages, branches or epochs"
        )

    def _over(self, stage: int) -> bool:
        """True when the loop plays no ``stage``: it played all of them, or spent its budget.

        Spent means: as :func:`~amaze.curriculum.regimes.curriculum_over` says,
        or the stage's branches would be allowed fewer steps than the
        learner's smallest unit of training.
        """
        c = self.config
        spent = [
            (c.budget_steps, self._steps()),
            (getattr(c, "budget_seconds", None), self._seconds()),
        ]
        if curriculum_over(stage, c.stages, spent):
            return True
        if c.budget_steps is None or stage == 0:
            return False
        allowance = branch_allowance(
            c.budget_steps, self._steps(), stage, c.stages, c.branches, c.epochs
        )
        unit, what = self.smallest_unit()
        if allowance >= unit:
            return False
        self.ended_because = (
            f"stage {stage}'s branches would be allowed {allowance:,} steps, less than {what}"
            f" ({unit:,} steps)"
        )
        return True

    def _lineage_mazes(self) -> list[str]:
        """The own mazes of the selected branches so far, newest first, each once."""
        mazes: list[str] = []
        for record in reversed(self.records):
            if record.selected is not None:
                maze = record.candidates[record.selected].mazes[0]
                if maze not in mazes:
                    mazes.append(maze)
        return mazes

    def _steps(self, current: Sequence[Candidate] = ()) -> int:
        """Env steps of every finished branch (and of ``current``, the stage in progress)."""
        done = sum(k.env_steps for record in self.records for k in record.candidates)
        finishing = self.finishing.env_steps if self.finishing is not None else 0
        return done + finishing + sum(k.env_steps for k in current)

    def _generate(self, history: History) -> list[str]:
        assert self.curator is not None
        curator = self.curator
        return self._curator_call(
            "generating mazes", lambda: curator.generate(self.config.branches, history)
        )

    def _curator_call(self, doing: str, call: Callable[[], Any]) -> Any:
        """``call()``, a call into the curator: whatever it raises is the config's error.

        A curator may be a plug-in: its exceptions (an ``OSError``, a bug, even
        ``SystemExit``) end the run with one line naming the curator and what
        it was doing, never a traceback or an exit status that hides the failure.
        """
        name = self.config.curator
        try:
            return call()
        except KeyboardInterrupt:
            raise
        except CuratorError as problem:
            raise self.config.error(str(problem)) from None
        except (Exception, SystemExit) as problem:
            detail = f"{type(problem).__name__}: {problem}".rstrip(": ")
            raise self.config.error(f"curator {name!r} failed {doing} ({detail})") from None

    def _seconds(self, current: Sequence[Candidate] = ()) -> float:
        """Seconds of every finished branch (and of ``current``, the stage in progress)."""
        done = sum(k.seconds for record in self.records for k in record.candidates)
        finishing = self.finishing.seconds if self.finishing is not None else 0.0
        return done + finishing + sum(k.seconds for k in current)

    def _time_spent(self) -> dict[str, float]:
        """Seconds of every branch by part (training, evaluation...), from ``result.json``."""
        from amaze.runs.config import read_json_object

        folders = [self._branch_folder(k) for record in self.records for k in record.candidates]
        if self.finishing is not None:
            folders.append(self.out / FINAL_FOLDER)
        totals: dict[str, float] = {}
        for folder in folders:
            data = read_json_object(folder / "result.json", self.config.error, "branch result")
            for part, seconds in data.get("time", {}).items():
                totals[part] = round(totals.get(part, 0.0) + float(seconds), 3)
        return totals

    def _select(self, stage: int) -> Candidate:
        """The select decision made before ``stage`` (``stages``: the final one)."""
        record = self.records[-1]
        candidates = record.candidates

        def ask() -> int:
            curator = self.curator
            assert curator is not None
            chosen = self._curator_call("selecting", lambda: curator.select(list(candidates)))
            for index, candidate in enumerate(candidates):
                if chosen is candidate or chosen == candidate:
                    return index
            raise self.config.error(
                f"curator {self.config.curator!r} selected {chosen!r}, not one of the candidates"
            )

        choice = self._decide(stage, "select", ask, candidates)
        self.records[-1] = dataclasses.replace(record, selected=choice)
        return candidates[choice]

    def _decide(
        self,
        stage: int,
        kind: str,
        ask: Callable[[], Any],
        candidates: Sequence[Candidate] = (),
    ) -> Any:
        """A decision: recorded already (resume), replayed, or asked now and recorded."""
        c = self.config
        index = decision_index(stage, kind)
        if index < len(self.recorded):
            decision = self.recorded[index]
        else:
            if index < len(self.replayed):
                decision = dataclasses.replace(
                    self.replayed[index], time=_now(), seconds=0.0, replayed=True
                )
            else:
                started = time.perf_counter()
                forced = kind == "select" and len(candidates) == 1
                answer = 0 if forced else ask()
                seconds = time.perf_counter() - started
                common = {
                    "stage": stage,
                    "kind": kind,
                    "curator": c.curator,
                    "time": _now(),
                    "seconds": seconds,
                    "forced": forced,
                }
                if kind == "generate":
                    count = 1 if stage == 0 else c.branches
                    try:
                        mazes = check_mazes(answer, count, c.curator)
                    except CuratorError as problem:
                        raise c.error(str(problem)) from None
                    decision = Decision(**common, mazes=tuple(mazes))
                else:
                    figures = tuple(candidate.figures() for candidate in candidates)
                    decision = Decision(**common, choice=int(answer), candidates=figures)
            self.decisions.append(decision)
            self.recorded.append(decision)
        if kind == "generate":
            return list(decision.mazes or ())
        if decision.choice is None or not 0 <= decision.choice < len(candidates):
            raise c.error(f"decision of stage {stage}: choice {decision.choice!r} is out of range")
        return decision.choice

    def _branch_folder(self, candidate_or_stage: Candidate | int, branch: int = 0) -> Path:
        if isinstance(candidate_or_stage, Candidate):
            stage, branch = candidate_or_stage.stage, candidate_or_stage.branch
        else:
            stage = candidate_or_stage
        return branch_folder(self.out, stage, branch)

    def _read_candidate(
        self, folder: Path, stage: int | None = None, branch: int | None = None
    ) -> Candidate:
        """The finished branch in ``folder``, its ``result.json`` checked.

        It must be the branch of the folder's name, or ``stage`` and ``branch``
        when they are given (the final training's).
        """
        from amaze.runs.config import read_json_object

        path = folder / "result.json"
        data = read_json_object(path, self.config.error, "branch result")
        try:
            candidate = _candidate_from_dict(data, folder)
        except (KeyError, TypeError, ValueError) as problem:
            raise self.config.error(
                f"branch result {str(path)!r} is damaged ({type(problem).__name__}: {problem})"
            ) from None
        expected = self._branch_folder(candidate) == folder
        if stage is not None:
            expected = (candidate.stage, candidate.branch) == (stage, branch)
        if not expected:
            raise self.config.error(
                f"branch result {str(path)!r} says stage {candidate.stage} branch"
                f" {candidate.branch}: it is in another branch's folder"
            )
        self.check_config_digest(data.get("config_sha256"), f"branch result {str(path)!r}")
        return candidate

    def _final_training(self, final: Candidate) -> None:
        """Spend what the stages left of the budget on the final agent, on its lineage's mazes.

        Fixed-stage curricula leave budget unspent when their branches
        converge early; with ``final_training`` the final choice trains on
        the own mazes of its whole lineage (4 rotations each), as a branch of
        its own in ``stages/final`` (resumed like one), and becomes the run's
        agent. Nothing is done when less than 5 % of a budget is left, or less
        than the smallest unit of training.
        """
        c = self.config
        budget_seconds = getattr(c, "budget_seconds", None)
        left_steps = None if c.budget_steps is None else c.budget_steps - self._steps()
        left_seconds = None if budget_seconds is None else budget_seconds - self._seconds()
        if not c.final_training:
            return
        if left_steps is not None and (
            left_steps < self.smallest_unit()[0] or left_steps < (1 - SPENT_ENOUGH) * c.budget_steps
        ):
            return
        if left_seconds is not None and left_seconds < (1 - SPENT_ENOUGH) * budget_seconds:
            return
        own = final.mazes[0]
        training = [own, *(maze for maze in self._lineage_mazes() if maze != own)]
        evaluator = Evaluator(c.robot, rotations(own), inputs=False)
        self.finishing = self._branch(
            len(self.records), 0, [own], training, final, (left_steps, left_seconds),
            evaluator, self._steps(), folder=self.out / FINAL_FOLDER,
        )  # fmt: skip

    def _check_branch_record(self, folder: Path, started: Mapping[str, Any]) -> None:
        """The branch in training in ``folder`` was started as the loop would start it now.

        Its ``branch.json`` recorded its mazes, parent, allowance and config
        when it started: a checkpoint goes on only with the same, since the
        learner would otherwise continue a session on other mazes, from
        another parent or with another budget (decisions or results edited
        since, or another config).
        """
        from amaze.runs.config import read_json_object

        path = folder / BRANCH_FILE
        where = f"branch record {str(path)!r}"
        if not (path.exists() or path.is_symlink()):
            raise self.config.error(
                f"{where} is missing: the checkpoint beside it cannot be checked"
            )
        recorded = read_json_object(path, self.config.error, "branch record")
        changed = sorted(key for key in started if recorded.get(key) != started[key])
        if changed:
            name = changed[0]
            raise self.config.error(
                f"{where}: the branch in training started with {name} {recorded.get(name)!r},"
                f" but the run's decisions, results and config now give {started[name]!r}"
                f" ({', '.join(changed)} changed since): its checkpoint cannot go on"
            )

    def _branch(
        self,
        stage: int,
        branch: int,
        mazes: Sequence[str],
        training: Sequence[str],
        parent: Candidate | None,
        allowance: tuple[int | None, float | None],
        evaluator: Evaluator,
        steps_before: int,
        folder: Path | None = None,
    ) -> Candidate:
        """Train (or finish training) one branch, evaluate it, write its result.

        The branch trains on the 4 rotations of each of ``training``: its own
        maze, ``mazes[branch]``, then the lineage's rehearsed ones. ``folder``
        defaults to the branch's (the final training has its own).
        """
        c = self.config
        folder = self._branch_folder(stage, branch) if folder is None else folder

        def report(steps: int, done: bool = False) -> None:
            self.branch_progress(BranchProgress(stage, branch, steps, *allowance, done=done))
            if self.shown is not None:
                spent = steps_before + steps if c.budget_steps else self._seconds()
                self.shown.update(spent, stage=stage, branch=branch)

        if (folder / "result.json").exists():
            candidate = self._read_candidate(folder, stage, branch)
            if candidate.mazes != (mazes[branch],) or candidate.stage != stage:
                raise c.error(
                    f"branch result {str(folder / 'result.json')!r} is of another maze or stage"
                    " than the decisions say"
                )
            report(candidate.env_steps, done=True)
            return candidate
        report(0)
        clock = [time.perf_counter()]
        checkpoint = folder / "checkpoint"
        started = {
            "stage": stage,
            "branch": branch,
            "training_mazes": list(training),
            "parent_lineage": None if parent is None else list(parent.lineage),
            "budget_steps": allowance[0],
            "budget_seconds": allowance[1],
            "config_sha256": self.config_digest,
        }
        if checkpoint.exists():
            self._check_branch_record(folder, started)
            learner = self.load_learner(checkpoint)
        elif parent is None:
            learner = self.new_learner(branch_seed(c.seed, stage, branch))
        else:
            parent_learner = self.load_learner(self._branch_folder(parent) / "agent")
            learner = parent_learner.branch(branch_seed(c.seed, stage, branch))
        if not checkpoint.exists():
            write_json(folder / BRANCH_FILE, started)
        clock.append(time.perf_counter())
        outcome = learner.train(
            [rotated for maze in training for rotated in rotations(maze)],
            allowance[0],
            budget_seconds=allowance[1],
            checkpoint=lambda: learner.save(checkpoint),
            progress=report,
        )
        clock.append(time.perf_counter())
        learner.save(folder / "agent")
        agent = learner.agent()
        clock.append(time.perf_counter())
        results = _maze_results(evaluator, agent, mazes)
        validation = []
        if self.validation is not None:
            validation = _maze_results(self.validation[0], agent, self.validation[1])
        clock.append(time.perf_counter())
        _, trajectory = record_episode(mazes[branch], c.robot, agent)
        picture = folder / "trajectory.png"
        spec = MazeSpec.from_string(mazes[branch])
        cell = max(8, PICTURE_SIDE // max(spec.width, spec.height))  # small, quick to draw
        save_trajectory_png(spec, trajectory, picture, robot=c.robot, caption=True, cell_size=cell)
        clock.append(time.perf_counter())
        # Where the branch's time went (the learner's seconds cover every resumed part).
        spent = {
            "training": outcome.seconds,
            "loading_and_saving": (clock[1] - clock[0]) + (clock[3] - clock[2]),
            "evaluation": clock[4] - clock[3],
            "picture": clock[5] - clock[4],
        }
        lineage = (*parent.lineage, branch) if parent is not None else (branch,)
        parent_steps = parent.lineage_steps if parent is not None else 0
        own = results[branch]
        candidate = Candidate(
            stage=stage,
            branch=branch,
            mazes=(mazes[branch],),
            own=(own,),
            others=tuple(r for i, r in enumerate(results) if i != branch),
            lineage=lineage,
            env_steps=outcome.env_steps,
            # rounded as result.json keeps it, so a resumed run shares time alike
            seconds=round(sum(spent.values()), 3),
            converged=outcome.converged,
            lineage_steps=parent_steps + outcome.env_steps,
            pictures=(picture,),
            validation=tuple(validation),
        )
        data = _candidate_to_dict(candidate, results)
        data["time"] = {part: round(seconds, 3) for part, seconds in spent.items()}
        data["training_mazes"] = list(training)
        data["config_sha256"] = self.config_digest
        write_json(folder / "result.json", data)
        # Branches run in order: the earlier stages' and this stage's first ``branch``.
        finished = sum(len(record.candidates) for record in self.records) + branch + 1
        self.progress.append(
            {
                "branches": finished,
                "stage": stage,
                "branch": branch,
                "steps": steps_before + candidate.env_steps,
                "seconds": round(candidate.seconds, 3),
                "success": candidate.success_rate,
                "rbar": candidate.mean_reward,
                "converged": candidate.converged,
                "maze": mazes[branch],
            }
        )
        shutil.rmtree(checkpoint, ignore_errors=True)
        report(candidate.env_steps, done=True)
        return candidate
