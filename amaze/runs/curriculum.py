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

import dataclasses
import json
import shutil
from abc import abstractmethod
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

from amaze.curriculum.curators import Candidate, History, StageRecord
from amaze.curriculum.learner import Learner, SessionWatch, branch_seed
from amaze.curriculum.regimes import (
    branch_allowance,
    branch_seconds,
    curriculum_over,
)
from amaze.evaluation.protocol import Evaluator
from amaze.maze import rotations
from amaze.runs.anytime import Spent
from amaze.runs.branches import (
    BRANCH_FILE,
    FINAL_FOLDER,
    BranchProgress,
    Clock,
    branch_folders,
    check_branch_record,
    maze_results,
    new_candidate,
    read_result,
    save_branch_trajectory,
    write_result,
)
from amaze.runs.config import RunConfig
from amaze.runs.curriculum_summary import CurriculumSummary
from amaze.runs.decisions import (
    DECISIONS_FILE,
    REPLAY_FILE,
    DecisionLog,
    Decisions,
    check_against_decisions,
    decision_sequence,
)
from amaze.runs.folder import settled_folder, write_bytes, write_folder, write_json
from amaze.runs.lifecycle import SPENT_ENOUGH, Run
from amaze.runs.progress import Progress

__all__ = ["CurriculumRun"]

PROGRESS_FIELDS = (
    "branches",
    "stage",
    "branch",
    "steps",
    "seconds",
    "success_rate",
    "normalized_reward",
    "converged",
    "maze",
)


