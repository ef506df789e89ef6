"""One run lifecycle for every trainer: start fresh, resume after a kill, report at the end.

A trainer (``evolution.run.EvolutionRun``, ``rl_baselines.train.SB3Run``)
subclasses :class:`Run` and writes only its own loop and its own state; the
lifecycle around it is the same for all (``docs/architecture.md``, "Run
folders"):

* **fresh** (:meth:`Run.fresh`): check the config, refuse a folder that is
  not new or empty (one that holds a run, or anything else: nothing in it is
  touched), set the trainer up (bad options fail here, before anything is
  written), write ``config.json``, train, finish;
* **resume** (:meth:`Run.resume`): read ``config.json``, check
  ``progress.csv`` and restore the latest checkpoint (the trainer checks its
  own files), refusing any damaged or inconsistent file by name before
  anything changes; then drop the ``progress.csv`` rows written after that
  checkpoint (or start over if the run was killed before its first one),
  train on, finish. Checkpoints record a SHA-256 digest of ``config.json``
  (:attr:`Run.config_digest`): a config changed since they were written is
  refused (:meth:`Run.check_config_digest`), not trained on. Only the budgets
  (:data:`BUDGET_KEYS`) are left out of the digest: raising one in
  ``config.json`` and resuming extends a run;
* **finish** (:meth:`Run.finish`): the final agent written at the top of the
  folder (:attr:`Run.agent_file`: ``agent.npz`` or ``agent.zip``, the one
  place of a run's agent) and scored on the standard evaluation suite (the
  one evaluation protocol), its trajectories, the trainer's pictures, and
  ``summary.json`` last: a run folder with a summary is a finished run. The
  summary says which rule chose the agent and when it was found
  (:meth:`Run.agent_figures`), what share of each budget was spent
  (``budget_spent``) and, when it reached none of them (less than
  :data:`SPENT_ENOUGH` of each), why it stopped early (:meth:`Run.stop_reason`).

Every file is written atomically (:mod:`amaze.runs.folder`), so a run killed at
any moment leaves readable files behind and resumes from its last checkpoint.

Training runs with the objects that exist when it starts (modules, compiled
kernels, maze tables: over a hundred thousand) frozen out of Python's cyclic
garbage collector (:func:`frozen_heap`). A training loop allocates many
objects that live a few generations (genomes, episode results), which makes
the collector run full collections often; each visited every object of the
process and, in a NEAT-like run, the collector took an eighth of the
training time. Freezing changes what the collector visits, never what the run
computes.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import hashlib
import json
import os
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

from amaze.runs.anytime import AnytimeEvaluations, Spent
from amaze.runs.config import RunConfig, read_json_object
from amaze.runs.folder import ProgressLog, write_json

__all__ = [
    "CONFIG_FILE",
    "LOG_FILE",
    "SUMMARY_FILE",
    "Run",
    "RunResult",
    "check_digest",
    "frozen_heap",
]

CONFIG_FILE = "config.json"
SUMMARY_FILE = "summary.json"
#: What ``summary.json`` holds of the final agent on the paper's suite (``paper_suite``),
#: besides the standard suite's figures at its top level.
PAPER_SUITE_FIGURES = ("success_rate", "normalized_reward", "pretty_reward")
#: Keys only one training command's ``config.json`` holds: a run folder of the
#: other command is named as such, with the command that resumes it.
COMMAND_KEYS = {
    "amaze-evolve": frozenset({"algorithm", "fitness", "max_generations", "checkpoint_seconds"}),
    "amaze-train": frozenset({"hyperparameters", "n_envs", "eval_every", "tensorboard"}),
}
#: The ``config.json`` keys a resumed run may find changed: raising a budget extends a run.
BUDGET_KEYS = frozenset({"budget_steps", "budget_seconds", "max_generations"})
#: A run that spent less than this share of a budget says why (``stopped_early``).
SPENT_ENOUGH = 0.95
#: What the process of a replicate prints (:mod:`amaze.runs.replicates`): it is
#: opened before the run starts, so a folder holding only it counts as empty.
LOG_FILE = "log.txt"


@contextlib.contextmanager
def frozen_heap() -> Iterator[None]:
    """Keep the objects alive now out of the garbage collector's full collections, meanwhile.

    :func:`gc.freeze` moves them to a generation the collector never visits
    (they are not garbage: modules, compiled code, the run's set-up);
    :func:`gc.unfreeze` gives them back at the end, even on an error.
    """
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def check_digest(recorded: object, digest: str, where: str, error: type[ValueError]) -> None:
    """Refuse a file (``where``) whose config digest ``recorded`` is not the run's ``digest``.

    ``recorded`` is the digest the file holds (:attr:`Run.config_digest`, a
    SHA-256 of ``config.json`` without its budgets); ``None``, a file of an
    older version, which recorded none, is accepted.
    """
    if recorded is not None and recorded != digest:
        raise error(
            f"{where} was written under another config.json: the run's config.json changed"
            " since (put it back, or start a new run)"
        )


@dataclass(frozen=True)
class RunResult:
    """A finished run: its folder, its final agent (a policy) and ``summary.json``'s content.

    ``headline`` sums it up in one line and ``outputs`` names the files a user
    looks at first (both from the run's class, for the command line).
    """

    out: Path
    agent: Any
    summary: dict[str, Any]
    headline: str = ""
    outputs: tuple[str, ...] = ()
    #: True when a resume found the run finished already (nothing was done).
    finished_before: bool = False

    @property
    def env_steps(self) -> int:
        """Environment steps spent (the budget's unit)."""
        return int(self.summary["env_steps"])

    @property
    def seconds(self) -> float:
        """Wall-clock seconds spent training, over every resumed part of the run."""
        return float(self.summary["seconds"])


class Run(ABC):
    """A training run in its folder; subclasses supply the trainer's part.

    Class attributes say what the trainer's folder holds; the abstract
    methods are the trainer's loop and state. Construct runs through
    :meth:`fresh` and :meth:`resume`.
    """

    #: The trainer's config class (its ``error`` is raised for bad input).
    config_class: ClassVar[type[RunConfig]]
    #: The columns of ``progress.csv``.
    progress_fields: ClassVar[tuple[str, ...]]
    #: The columns of ``progress.csv`` that hold text (the others hold numbers).
    progress_text_fields: ClassVar[tuple[str, ...]] = ()
    #: The ``progress.csv`` column that says how far the run was when a row was written.
    position_field: ClassVar[str]
    #: The files of a checkpoint, in ``checkpoints/``.
    checkpoint_files: ClassVar[tuple[str, ...]]
    #: Files a finished run folder shows a user (printed by the command).
    outputs: ClassVar[tuple[str, ...]] = ("summary.json", "progress.csv")
    #: The file of the run's final agent, at the top of its folder.
    agent_file: ClassVar[str]

    def __init__(self, out: str | os.PathLike, config: RunConfig) -> None:
        self.out = Path(out)
        self.config = config
        self.progress = ProgressLog(
            self.out / "progress.csv", self.progress_fields, self.progress_text_fields
        )
        self.checkpoints = self.out / "checkpoints"
        #: The anytime evaluations (:mod:`amaze.runs.anytime`, ``evaluations.csv``).
        self.anytime = AnytimeEvaluations(self.out, config)

    # -- the trainer's part ---------------------------------------------------

    @abstractmethod
    def start(self) -> None:
        """Set up a fresh run's state. Bad options fail here, before any file is written."""

    @abstractmethod
    def restore(self) -> int | None:
        """Load the latest checkpoint; return its position (``position_field``), or ``None``.

        Check every file the trainer owns (checkpoint, champion) and raise the
        config's error naming a bad one; write nothing (the lifecycle changes
        the folder only once all its files are known to be good).
        """

    @abstractmethod
    def train(self, progress: str) -> None:
        """Spend the budget: the trainer's loop, logging progress and checkpointing."""

    @abstractmethod
    def final_agent(self) -> Any:
        """The agent the run hands over (a policy of :mod:`amaze.evaluation.policy`)."""

    @abstractmethod
    def figures(self) -> dict[str, Any]:
        """The trainer's entries of ``summary.json``: at least ``env_steps`` and ``seconds``."""

    @abstractmethod
    def save_agent(self, agent: Any, path: Path) -> None:
        """Write the final agent (from :meth:`final_agent`) to ``path``, an agent file."""

    def replayed_agent(self, path: Path, agent: Any) -> Any:
        """The final ``agent`` as ``amaze evaluate`` plays its file ``path``: the one scored.

        ``agent`` itself, unless the file is played by other code than the run's
        (a JAX network's actor, played by evolution's compiled networks): the
        run's last figures are then those a replay of the file gives.
        """
        return agent

    @abstractmethod
    def spent(self) -> Spent:
        """How far training is now: ``progress.csv`` position, env steps, training seconds."""

    def current_agent(self) -> Any:
        """The agent the run would hand over if it stopped now (for the anytime evaluations).

        :meth:`final_agent` by default; a trainer whose final choice is made
        only at the end (a curriculum) says what it would be now.
        """
        return self.final_agent()

    def evaluate_anytime(self) -> float:
        """Play the anytime evaluations due now; return their seconds (0 when none was).

        A trainer's loop calls it after each unit of training, outside the
        time its budget counts (or takes the seconds returned off its clock).
        """
        return self.anytime.take(self.spent(), self.current_agent)

    @abstractmethod
    def agent_figures(self) -> dict[str, Any]:
        """How the final agent was chosen: ``agent_rule``, ``agent_steps``, ``agent_untrained``.

        ``agent_steps`` is the env steps spent when the agent was found (it was
        then the run's latest), ``agent_untrained`` whether it had learnt
        nothing yet (RL's step-0 model, an initial random population's best).
        """

    def stop_reason(self) -> str:
        """Why training ended, in words (the summary's ``stopped_early`` if a budget is left)."""
        return ""

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        """``(file stem, maze)`` of the episodes drawn into ``trajectories/``."""
        return []

    def extra_outputs(self) -> None:  # noqa: B027 (optional hook)
        """Write the trainer's own pictures (called before ``summary.json`` is written)."""

    @classmethod
    def run_class_for(cls, config: RunConfig) -> type[Run]:
        """The class that runs ``config``: this one, or a sibling for another regime.

        A trainer whose regimes need different loops (a fixed training set, a
        curriculum) returns the class of the config's regime; :meth:`fresh`
        and :meth:`resume` hand the run to it.
        """
        return cls

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        """One line that sums a finished run up for the command line."""
        recognition = summary.get("input_recognition")
        return (
            f"{summary['env_steps']} env steps, {summary['seconds']:.1f} s; standard suite:"
            f" success {summary['success_rate']:.3f},"
            f" normalized_reward {summary['normalized_reward']:.3f},"
            f" input_recognition {'n/a' if recognition is None else f'{recognition:.3f}'}"
        )

    @staticmethod
    def closing_lines(summary: Mapping[str, Any]) -> list[str]:
        """What a finished run says besides its headline: its agent, and a budget left unspent."""
        lines = []
        if "agent_rule" in summary:
            found = f"found at {summary['agent_steps']:,} env steps"
            if summary.get("agent_untrained"):
                found += ": the untrained agent, no training improved on it"
            lines.append(f"agent: {summary.get('agent')} (rule {summary['agent_rule']}, {found})")
        if summary.get("progress_reward"):
            lines.append(
                f"trained with AMaze's reward plus the progress reward"
                f" (k = {summary['progress_reward']:g}); every evaluation scores AMaze's reward"
            )
        spent = summary.get("budget_spent") or {}
        if summary.get("stopped_early"):
            shares = ", ".join(f"{share:.0%} of the {unit} budget" for unit, share in spent.items())
            lines.append(f"stopped early, at {shares}: {summary['stopped_early']}")
        return lines

    def _budget_figures(self, summary: Mapping[str, Any]) -> dict[str, Any]:
        """``budget_spent`` (each budget's share spent) and ``stopped_early`` (why, if below)."""
        c = self.config
        spent: dict[str, float] = {}
        for unit, budget, used in (
            ("steps", getattr(c, "budget_steps", None), summary.get("env_steps")),
            ("seconds", getattr(c, "budget_seconds", None), summary.get("seconds")),
            ("generations", getattr(c, "max_generations", None), summary.get("generations")),
        ):
            if budget is not None and used is not None:
                spent[unit] = round(float(used) / float(budget), 4)
        figures: dict[str, Any] = {"budget_spent": spent, "stopped_early": None}
        if spent and max(spent.values()) < SPENT_ENOUGH:  # no budget reached: why stop?
            figures["stopped_early"] = self.stop_reason() or "the trainer gave no reason"
        return figures

    @cached_property
    def config_digest(self) -> str:
        """The SHA-256 of ``config.json``'s object, budgets left out (hex, of sorted-key JSON)."""
        data = read_json_object(self.out / CONFIG_FILE, self.config.error, "run config")
        kept = {key: value for key, value in data.items() if key not in BUDGET_KEYS}
        return hashlib.sha256(json.dumps(kept, sort_keys=True).encode("utf-8")).hexdigest()

    def check_config_digest(self, recorded: object, where: str) -> None:
        """Refuse a file (``where``) written under another ``config.json`` than the folder's."""
        check_digest(recorded, self.config_digest, where, self.config.error)

    # -- the lifecycle ----------------------------------------------------------

    @classmethod
    def fresh(
        cls,
        config: RunConfig | Mapping[str, Any],
        out: str | os.PathLike,
        *,
        progress: str = "off",
    ) -> RunResult:
        """Start a run as ``config`` says in the folder ``out``, train it and finish it."""
        if not isinstance(config, cls.config_class):
            config = cls.config_class.from_dict(config)
        config.validate()
        path = Path(out)
        cls._check_new_folder(path, config.error)
        run = cls.run_class_for(config)(path, config)
        run.start()
        path.mkdir(parents=True, exist_ok=True)
        write_json(path / CONFIG_FILE, config.to_dict())
        with frozen_heap():
            run.train(progress)
        return run.finish()

    @classmethod
    def resume(cls, out: str | os.PathLike, *, progress: str = "off") -> RunResult:
        """Continue the run in ``out`` from its latest checkpoint, then finish it."""
        path = Path(out)
        config = cls.read_config(path)
        cls = cls.run_class_for(config)
        run = cls(path, config)
        error = run.config.error
        if (path / SUMMARY_FILE).exists():
            return run.finished_result()
        if "evaluation_points" not in read_json_object(path / CONFIG_FILE, error, "run config"):
            run.anytime.points = 0  # a run started before anytime evaluations: none now either
        # Every file is checked before anything in the folder changes.
        rows = run.progress.checked_rows(cls.position_field, error)
        position = run.restore()
        evaluations = run.anytime.check()
        if position is None:
            if len(rows) > 1:  # more than a run killed before its first checkpoint writes
                files = " and ".join(repr(str(run.checkpoints / f)) for f in cls.checkpoint_files)
                raise error(
                    f"{str(run.progress.path)!r} has {len(rows)} rows but the checkpoint"
                    f" {files} is missing: resuming would lose them"
                )
            run.start()
            run.progress.keep(lambda row: False)
            run.anytime.restore(None, evaluations)
        else:
            if not any(int(row[cls.position_field]) == position for row in rows):
                raise error(
                    f"{str(run.progress.path)!r} has no row at {cls.position_field} {position},"
                    " where the checkpoint is"
                )
            run.progress.keep(lambda row: int(row[cls.position_field]) <= position)
            run.anytime.restore(position, evaluations)
        with frozen_heap():
            run.train(progress)
        return run.finish()

    @classmethod
    def replay(
        cls, source: str | os.PathLike, out: str | os.PathLike, *, progress: str = "off"
    ) -> RunResult:
        """A new run in ``out`` with the config of the run in ``source`` and its decisions.

        Only runs that record decisions (curricula) can be replayed; the
        others are refused by :meth:`replay_config`.
        """
        path = Path(source)
        config = cls.read_config(path)
        run_class = cls.run_class_for(config)
        replayed = run_class.replay_config(path, config)
        return run_class.fresh(replayed, out, progress=progress)

    @classmethod
    def replay_config(cls, source: Path, config: RunConfig) -> RunConfig:
        """The config of a run that replays the run in ``source`` (hook; refused by default)."""
        raise config.error(
            f"{str(source)!r} holds a run that records no decisions: there is nothing to replay"
        )

    def finished_result(self) -> RunResult:
        """The result of this run, finished already: read from its folder, nothing changed."""
        summary = read_json_object(self.out / SUMMARY_FILE, self.config.error, "run summary")
        try:
            headline = type(self).headline(summary)
        except (KeyError, TypeError, ValueError) as problem:
            raise self.config.error(
                f"run summary {str(self.out / SUMMARY_FILE)!r} is damaged ({problem!r})"
            ) from None
        outputs = tuple(name for name in self.outputs if any(self.out.glob(name.rstrip("/"))))
        return RunResult(self.out, None, summary, headline, outputs, finished_before=True)

    @staticmethod
    def _check_new_folder(path: Path, error: type[ValueError]) -> None:
        """A new run goes into a new or empty folder; anything else is refused untouched.

        A folder that holds only :data:`LOG_FILE` (the output of the process
        about to run there) counts as empty.
        """
        if path.is_dir():
            if (path / CONFIG_FILE).exists():
                raise error(f"{str(path)!r} already holds a run (use --resume)")
            if any(entry.name != LOG_FILE for entry in path.iterdir()):
                raise error(
                    f"{str(path)!r} is not empty and holds no run: give a new or empty folder"
                )
        elif path.exists() or path.is_symlink():
            raise error(f"{str(path)!r} exists and is not a folder")

    @classmethod
    def read_config(cls, path: Path) -> RunConfig:
        """The checked config of the run in ``path``."""
        error = cls.config_class.error
        config_file = path / CONFIG_FILE
        if not (config_file.exists() or config_file.is_symlink()):
            if not path.exists():
                raise error(f"{str(path)!r} does not exist")
            if not path.is_dir():
                raise error(f"{str(path)!r} is not a folder")
            seeds = sorted(p.name for p in path.glob("seed-*") if (p / CONFIG_FILE).exists())
            if seeds:
                raise error(
                    f"{str(path)!r} holds replicates ({', '.join(seeds)}), each a run: resume"
                    f" them one by one (--resume {str(path / seeds[0])!r}...)"
                )
            raise error(f"{str(path)!r} holds no run (no {CONFIG_FILE})")
        data = read_json_object(config_file, error, "run config")
        known = {f.name for f in dataclasses.fields(cls.config_class)}
        for command, keys in COMMAND_KEYS.items():
            if keys & set(data) and not keys & known:
                raise error(
                    f"{str(path)!r} holds a run of {command} (its config.json has"
                    f" {', '.join(sorted(keys & set(data)))}): use {command} for it"
                )
        try:
            return cls.config_class.from_dict(data)
        except error as problem:
            raise error(f"run config {str(config_file)!r}: {problem}") from None

    def finish(self) -> RunResult:
        """The final agent on the standard suite, its trajectories, then ``summary.json``."""
        # Imported here: the evaluation and the pictures (Pillow) are needed only
        # at the end of a run, and every command line would otherwise pay for them.
        from amaze.agents.trajectories import save_trajectory_png
        from amaze.evaluation.policy import record_episode
        from amaze.evaluation.protocol import Evaluator
        from amaze.evaluation.suite import paper_suite

        agent = self.final_agent()
        self.save_agent(agent, self.out / self.agent_file)
        agent = self.replayed_agent(self.out / self.agent_file, agent)
        self.anytime.finish(self.spent(), agent)
        robot = self.config.robot
        summary = Evaluator(robot).evaluate(agent).summary()
        paper = Evaluator(robot, paper_suite(), inputs=False).evaluate(agent).summary()
        summary["paper_suite"] = {key: paper[key] for key in PAPER_SUITE_FIGURES}
        summary.update(self.figures())
        summary.update(self.agent_figures(), agent=self.agent_file)
        summary["anytime"] = self.anytime.figures()
        summary.update(self._budget_figures(summary))
        for stem, maze in self.trajectory_mazes():
            _, trajectory = record_episode(maze, robot, agent)
            path = self.out / "trajectories" / f"{stem}.png"
            save_trajectory_png(maze, trajectory, path, robot=robot, caption=True)
        self.extra_outputs()
        write_json(self.out / SUMMARY_FILE, summary)
        run_class = type(self)
        return RunResult(
            self.out,
            agent,
            summary,
            run_class.headline(summary),
            # only what the run wrote (no tensorboard/ when it was turned off...)
            tuple(name for name in run_class.outputs if any(self.out.glob(name.rstrip("/")))),
        )
