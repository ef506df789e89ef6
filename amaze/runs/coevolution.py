"""The co-evolution loop as a run: a maze population beside the learner, for any trainer.

::

    while the budget pays one more round:
        batch <- mazes.propose()                     # replayed members + new mazes
        results <- the trainer learns on the batch   # each maze in its 4 rotations
        mazes.update(batch, results per maze)        # scores, admission, retirement
        every validation_every-th round:
            the round's agents on the validation mazes; the best there so far is the champion

:class:`CoevolutionRun` is that loop on the shared run lifecycle
(:mod:`amaze.runs.lifecycle`), with a
:class:`~amaze.curriculum.maze_population.MazePopulation` beside the learner. A
trainer supplies its step on a batch (:meth:`CoevolutionRun.learn`: one
generation of a search algorithm, one rollout of SB3), how its agents are
played on the validation mazes, and what is its own: its learner's state, the
parts of its checkpoint, its figures. The loop calls a round what each trainer
calls it in its files (:attr:`~amaze.runs.lifecycle.Run.position_field`:
``generation`` for evolution, ``round`` for RL): the first column of
``progress.csv`` and the summary's ``generations``/``rounds``,
``champion_generation``/``champion_round`` and ``agent_generation``/``agent_round``.

**Champion.** Results on a changing batch do not compare across rounds, so
the champion is chosen on fixed *validation mazes*: ``coevolution.validation``
mazes of the target's family whose seeds are neither the evaluation suite's
nor any training maze's (:func:`~amaze.curriculum.validation.validation_mazes`).
Every ``validation_every``-th round the trainer plays its round's agents
there (evolution: the ``validation_candidates`` best on the batch; RL: its
one agent), 4 rotations each; the champion is the best there so far (the
latest on ties: validation saturates, at R̄ 1.000 on every validation maze,
long before the run ends, and a later agent equal there has learnt from more
mazes; with the earliest, one run kept from generation 133 of 2 691 an agent
that solved 0.833 of the suite), the agent the run hands over (``agent_rule``
``best-validation``). The suite itself is never looked at before the end.
``summary.json`` also reports the champion on other family mazes no part of
the run played (``unseen_success_rate``, ``unseen_normalized_reward``;
:func:`~amaze.curriculum.validation.unseen_mazes`).

**Budget.** ``budget_steps`` env steps and/or ``budget_seconds`` seconds of
the loop (over every resumed part of the run), and the trainer's own limits
(evolution's ``max_generations``, a search algorithm that stopped). Budgets
are hard limits: a round starts only if the steps left pay the trainer's
smallest unit (:meth:`CoevolutionRun.smallest_unit`: a generation at a step
per episode, a rollout), and a budget that cannot pay the first one is
refused before the run's folder is written. Where the time goes is reported
in ``summary.json`` (``time``: the trainer's parts, ``mazes``, ``validation``
and ``logging_and_checkpoints``). After each round the run plays the anytime
evaluations that are due (:meth:`~amaze.runs.lifecycle.Run.evaluate_anytime`),
outside the seconds the budget counts.

**Run folder** (besides ``config.json``, the agent, ``summary.json`` and
``trajectories/``, the champion in the target's 4 rotations):

* ``progress.csv``: a row per round: the round, ``steps``, ``seconds``, the
  trainer's own columns, then :attr:`CoevolutionRun.population_fields`;
* ``checkpoints/state.npz``: the loop's state and the trainer's
  (:class:`CoevolutionState`; :mod:`amaze.runs.checkpoint`), written after
  the first round a process plays, whenever the trainer says one is due, and
  after the last round;
* ``mazes.csv``: every maze that was ever a member of the population (its
  string, origin, parent, birth, retirement, last scores and difficulty
  profile; :data:`~amaze.curriculum.maze_population.MAZES_CSV_FIELDS`), written
  with each checkpoint from the checkpointed population;
* ``population.png``: the members at the end, best score first;
* ``coevolution.png``: the trainer's figures on the batches, the validation
  success of each validated round and of the champion, and the difficulty of
  the batches and of the population against the target's, over env steps.

**Resume.** The checkpoint holds the population (members, records, scores
and random generator), the champion and the trainer's state; a resumed run
goes on from it, bit-identically where the trainer is deterministic
(evolution; seconds budgets aside).
"""

from __future__ import annotations