class CurriculumRun(CurriculumSummary, Run):
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
    config: Any  # a RegimeConfig subclass with budget_steps (and maybe budget_seconds)

    def __init__(self, out: Any, config: Any) -> None:
        super().__init__(out, config)
        #: The loop's decisions: recorded (a resume), replayed, or asked of the curator.
        self.decided = Decisions(DecisionLog(self.out / DECISIONS_FILE), config)
        self.records: list[StageRecord] = []
        #: The finished branches of the stage in progress.
        self.current: list[Candidate] = []
        self.final: Candidate | None = None
        #: The final agent trained on its lineage's mazes (``final_training``), if it was.
        self.finishing: Candidate | None = None
        #: Why the loop played no more stages, when a budget ended it.
        self.ended_because = ""
        #: What shows the loop's progress while it trains.
        self.shown: Progress | None = None
        #: The curator's and advisor's validation mazes and their evaluator, if they have any.
        self.validation: tuple[Evaluator, list[str]] | None = None
        #: The branch folder whose agent was loaded last, and that agent.
        self._loaded: tuple[Path | None, Any] = (None, None)

    # -- the trainer's part ---------------------------------------------------

    @abstractmethod
    def new_learner(self, seed: int) -> Learner:
        """A fresh learner for the run's robot and options, drawing from ``seed``."""

    @abstractmethod
    def load_learner(self, folder: Path) -> Learner:
        """The learner saved in ``folder``; a damaged one raises the config's error naming it."""

    def smallest_unit(self) -> tuple[int, str]:
        """The env steps of the learner's smallest unit of training, and what that unit is.

        A rollout for RL, a generation on the trivial first maze for
        evolution: a branch allowed fewer steps could not train at all, so the
        loop plays no stage whose branches it would give fewer (the trainer's
        learner itself never starts a unit its session cannot pay).
        """
        return 1, "one env step"

    def session_watch(
        self,
        stage: int,
        folder: Path,
        learner: Learner,
        allowance: tuple[int | None, float | None],
    ) -> SessionWatch | None:
        """What a branch of ``stage`` is judged on instead of its own mazes (default: nothing).

        A trainer whose config asks for it (the RL trainer's
        ``stage_eval_target``) returns a :class:`~amaze.curriculum.learner.SessionWatch`
        whose ``keep_best`` writes the branch's best agent into ``folder``.
        """
        return None

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
        """Build the curator and its advisor (a bad name, plug-in or pairing fails here).

        Then read a replay's decisions. A steps budget that cannot give the
        first branch the learner's smallest unit of training is refused here
        too, before anything is written.
        """
        c = self.config
        self._check_budget()
        decided = self.decided
        validation = decided.build()
        self.validation = (
            (Evaluator(c.robot, rotations(validation), inputs=False), validation)
            if validation
            else None
        )
        if c.replay is not None:
            # The run's own copy once it has one (the replayed run may be gone since).
            copy = DecisionLog(self.out / REPLAY_FILE)
            if copy.path.exists():
                decided.replayed = copy.read(c.stages, c.branches, c.error, "replayed decisions")
            else:
                source = DecisionLog(Path(c.replay) / DECISIONS_FILE)
                decided.replayed = source.read(c.stages, c.branches, c.error)

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
        decided = self.decided
        decided.recorded = decided.log.read(c.stages, c.branches, c.error)
        finished: dict[tuple[int, int], Candidate] = {}
        for folder in branch_folders(self.out):
            if (folder / "result.json").exists():
                candidate = self._read_candidate(folder)
                finished[candidate.stage, candidate.branch] = candidate
        for candidate in finished.values():
            check_against_decisions(
                candidate, finished, decided.recorded, decided.log.path, c.error
            )
        final = self.out / FINAL_FOLDER
        for folder in [*branch_folders(self.out), final]:
            has_result = (folder / "result.json").exists()
            if folder == final and has_result:
                self._read_candidate(final, (len({stage for stage, _ in finished}), 0))
            if has_result or settled_folder(folder / "checkpoint").exists():
                self.load_learner(folder / ("agent" if has_result else "checkpoint"))
        return len(finished) + (final / "result.json").exists() or None

    def train(self, progress: str) -> None:
        """The loop (see the module docstring), skipping what the folder says is done."""
        c = self.config
        replayed = self.decided.replayed
        if replayed and not (self.out / REPLAY_FILE).exists():
            text = "".join(json.dumps(d.to_dict(), sort_keys=True) + "\n" for d in replayed)
            write_bytes(self.out / REPLAY_FILE, text.encode("utf-8"))
        self.records = []
        budget_seconds = getattr(c, "budget_seconds", None)
        total, unit = (c.budget_steps, "steps") if c.budget_steps else (budget_seconds, "s")
        desc = f"{c.regime} {c.curator} seed {c.seed}"
        with Progress(total, unit, desc, mode=progress) as self.shown:
            stage = 0
            while not self._over(stage):
                self.records.append(self._stage(stage))
                self.current = []
                stage += 1
            self.final = self._select(stage)
            self._final_training(self.final)

    def _stage(self, stage: int) -> StageRecord:
        """Play ``stage``: its decisions (or the recorded ones), then each of its branches."""
        c = self.config
        parent: Candidate | None = None
        if stage == 0:
            trivial = [c.curator_context().trivial_maze()]
            mazes = self.decided.generate(0, lambda: trivial)
        else:
            parent = self._select(stage)
            history = History(stage=stage, parent=parent, stages=tuple(self.records))
            mazes = self.decided.generate(stage, history)
        allowance = self._allowance(stage)
        evaluator = Evaluator(c.robot, rotations(mazes), inputs=False)
        lineage = self._lineage_mazes()
        candidates = self.current = []
        for branch in range(len(mazes)):
            own = mazes[branch]
            rehearsed = [maze for maze in lineage if maze != own][: c.rehearsal]
            steps_before = self._steps(candidates)
            training = [own, *rehearsed]
            candidate = self._branch(
                stage, branch, mazes, training, parent, allowance, evaluator, steps_before
            )
            candidates.append(candidate)
            self.evaluate_anytime()
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
        return self._agent_in(self._final_folder())

    def spent(self) -> Spent:
        """Finished branches (the final training counts as one), their steps and seconds."""
        finished = sum(len(record.candidates) for record in self.records) + len(self.current)
        return Spent(
            finished + (self.finishing is not None),
            self._steps(self.current),
            self._seconds(self.current),
        )

    def current_agent(self) -> Any:
        """The final training's agent, else the final choice, else the latest selection.

        Before the first selection (stage 0), the newest finished branch: the
        only agents there are.
        """
        if self.final is not None:
            return self.final_agent()
        selected = [r for r in self.records if r.selected is not None]
        if selected:
            record = selected[-1]
            assert record.selected is not None
            return self._agent_in(self._branch_folder(record.candidates[record.selected]))
        return self._agent_in(self._branch_folder(self.current[-1]))

    def _agent_in(self, folder: Path) -> Any:
        """The agent saved in a branch ``folder`` (the last one loaded is kept)."""
        if self._loaded[0] != folder:
            self._loaded = (folder, self.load_learner(folder / "agent").agent())
        return self._loaded[1]

    def _final_folder(self) -> Path:
        """The folder of the agent the run hands over: its final training's or final choice's."""
        assert self.final is not None
        if self.finishing is not None:
            return self.out / FINAL_FOLDER
        return self._branch_folder(self.final)

    # -- the loop's own ---------------------------------------------------------

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

    def _select(self, stage: int) -> Candidate:
        """The select decision made before ``stage`` (``stages``: the final one)."""
        record = self.records[-1]
        choice = self.decided.select(stage, record.candidates)
        self.records[-1] = dataclasses.replace(record, selected=choice)
        return record.candidates[choice]

    def _read_candidate(self, folder: Path, expected: tuple[int, int] | None = None) -> Candidate:
        """The finished branch in ``folder`` (see :func:`~amaze.runs.branches.read_result`)."""
        return read_result(folder, self.config.error, self.config_digest, expected)

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
        self.evaluate_anytime()

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
            candidate = self._read_candidate(folder, (stage, branch))
            if candidate.mazes != (mazes[branch],):
                raise c.error(
                    f"branch result {str(folder / 'result.json')!r} is of another maze than"
                    " the decisions say"
                )
            report(candidate.env_steps, done=True)
            return candidate
        report(0)
        clock = Clock()
        started = {
            "stage": stage,
            "branch": branch,
            "training_mazes": list(training),
            "parent_lineage": None if parent is None else list(parent.lineage),
            "budget_steps": allowance[0],
            "budget_seconds": allowance[1],
            "config_sha256": self.config_digest,
        }
        learner = self._start_learner(folder, started, parent)
        clock.lap("loading_and_saving")
        watch = self.session_watch(stage, folder, learner, allowance)
        outcome = learner.train(
            [rotated for maze in training for rotated in rotations(maze)],
            allowance[0],
            budget_seconds=allowance[1],
            checkpoint=lambda: write_folder(folder / "checkpoint", learner.save),
            progress=report,
            **({} if watch is None else {"watch": watch}),
        )
        clock.skip()  # the learner keeps the seconds of its session, over every resumed part
        write_folder(folder / "agent", learner.save)
        agent = learner.agent()
        clock.lap("loading_and_saving")
        results = maze_results(evaluator, agent, mazes)
        validation = []
        if self.validation is not None:
            validation = maze_results(self.validation[0], agent, self.validation[1])
        clock.lap("evaluation")
        picture = save_branch_trajectory(folder, mazes[branch], c.robot, agent)
        clock.lap("picture")
        spent = {"training": outcome.seconds, **clock.parts}
        candidate = new_candidate(
            stage, branch, mazes, results, validation, parent, outcome, spent, picture
        )
        write_result(folder, candidate, results, spent, training, self.config_digest)
        self._log_branch(candidate, mazes[branch], steps_before)
        shutil.rmtree(folder / "checkpoint", ignore_errors=True)
        report(candidate.env_steps, done=True)
        return candidate

    def _start_learner(
        self, folder: Path, started: Mapping[str, Any], parent: Candidate | None
    ) -> Learner:
        """The branch's learner: its checkpoint's (checked), or a copy of its parent's, or new.

        A branch that starts records what it started with (``branch.json``)
        before anything of it is trained.
        """
        c = self.config
        stage, branch = started["stage"], started["branch"]
        if settled_folder(folder / "checkpoint").exists():
            check_branch_record(folder, started, c.error)
            return self.load_learner(folder / "checkpoint")
        if parent is None:
            learner = self.new_learner(branch_seed(c.seed, stage, branch))
        else:
            parent_learner = self.load_learner(self._branch_folder(parent) / "agent")
            learner = parent_learner.branch(branch_seed(c.seed, stage, branch))
        write_json(folder / BRANCH_FILE, dict(started))
        return learner

    def _log_branch(self, candidate: Candidate, maze: str, steps_before: int) -> None:
        """The ``progress.csv`` row of a finished branch (branches run in order)."""
        finished = sum(len(record.candidates) for record in self.records) + candidate.branch + 1
        self.progress.append(
            {
                "branches": finished,
                "stage": candidate.stage,
                "branch": candidate.branch,
                "steps": steps_before + candidate.env_steps,
                "seconds": round(candidate.seconds, 3),
                "success_rate": candidate.success_rate,
                "normalized_reward": candidate.normalized_reward,
                "converged": candidate.converged,
                "maze": maze,
            }
        )
