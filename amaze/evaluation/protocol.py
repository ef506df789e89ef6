"""The evaluation protocol: how every agent of this project is scored.

One function, :func:`evaluate`, takes a policy (see :mod:`amaze.evaluation.policy`: a
callable from a batch of observations to a batch of actions) and plays it on
the standard evaluation suite (:mod:`amaze.evaluation.suite`: 18 mazes x 4 rotations =
72 episodes, all stepped together on the batch engine), then runs the
input-recognition test (:mod:`amaze.evaluation.inputs`) with the suite's signs. It
returns an :class:`EvaluationReport`:

* ``success_rate``: fraction of episodes that reached the goal;
* ``normalized_reward``: mean of the paper's normalised reward R̄ (1 for an optimal
  run; the score of the paper's result tables). Run folders store it as
  ``normalized_reward``, the one renaming, made by :meth:`EvaluationReport.summary`;
* ``pretty_reward``: mean of the reference library's normalised reward;
* ``input_recognition``: fraction of all enumerated inputs handled correctly,
  with the per-class rates (empty corridor, lure, clue, trap) in
  ``input_rates``. It is ``None`` for continuous robots (their inputs are not
  enumerable) and for privileged policies that read the maze itself (the
  oracle), for which it has no meaning;
* ``paper_input_recognition``: the same answers scored as the paper's
  evaluation script scored them (the unweighted mean of the four class rates,
  lures in dead ends left out; see :mod:`amaze.evaluation.inputs`), the input
  recognition of the paper's Table 3; ``None`` where ``input_recognition`` is;

and every episode's scores, aggregated per suite maze and per column.

**Rotations.** The suite plays each of its mazes in its four rotations (start
in each corner), as training does. Other mazes are played as given by
default, one episode each; ``rotations=4`` plays each in its four rotations
(:func:`~amaze.maze.rotations`), ``rotations=1`` plays the suite's mazes in
their base orientation only. Either way the report records the count
(``EvaluationReport.rotations``, the ``rotations`` key of :meth:`~EvaluationReport.summary`),
so that every figure says how its mazes were played.

Evolved agents, SB3 agents and the built-in controllers all go through here,
so their figures are comparable. :class:`Evaluator` prepares the mazes once
(generation and compilation take longer than an evaluation) and can then
evaluate many policies; :func:`evaluate` keeps one per robot and maze list.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from amaze.agents.engine import BatchEngine
from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR, check_deadline_factor
from amaze.agents.robot import Robot, as_robot
from amaze.errors import OptionError
from amaze.evaluation.inputs import InputSet, evaluate_inputs, inputs_for_maze
from amaze.evaluation.policy import run_episodes
from amaze.evaluation.suite import PAPER_TRAINING_MAZE, EvaluationSuite, standard_suite
from amaze.maze.maze import Maze, as_maze
from amaze.maze.maze import rotations as all_rotations
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer

__all__ = [
    "ROTATIONS",
    "EpisodeResult",
    "EvaluationReport",
    "Evaluator",
    "check_rotations",
    "evaluate",
]

#: The signs of the input-recognition test: those of the suite's mazes (C1, L.25, T.5), the
#: paper's (:data:`~amaze.evaluation.inputs.PAPER_INPUT_SIGNS`).
INPUT_SIGNS_MAZE = PAPER_TRAINING_MAZE

#: How many rotations of each maze an evaluation may play: the maze as given, or all four.
ROTATIONS: tuple[int, ...] = (1, 4)
#: The rotations of the standard suite (72 episodes), those of training sets too.
SUITE_ROTATIONS = 4


@dataclass(frozen=True)
class EpisodeResult:
    """The outcome of one evaluation episode, with its maze: one row of the report's CSV.

    Unlike :class:`~amaze.evaluation.policy.EpisodeResults` (arrays, one
    finished episode per agent of a run), it is one episode of one agent, in
    plain values, labelled by its maze string, suite column and row, and start
    corner; ``normalized_reward`` is the paper's R̄ of the episode. ``maze`` is the
    maze played (a rotation, when rotations are played); for mazes outside the
    suite, ``column`` is the maze as it was given (its canonical string, shared
    by its rotations) and ``row`` is empty.
    """

    maze: str
    column: str
    row: str
    start: str
    success: bool
    normalized_reward: float
    pretty_reward: float
    steps: int
    collisions: int
    backsteps: int
    path_length: int


def _mean(values: Sequence[float]) -> float:
    return float(np.mean(values)) if len(values) else float("nan")


@dataclass(frozen=True)
class EvaluationReport:
    """Scores of one policy: aggregated figures and every episode (see the module docstring)."""

    robot: str
    episodes: tuple[EpisodeResult, ...]
    input_recognition: float | None = None
    input_rates: dict[str, float] = field(default_factory=dict)
    #: Episodes played per given maze: 1 (as given) or 4 (its four rotations).
    rotations: int = 1
    #: The input recognition as the paper's script computed it (see the module docstring).
    paper_input_recognition: float | None = None

    @property
    def success_rate(self) -> float:
        return _mean([float(e.success) for e in self.episodes])

    @property
    def normalized_reward(self) -> float:
        return _mean([e.normalized_reward for e in self.episodes])

    @property
    def pretty_reward(self) -> float:
        return _mean([e.pretty_reward for e in self.episodes])

    @property
    def mean_steps(self) -> float:
        """Mean length of the episodes in steps (a failed one lasts until its deadline)."""
        return _mean([float(e.steps) for e in self.episodes])

    def grouped(self, key: str) -> dict[Any, dict[str, float]]:
        """Success rate and mean rewards per value of an episode field (e.g. ``"column"``).

        ``key="suite_maze"`` groups by (column, row): a suite maze's 4 rotations together.
        """
        groups: dict[Any, list[EpisodeResult]] = {}
        for episode in self.episodes:
            group = (episode.column, episode.row) if key == "suite_maze" else getattr(episode, key)
            groups.setdefault(group, []).append(episode)
        return {
            group: {
                "episodes": len(items),
                "success_rate": _mean([float(e.success) for e in items]),
                "normalized_reward": _mean([e.normalized_reward for e in items]),
                "pretty_reward": _mean([e.pretty_reward for e in items]),
                "mean_steps": _mean([float(e.steps) for e in items]),
            }
            for group, items in groups.items()
        }

    def per_column(self) -> dict[str, dict[str, float]]:
        return self.grouped("column")

    def per_maze(self) -> dict[tuple[str, str], dict[str, float]]:
        """Per suite maze (column, row), its rotations together.

        A maze outside the suite is keyed ``(its string as given, "")``.
        """
        return self.grouped("suite_maze")

    def summary(self) -> dict[str, Any]:
        """The aggregated figures, JSON-ready (the keys of a run folder's ``summary.json``).

        The paper's R̄ is ``normalized_reward`` everywhere in code but
        ``normalized_reward`` in this dict: the key that ``summary.json`` files
        have always used, a file contract that must stay. This is the one place
        where the name changes; everything that writes or reads a summary
        (run folders, the training commands) goes through this dict, so no
        other code renames the reward. ``pretty_reward`` (the reference
        library's normalised reward) keeps its name. ``rotations`` says how
        each maze was played (1: as given; 4: in its four rotations).
        """
        return {
            "robot": self.robot,
            "episodes": len(self.episodes),
            "rotations": self.rotations,
            "success_rate": self.success_rate,
            "normalized_reward": self.normalized_reward,
            "pretty_reward": self.pretty_reward,
            "input_recognition": self.input_recognition,
            "input_rates": dict(self.input_rates),
            "paper_input_recognition": self.paper_input_recognition,
        }

    def played(self) -> str:
        """How the mazes were played, in words: ``18 mazes, each in its 4 rotations``."""
        mazes = len(self.episodes) // max(self.rotations, 1)
        noun = "maze" if mazes == 1 else "mazes"
        if self.rotations == 1:
            return f"{mazes} {noun}, each as given (1 rotation)"
        return f"{mazes} {noun}, each in its {self.rotations} rotations"

    def write_csv(self, path: str | Path) -> None:
        """One row per episode."""
        names = list(EpisodeResult.__dataclass_fields__)
        with open(path, "w", newline="", encoding="utf-8") as handle:
            writer = csv.DictWriter(handle, fieldnames=names)
            writer.writeheader()
            for episode in self.episodes:
                writer.writerow(asdict(episode))

    def format(self) -> str:
        """A plain-text summary: the aggregated figures and a per-column table."""
        recognition = (
            "n/a" if self.input_recognition is None else f"{100 * self.input_recognition:.1f}%"
        )
        lines = [
            f"{len(self.episodes)} episodes ({self.robot}): success {100 * self.success_rate:.1f}%,"
            f" mean R̄ {self.normalized_reward:+.3f}, mean pretty reward {self.pretty_reward:+.3f},"
            f" input recognition {recognition}",
            f"  {self.played()}",
        ]
        if self.input_rates:
            rates = ", ".join(f"{k} {100 * v:.1f}%" for k, v in self.input_rates.items())
            lines.append(f"  inputs per class: {rates}")
        if self.paper_input_recognition is not None:
            paper = 100 * self.paper_input_recognition
            lines.append(f"  input recognition as the paper scored it: {paper:.1f}%")
        columns = self.per_column()
        width = max(10, *(len(name) for name in columns))
        lines.append(f"  {'column':<{width}} {'success':>8} {'mean R̄':>8} {'pretty':>8}")
        for name, scores in columns.items():
            lines.append(
                f"  {name:<{width}} {100 * scores['success_rate']:7.1f}%"
                f" {scores['normalized_reward']:+8.3f} {scores['pretty_reward']:+8.3f}"
            )
        return "\n".join(lines)


def check_rotations(rotations: int | None, suite: bool) -> int:
    """The rotations an evaluation plays: 1 or 4; ``None`` is 4 for the suite, 1 otherwise.

    ``None`` keeps what each maze set has always meant: the standard suite is
    defined by its 72 episodes (18 mazes x 4 rotations), while a list of mazes
    is played as given (callers that want every corner pass the rotations
    themselves, from :func:`~amaze.maze.rotations`, or ``rotations=4``).
    """
    if rotations is None:
        return SUITE_ROTATIONS if suite else 1
    number = check_integer("rotations", rotations, error=OptionError)
    if number not in ROTATIONS:
        raise OptionError(
            f"rotations {rotations!r} must be 1 (each maze as given) or 4 (its four rotations)"
        )
    return number


def _suite_mazes(suite: EvaluationSuite, rotations: int) -> list[tuple[str, tuple[str, str]]]:
    """The suite's maze strings to play and their (column, row) labels."""
    if rotations == 1:
        return [(m.string, (m.column, m.row)) for m in suite.mazes]
    return [(rotated, (m.column, m.row)) for m, rotated in suite.episodes()]


def _labelled_mazes(
    mazes: EvaluationSuite | Sequence[Maze | MazeSpec | str] | None, rotations: int
) -> tuple[list[Maze], list[tuple[str, str]]]:
    """The mazes to play and their (column, row) labels.

    Mazes outside the suite are labelled by their own canonical string (one
    column each, shared by its rotations when ``rotations`` is 4).
    """
    if mazes is None:
        mazes = standard_suite()
    if isinstance(mazes, EvaluationSuite):
        labelled = _suite_mazes(mazes, rotations)
        return [Maze.from_string(text) for text, _ in labelled], [label for _, label in labelled]
    if not mazes:
        raise OptionError("evaluate: give at least one maze")
    if rotations == 1:
        generated = [as_maze(m) for m in mazes]
        return generated, [(m.to_string(), "") for m in generated]
    given = [_maze_key(m) for m in mazes]  # one seed drawn for a seedless string
    played = [(rotated, (name, "")) for name in given for rotated in all_rotations(name)]
    return [Maze.from_string(text) for text, _ in played], [label for _, label in played]


def _maze_key(maze: Maze | MazeSpec | str) -> str:
    """The canonical string of a maze, without generating it when given a string or spec."""
    if isinstance(maze, str):
        return MazeSpec.from_string(maze).to_string()
    return maze.to_string()


class Evaluator:
    """The evaluation protocol prepared for one robot and one list of mazes.

    ``mazes`` defaults to the standard suite (72 episodes); any list of mazes
    (strings, specs or mazes) can be given instead. ``rotations`` says how
    each maze is played: 1 (as given) or 4 (in its four rotations); the default
    (``None``) is 4 for the suite and 1 for a list (:func:`check_rotations`).
    ``inputs=False`` skips the input-recognition test.
    """

    def __init__(
        self,
        robot: Robot | str = "DD",
        mazes: EvaluationSuite | Sequence[Maze | MazeSpec | str] | None = None,
        *,
        rotations: int | None = None,
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
        inputs: bool = True,
    ) -> None:
        self.robot = as_robot(robot)
        deadline_factor = check_deadline_factor(deadline_factor)  # before generating mazes
        suite = mazes is None or isinstance(mazes, EvaluationSuite)
        self.rotations = check_rotations(rotations, suite)
        generated, self.labels = _labelled_mazes(mazes, self.rotations)
        self.maze_strings = [m.to_string() for m in generated]
        self.starts = [m.spec.start.shorthand for m in generated]
        self.engine = BatchEngine(
            generated, self.robot, len(generated), deadline_factor=deadline_factor
        )
        self.input_set: InputSet | None = None
        if inputs and self.robot.kind != "continuous":
            self.input_set = inputs_for_maze(INPUT_SIGNS_MAZE, self.robot)

    def __call__(self, policy: Any) -> EvaluationReport:
        return self.evaluate(policy)

    def evaluate(self, policy: Any) -> EvaluationReport:
        """Play ``policy`` once in every maze (or rotation) and run the input-recognition test."""
        results = run_episodes(self.engine, policy)
        episodes = tuple(
            EpisodeResult(
                maze=self.maze_strings[k],
                column=self.labels[k][0],
                row=self.labels[k][1],
                start=self.starts[k],
                success=bool(results.success[k]),
                normalized_reward=float(results.normalized_reward[k]),
                pretty_reward=float(results.pretty_reward[k]),
                steps=int(results.steps[k]),
                collisions=int(results.collisions[k]),
                backsteps=int(results.backsteps[k]),
                path_length=int(results.path_length[k]),
            )
            for k in range(len(self.maze_strings))
        )
        recognition, rates, paper = None, {}, None
        privileged = callable(getattr(policy, "bind", None))
        if self.input_set is not None and not privileged:
            outcome = evaluate_inputs(policy, self.input_set)
            recognition, rates = float(outcome.overall), dict(outcome.rates)
            paper = outcome.paper_input_recognition
        return EvaluationReport(
            robot=self.robot.to_string(),
            episodes=episodes,
            input_recognition=recognition,
            input_rates=rates,
            rotations=self.rotations,
            paper_input_recognition=paper,
        )


@lru_cache(maxsize=8)
def _evaluator(
    robot: str,
    mazes: tuple[str, ...] | None,
    rotations: int | None,
    deadline_factor: float,
    inputs: bool,
) -> Evaluator:
    return Evaluator(robot, list(mazes) if mazes is not None else None, rotations=rotations,
                     deadline_factor=deadline_factor, inputs=inputs)  # fmt: skip


def evaluate(
    policy: Any,
    robot: Robot | str = "DD",
    mazes: Sequence[Maze | MazeSpec | str] | None = None,
    *,
    rotations: int | None = None,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
    inputs: bool = True,
) -> EvaluationReport:
    """Score ``policy`` on the standard suite (or on ``mazes``); see the module docstring.

    Args:
        policy: a policy of :mod:`amaze.evaluation.policy`: a callable mapping a
            batch of observations to a batch of actions (saved agents, controllers,
            populations of one).
        robot: the robot the policy drives.
        mazes: the mazes to play; the standard suite's 18 when ``None``.
        rotations: 1 (each maze as given) or 4 (each in its four rotations); by
            default 4 for the suite (72 episodes) and 1 for ``mazes``.
        deadline_factor: episodes end after ``deadline_factor`` times the
            solution's length.
        inputs: also run the input-recognition test.

    Returns:
        The report of per-episode results, success rate, R̄ and input
            recognition (``summary()`` gives the figures of ``summary.json``).
    """
    key = None if mazes is None else tuple(_maze_key(m) for m in mazes)
    played = check_rotations(rotations, mazes is None)
    factor = check_deadline_factor(deadline_factor)
    evaluator = _evaluator(as_robot(robot).to_string(), key, played, factor, inputs)
    return evaluator.evaluate(policy)