import math
import time
from abc import abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from amaze.agents.engine import BatchEngine
from amaze.curriculum.difficulty import difficulty
from amaze.curriculum.maze_population import (
    MazePopulation,
    MazePopulationConfig,
    MazeResult,
    mazes_csv,
)
from amaze.curriculum.picture import save_population_png
from amaze.curriculum.validation import unseen_mazes, validation_mazes
from amaze.errors import SignError, one_line
from amaze.evaluation.policy import run_episodes
from amaze.maze import Maze, as_mazes, rotations
from amaze.maze.arrow_styles import TRAINING_FOLDER, write_sign_styles
from amaze.maze.signs import known_shapes, register_custom_signs
from amaze.maze.spec import MazeSpec
from amaze.runs.anytime import Spent
from amaze.runs.branches import Clock
from amaze.runs.checkpoint import StateCodec, read_checkpoint, write_checkpoint
from amaze.runs.coevolution_picture import Curve, save_coevolution_plot
from amaze.runs.folder import write_bytes
from amaze.runs.lifecycle import Run
from amaze.runs.progress import Progress

__all__ = [
    "POPULATION_FIELDS",
    "BatchResults",
    "CoevolutionRun",
    "CoevolutionState",
    "Validation",
]

#: The ``progress.csv`` columns of the population and the champion, after the trainer's own.
POPULATION_FIELDS = (
    "validation", "validation_success_rate", "champion_success_rate", "members", "admitted",
    "batch_difficulty", "population_difficulty",
)  # fmt: skip
#: Files of a finished co-evolution run a user looks at first (besides its agent).
OUTPUTS = ("summary.json", "progress.csv", "mazes.csv", "population.png", "coevolution.png")
#: The parts of a round the loop times itself (``summary.json``'s ``time``).
LOOP_TIME_PARTS = ("mazes", "validation")
#: The run's sub-folder of drawn sign styles (the ``sign_styles`` option).
SIGNS_FOLDER = "signs"


@dataclass
class CoevolutionState:
    """What the loop keeps in every checkpoint; a trainer's state class adds its own fields.

    Old layouts are read through :meth:`upgrade` (a checkpoint is restored
    by ``__setstate__``, never by ``__init__``), then checked against
    :attr:`VERSION`.
    """

    #: The version of the trainer's checkpoint layout (a subclass sets it).
    VERSION: ClassVar[int] = 0

    mazes: MazePopulation
    #: Rounds played (``generation`` or ``round`` in the trainer's files).
    round: int = 0
    #: Env steps spent, as the budget counts them.
    steps: int = 0
    #: Seconds of the loop, over every resumed part of the run.
    seconds: float = 0.0
    #: Env steps of the validation episodes.
    validation_steps: int = 0
    #: The champion's fitness on the validation mazes (the trainer's measure).
    champion_fitness: float = -math.inf
    champion_success_rate: float = 0.0
    #: The round that found the champion, and the env steps spent by its end.
    champion_round: int = 0
    champion_steps: int = 0
    #: Seconds spent per part of the loop (the trainer's parts, ``mazes``, ``validation``).
    time: dict[str, float] = field(default_factory=dict)
    version: int = 0
    #: The SHA-256 of the run's ``config.json`` (:attr:`~amaze.runs.lifecycle.Run.config_digest`).
    config_sha256: str | None = None
    #: The EDEnS selector's state in the ``edens-populations`` regime
    #: (:class:`~amaze.curriculum.population_selector.SelectorState`); None otherwise.
    selection: Any = None

    def __post_init__(self) -> None:
        self.version = self.VERSION

    def __setstate__(self, attributes: Any) -> None:
        """Restore the saved attributes, an older layout's brought up to date by :meth:`upgrade`."""
        if not isinstance(attributes, dict) or not all(isinstance(k, str) for k in attributes):
            raise TypeError(f"{type(self).__name__} is given attributes that are not named")
        self.__dict__.update(self.upgrade(dict(attributes)))

    @classmethod
    def upgrade(cls, attributes: dict[str, Any]) -> dict[str, Any]:
        """The attributes of an older checkpoint layout in this one's (none by default)."""
        return attributes


@dataclass
class BatchResults:
    """What a trainer's step on a batch gives the loop (:meth:`CoevolutionRun.learn`)."""

    #: Successes and R̄ of the episodes, ``(agents, episodes)``: the batch's mazes in
    #: order, each in its 4 rotations.
    success: np.ndarray
    normalized_reward: np.ndarray
    #: The round's agents to validate, in the trainer's own terms.
    candidates: Sequence[Any]
    #: The trainer's ``progress.csv`` columns.
    figures: dict[str, Any]


@dataclass
class Validation:
    """The candidates of a round on the validation mazes (arrays in the candidates' order)."""

    fitness: np.ndarray
    success_rate: np.ndarray
    env_steps: int


class CoevolutionRun(Run):
    """The co-evolution loop of a trainer; subclasses supply its step on a batch and its state."""

    checkpoint_files = ("state.npz",)
    outputs: ClassVar[tuple[str, ...]] = OUTPUTS
    #: The ``progress.csv`` columns after the trainer's own (:data:`POPULATION_FIELDS`).
    population_fields: ClassVar[tuple[str, ...]] = POPULATION_FIELDS
    #: The trainer's state class (what ``state.npz`` must hold).
    state_class: ClassVar[type[CoevolutionState]]
    #: The trainer's parts of a round in ``summary.json``'s ``time``.
    time_parts: ClassVar[tuple[str, ...]] = ()
    #: Whether validation episodes count in the steps budget.
    validation_spends_budget: ClassVar[bool] = True
    #: Whether a round validates the agents it played before they learnt from the
    #: batch (evolution's candidates): the first round's champion is then untrained.
    validated_before_learning: ClassVar[bool] = False
    #: ``coevolution.png``'s top panel: its label and the trainer's columns drawn there.
    batch_plot: ClassVar[tuple[str, tuple[Curve, ...]]] = ("", ())
    config: Any  # a RegimeConfig subclass with algo, budget_steps and budget_seconds
    state: CoevolutionState

    def __init__(self, out: Any, config: Any) -> None:
        super().__init__(out, config)
        self.checkpoint = self.checkpoints / self.checkpoint_files[0]
        self._ticked = time.perf_counter()

    # -- the trainer's part ---------------------------------------------------

    @abstractmethod
    def new_state(self, mazes: MazePopulation) -> CoevolutionState:
        """A fresh run's state with ``mazes`` and a new learner (bad options fail here)."""

    @abstractmethod
    def state_codec(self) -> StateCodec:
        """What ``state.npz`` may hold: the trainer's state class and what it holds."""

    @abstractmethod
    def restore_learner(self, state: CoevolutionState) -> None:
        """Load what the checkpointed ``state`` names; the config's error names a bad file."""

    @abstractmethod
    def smallest_unit(self) -> tuple[int, str, str]:
        """The fewest env steps the next round can spend, what they pay and how they are counted.

        ``(steps, "rollout", "n_steps 5 x n_envs 4")``: a round starts only
        if the steps budget left pays ``steps``.
        """

    @abstractmethod
    def learn(self, mazes: list[Maze], clock: Clock) -> BatchResults:
        """Learn on a batch (``mazes``: each batch maze in its 4 rotations); count the steps.

        The trainer adds the steps it spends to ``state.steps`` and laps
        ``clock`` for its :attr:`time_parts`.
        """

    @abstractmethod
    def validate(self, candidates: Sequence[Any]) -> Validation:
        """The round's ``candidates`` on the validation mazes (:attr:`validation_mazes`)."""

    @abstractmethod
    def keep_champion(self, candidates: Sequence[Any], index: int) -> None:
        """``candidates[index]`` is the new champion: keep it as the agent the run hands over."""

    @abstractmethod
    def own_figures(self) -> dict[str, Any]:
        """The trainer's own entries of ``summary.json``."""

    @abstractmethod
    def checkpoint_due(self, steps: int, seconds: float) -> bool:
        """Whether a checkpoint is due, ``steps`` and ``seconds`` after the last one."""

    def goes_on(self) -> bool:
        """Whether the learner can play another round (a search algorithm may stop)."""
        return True

    def round_limit(self) -> int | None:
        """The most rounds the config allows (evolution's ``max_generations``), if any."""
        return None

    def save_learner(self) -> None:
        """Write the trainer's files of a checkpoint, before ``state.npz`` names them."""

    def learner_saved(self) -> None:
        """Clear what the checkpoint just written no longer needs."""

    def round_done(self, row: Mapping[str, Any]) -> None:
        """Hear the round's ``progress.csv`` row (the trainer's own logs)."""

    def shown_figures(self, row: Mapping[str, Any]) -> dict[str, Any]:
        """The trainer's figures beside the progress bar."""
        return {}

    # -- the regime's common part ---------------------------------------------

    @cached_property
    def options(self) -> MazePopulationConfig:
        """The maze population's options (the config's ``coevolution``, checked by it)."""
        return MazePopulationConfig.from_dict(self.config.coevolution)

    @cached_property
    def validation_mazes(self) -> list[str]:
        """The mazes the champion is chosen on (each played in its 4 rotations).

        With the ``shapes`` or ``sign_styles`` options, their signs are drawn
        in those shapes in turn (maze ``i`` in ``shapes[i % len(shapes)]``,
        :attr:`~amaze.curriculum.maze_population.MazePopulationConfig.drawn_shapes`):
        a champion chosen on arrows alone would be the best arrow reader,
        whatever the run trained on.
        """
        c, shapes = self.config, self.options.drawn_shapes
        mazes = validation_mazes(c.target, self.options.validation, c.seed)
        if shapes is None:
            return mazes
        return [
            MazeSpec.from_string(maze).in_shape(shapes[i % len(shapes)]).to_string()
            for i, maze in enumerate(mazes)
        ]

    # -- the lifecycle's hooks ------------------------------------------------

    def register_sign_styles(self) -> None:
        """Draw the ``sign_styles`` option's arrow styles into ``signs/`` and register them.

        ``signs/training`` holds the styles (``arrowv0.png`` ...), ``signs/held-out``
        the drawings never trained on, as ``amaze draw-signs`` writes them. A
        resumed run draws them again (the same config draws the same images)
        and registers them; a process that only plays the agent on the suite
        needs none of them (the suite's signs are arrows).
        """
        options = self.options
        if not options.sign_styles:
            return
        known_shapes()  # the environment's custom signs first: the run's styles win
        folder = self.out / SIGNS_FOLDER
        try:
            write_sign_styles(
                folder,
                options.sign_styles,
                options.sign_styles_seed,
                options.sign_styles_heads,
                options.sign_styles_shaft_width,
            )
            register_custom_signs(folder / TRAINING_FOLDER)
        except (SignError, OSError) as problem:
            raise self.config.error(f"sign_styles: {one_line(problem)}") from None

    def start(self) -> None:
        """A fresh population and learner; a steps budget that cannot pay a round is refused."""
        self.register_sign_styles()
        c = self.config
        mazes = MazePopulation.for_run(c.target, self.options, c.seed, self.validation_mazes)
        self.state = self.new_state(mazes)
        self.check_budget()

    def restore(self) -> int | None:
        if not self.checkpoint.exists():
            return None
        self.register_sign_styles()
        c = self.config
        where = f"checkpoint {str(self.checkpoint)!r}"
        state = read_checkpoint(self.checkpoint, self.state_codec(), c.error, self.state_class)
        if state.version != state.VERSION:
            raise c.error(f"{where} is of version {state.version!r}, not {state.VERSION}")
        self.check_config_digest(state.config_sha256, where)
        self.restore_learner(state)
        self.state = state
        return state.round

    def train(self, progress: str) -> None:
        """Rounds until a budget is spent, checkpointing as the module docstring says."""
        c, s = self.config, self.state
        if c.budget_steps is not None:
            total, unit = c.budget_steps, "steps"
        elif c.budget_seconds is not None:
            total, unit = c.budget_seconds, "s"
        else:
            total, unit = self.round_limit(), f"{self.position_field}s"
        desc = f"{c.algo} {c.regime} seed {c.seed}"
        self._ticked = time.perf_counter()
        last: tuple[int, float] | None = None  # steps and seconds at the last checkpoint
        going = self.budget_left()
        with Progress(total, unit, desc, mode=progress, initial=self._done()) as shown:
            while going:
                row = self.play_round()
                self.progress.append(row)
                # looked at once a round: the round that spends the budget is checkpointed
                going = self.budget_left()
                if last is None or not going or self.checkpoint_due(*self._since(last)):
                    self.save_checkpoint()
                    last = (s.steps, s.seconds)
                self._tick()
                self.evaluate_anytime()
                self._ticked = time.perf_counter()  # outside the seconds the budget counts
                figures = {self.position_field: s.round, **self.shown_figures(row)}
                figures["champion_success_rate"] = f"{s.champion_success_rate:.2f}"
                shown.update(self._done(), **figures)
        if s.round == 0:
            raise c.error(f"the run played no {self.position_field}")

    def spent(self) -> Spent:
        s = self.state
        return Spent(s.round, s.steps, s.seconds)

    def agent_figures(self) -> dict[str, Any]:
        s = self.state
        return {
            "agent_rule": "best-validation",
            "agent_steps": s.champion_steps,
            f"agent_{self.position_field}": s.champion_round,
            "agent_untrained": self.validated_before_learning and s.champion_round == 1,
        }

    def stop_reason(self) -> str:
        c, s = self.config, self.state
        if c.budget_steps is not None:
            (steps, unit, detail), left = self.smallest_unit(), c.budget_steps - s.steps
            if left < steps:
                return (
                    f"the {left:,} steps left cannot pay another {unit} ({steps:,} steps: {detail})"
                )
        return ""

    def figures(self) -> dict[str, Any]:
        c, s = self.config, self.state
        word = self.position_field
        return {
            "algo": c.algo,
            "robot": c.robot,
            "seed": c.seed,
            "regime": c.regime,
            "target": c.target,
            f"{word}s": s.round,
            f"champion_{word}": s.champion_round,
            "champion_validation_success_rate": s.champion_success_rate,
            **self.unseen_figures(self.final_agent()),
            "env_steps": s.steps,
            "validation_steps": s.validation_steps,
            "seconds": round(s.seconds, 3),
            "time": self.time_breakdown(),
            "mazes_ever": len(s.mazes.records),
            "members": len(s.mazes.members),
            "population_difficulty": s.mazes.mean_difficulty(),
            "target_difficulty": difficulty(c.target),
            "coevolution": self.options.to_dict(),
            "budget_steps": c.budget_steps,
            "budget_seconds": c.budget_seconds,
            **self.own_figures(),
        }

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        """The champion in the target's 4 rotations."""
        return [(f"target-rotation-{i}", m) for i, m in enumerate(rotations(self.config.target))]

    def extra_outputs(self) -> None:
        """``mazes.csv``, ``population.png`` and ``coevolution.png``."""
        c, s = self.config, self.state
        self.write_mazes_csv()
        rounds = f"{s.round} {self.position_field}s"
        title = f"maze population after {rounds} ({len(s.mazes.records)} ever)"
        save_population_png(s.mazes, self.out / "population.png", title)
        save_coevolution_plot(
            self.progress, self.out / "coevolution.png", c.target, self.batch_plot,
            title=f"{c.algo}, {c.regime}, seed {c.seed}",
        )  # fmt: skip

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        return (
            f"{summary[f'{cls.position_field}s']} {cls.position_field}s,"
            f" {summary['mazes_ever']} mazes;"
            f" unseen family mazes: success {summary['unseen_success_rate']:.3f};"
            f" {super().headline(summary)}"
        )

    # -- one round ------------------------------------------------------------

    def play_round(self) -> dict[str, Any]:
        """Learn on a batch, score its mazes, validate when due; return the ``progress.csv`` row."""
        s = self.state
        clock = Clock()
        batch = s.mazes.propose()
        mazes = [rotated for item in batch for rotated in s.mazes.generated(item.maze)]
        clock.lap("mazes")
        played = self.learn(mazes, clock)
        shape = (-1, len(batch), 4)
        success = played.success.reshape(shape)
        reward = played.normalized_reward.reshape(shape)
        results = [MazeResult.of(success[:, b], reward[:, b]) for b in range(len(batch))]
        report = s.mazes.update(batch, results)
        s.round += 1
        clock.lap("mazes")
        validation = validation_success_rate = math.nan
        if self.validation_due():
            validation, validation_success_rate = self._validate_round(played.candidates)
            clock.lap("validation")
        row = {
            **played.figures,
            "validation": validation,
            "validation_success_rate": validation_success_rate,
            "champion": s.champion_fitness,
            "champion_success_rate": s.champion_success_rate,
            "members": len(s.mazes.members),
            "admitted": report.admitted,
            "batch_difficulty": round(report.batch_difficulty, 4),
            "population_difficulty": round(s.mazes.mean_difficulty(), 4),
        }
        if "diversity" in self.progress_fields:  # a trainer's choice: quadratic in the members
            row["diversity"] = round(s.mazes.diversity(), 4)
        clock.lap("mazes")
        for part, seconds in clock.parts.items():
            s.time[part] = s.time.get(part, 0.0) + seconds
        self._tick()
        row.update({self.position_field: s.round, "steps": s.steps, "seconds": round(s.seconds, 3)})
        row = {name: row[name] for name in self.progress_fields}
        self.round_done(row)
        return row

    def validation_due(self) -> bool:
        """Whether the round just played validates its candidates: every ``validation_every``-th."""
        return (self.state.round - 1) % self.options.validation_every == 0

    def _validate_round(self, candidates: Sequence[Any]) -> tuple[float, float]:
        """Play ``candidates`` on the validation mazes; their best is champion if it beats it."""
        s = self.state
        checked = self.validate(candidates)
        best = int(np.argmax(checked.fitness))  # the first on ties
        fitness, success_rate = float(checked.fitness[best]), float(checked.success_rate[best])
        s.validation_steps += checked.env_steps
        if self.validation_spends_budget:
            s.steps += checked.env_steps
        if fitness >= s.champion_fitness:  # the latest on ties (the module docstring)
            s.champion_fitness, s.champion_success_rate = fitness, success_rate
            s.champion_round, s.champion_steps = s.round, s.steps
            self.keep_champion(candidates, best)
        return fitness, success_rate

    # -- budgets, time, checkpoints -------------------------------------------

    def check_budget(self) -> None:
        """Refuse a steps budget that cannot pay the first round (:meth:`smallest_unit`)."""
        c = self.config
        steps, unit, detail = self.smallest_unit()
        if c.budget_steps is not None and c.budget_steps < steps:
            raise c.error(
                f"budget_steps {c.budget_steps} cannot pay one {unit} ({steps} steps: {detail});"
                " give a larger budget"
            )

    def budget_left(self) -> bool:
        """Whether another round starts: the learner goes on and every budget pays it."""
        c, s = self.config, self.state
        if not self.goes_on():  # first: a stopped search has no next unit to count
            return False
        if c.budget_steps is not None and c.budget_steps - s.steps < self.smallest_unit()[0]:
            return False
        if c.budget_seconds is not None and s.seconds >= c.budget_seconds:
            return False
        limit = self.round_limit()
        return limit is None or s.round < limit

    def _tick(self) -> None:
        """Add the seconds since the last tick to the state's."""
        now = time.perf_counter()
        self.state.seconds += now - self._ticked
        self._ticked = now

    def _since(self, last: tuple[int, float]) -> tuple[int, float]:
        """Steps and seconds since ``last``."""
        return self.state.steps - last[0], self.state.seconds - last[1]

    def _done(self) -> float:
        """How much of the budget the progress bar counts is spent (steps, seconds or rounds)."""
        c, s = self.config, self.state
        if c.budget_steps is not None:
            return min(s.steps, c.budget_steps)
        if c.budget_seconds is not None:
            return min(s.seconds, c.budget_seconds)
        return s.round

    def time_breakdown(self) -> dict[str, float]:
        """Seconds spent per part of the loop; logging and checkpoints are the rest."""
        s = self.state
        parts = {k: s.time.get(k, 0.0) for k in (*self.time_parts, *LOOP_TIME_PARTS)}
        parts["logging_and_checkpoints"] = max(s.seconds - sum(parts.values()), 0.0)
        return {k: round(v, 3) for k, v in parts.items()}

    def save_checkpoint(self) -> None:
        """The trainer's files, then ``state.npz`` naming them, then ``mazes.csv``."""
        s = self.state
        self._tick()
        self.save_learner()
        s.config_sha256 = self.config_digest
        write_checkpoint(self.checkpoint, s, self.state_codec())
        self.learner_saved()
        self.write_mazes_csv()

    def write_mazes_csv(self) -> Path:
        """``mazes.csv``: every maze that was ever a member, written atomically."""
        text = mazes_csv(self.state.mazes.records)
        return write_bytes(self.out / "mazes.csv", text.encode("utf-8"))

    def unseen_figures(self, agent: Any) -> dict[str, float]:
        """``agent`` on the unseen family mazes, 4 rotations each (one episode per maze)."""
        c = self.config
        mazes = as_mazes(rotations(unseen_mazes(c.target, c.seed)))
        played = run_episodes(BatchEngine(mazes, c.robot, len(mazes)), agent)
        return {
            "unseen_success_rate": float(played.success.mean()),
            "unseen_normalized_reward": float(played.normalized_reward.mean()),
        }
