"""Input recognition: every discrete situation an agent may meet, with its correct action.

The paper's second evaluation shows the agent every cell content it could
perceive, one at a time, and checks the action it picks (so one wrong turn
does not spoil the rest, as it does in a maze). The inputs are enumerated from
the sign types of a maze (its clues, lures and traps), exactly as the
reference library's ``_all_inputs`` (``docs/reference-behaviour.md`` §7.1), in
its order:

* **dead ends** (three walls): for each open side, arriving from nowhere (the
  start) or through that side, without a sign and with each lure pointing to
  each other side; the correct action is the open side. ``8 (1 + 3 nL)`` inputs;
* **corridors** (two walls): for each of the 6 wall pairs and each of the two
  open sides as arrival, without a sign and with each lure pointing anywhere but
  the way out; the correct action is the other open side. ``12 (1 + 3 nL)``;
* **intersections** (one wall): for each sign direction ``j`` and arrival side
  ``k`` among the open sides, each clue pointing ``j`` (correct: ``j``; ``k``
  may equal ``j``) and, when ``j != k``, each trap pointing ``j`` (correct: the
  remaining open side). ``36 nC + 24 nT``. Optionally, intersections without a
  sign, one for each ``(j, k)`` (correct: the first open side other than ``j``
  and ``k``, a convention of the reference), left out by default.

The results are reported per (cell type, sign kind), as the reference does,
and per the paper's four classes: **empty** (dead ends and corridors without a
sign), **lure** (dead ends and corridors with a lure), **clue** (intersections
with a clue) and **trap** (intersections with a trap). The paper's own figure,
on its script's 116 inputs (:func:`paper_input_set`), is
:attr:`InputRecognition.paper_input_recognition` (``docs/evaluation.md``).

Discrete (DD) agents see the signs: the input holds the sign's lightness in the
slot of the direction it points to, as in a maze
(:func:`amaze.agents.observations.discrete_input`; the reference left it out).
Hybrid robots get the ``v x v`` image of the cell (uint8, ``round(255 x)``).
Continuous robots are not supported (their inputs depend on the position
inside the cell). Observations are in the policy format of
:mod:`amaze.evaluation.policy`, so :func:`evaluate_inputs` calls a policy once
on the whole set.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from amaze.agents.observations import discrete_input, draw_cell
from amaze.agents.robot import Robot, as_robot, robot_name
from amaze.errors import AmazeError
from amaze.maze.directions import Direction
from amaze.maze.maze import Maze
from amaze.maze.signs import Sign, SignKind
from amaze.maze.spec import MazeSpec

__all__ = [
    "CSV_COLUMNS",
    "PAPER_INPUT_SIGNS",
    "InputCase",
    "InputClass",
    "InputRecognition",
    "InputRecognitionError",
    "InputSet",
    "InputType",
    "enumerate_inputs",
    "evaluate_inputs",
    "in_paper_set",
    "inputs_for_maze",
    "paper_input_set",
]

#: Columns of the reference's ``inputs_recognition.csv`` (without its index column).
CSV_COLUMNS: tuple[str, ...] = (
    "Walls",
    "Type",
    "Sign",
    "SignType",
    "SignDirection",
    "Source",
    "Expected",
    "Action",
    "Success",
)

#: How the reference writes a missing value (no sign, no arrival side).
NO_VALUE = "None"


class InputRecognitionError(AmazeError):
    """The input-recognition test cannot be run as asked (robot, signs or policy output)."""


class InputType(StrEnum):
    """The shape of a cell, named as in the reference's ``Type`` column."""

    DEAD_END = "Dead-end"
    CORRIDOR = "Corridor"
    INTERSECTION = "Intersection"

    @classmethod
    def of_walls(cls, walls: Sequence[int]) -> InputType:
        """Three walls: dead end; two: corridor; one: intersection."""
        n = int(sum(walls))
        try:
            return {3: cls.DEAD_END, 2: cls.CORRIDOR, 1: cls.INTERSECTION}[n]
        except KeyError:
            raise InputRecognitionError(f"a cell with {n} walls is not a maze input") from None


class InputClass(StrEnum):
    """The paper's classes of inputs (plus sign-less intersections, when asked for)."""

    EMPTY = "empty"
    """A dead end or a corridor without a sign: go the only new way."""
    LURE = "lure"
    """A dead end or a corridor with a lure: ignore the sign."""
    CLUE = "clue"
    """An intersection with a clue: follow the sign."""
    TRAP = "trap"
    """An intersection with a trap: take neither the sign's way nor the way back."""
    EMPTY_INTERSECTION = "empty_intersection"
    """An intersection without a sign (optional; its correct action is a convention)."""


#: The paper's four classes, in the paper's order.
PAPER_CLASSES: tuple[InputClass, ...] = (
    InputClass.EMPTY,
    InputClass.LURE,
    InputClass.CLUE,
    InputClass.TRAP,
)


class InputCase(NamedTuple):
    """One enumerated situation: the content of a cell and the correct action there."""

    #: Walls on the sides E, N, W, S (1 = wall).
    walls: tuple[int, int, int, int]
    #: The side the agent came through (``None``: it starts there).
    arrival: Direction | None
    #: The correct action.
    expected: Direction
    #: The kind of the sign in the cell (``None``: no sign).
    kind: SignKind | None = None
    sign: Sign | None = None
    #: Where the sign points.
    sign_direction: Direction | None = None

    @property
    def input_type(self) -> InputType:
        return InputType.of_walls(self.walls)

    @property
    def input_class(self) -> InputClass:
        """The paper's class of this input."""
        if self.input_type is InputType.INTERSECTION:
            return {
                SignKind.CLUE: InputClass.CLUE,
                SignKind.TRAP: InputClass.TRAP,
                None: InputClass.EMPTY_INTERSECTION,
            }[self.kind]
        return InputClass.LURE if self.kind is SignKind.LURE else InputClass.EMPTY

    @property
    def wall_code(self) -> str:
        """The walls as the reference writes them: ``"0111"`` (E, N, W, S)."""
        return "".join(str(w) for w in self.walls)

    @property
    def type_key(self) -> tuple[str, str]:
        """The reference's statistics key: ``(Type, SignType)``, e.g. ``("Corridor", "LURE")``."""
        return self.input_type.value, _name(self.kind)


@dataclass(frozen=True, eq=False)
class InputSet:
    """Every input of the test for one robot, with the correct actions.

    ``cases[k]`` describes input ``k`` and ``observations[k]`` is what the robot
    perceives there, in the policy format (float32 ``(n, 8)`` or uint8
    ``(n, 1, v, v)``, read-only). ``clues``, ``lures`` and ``traps`` are the
    sign types the set was built from.
    """

    robot: Robot
    cases: tuple[InputCase, ...]
    observations: np.ndarray
    clues: tuple[Sign, ...] = ()
    lures: tuple[Sign, ...] = ()
    traps: tuple[Sign, ...] = ()

    def __len__(self) -> int:
        return len(self.cases)

    @property
    def expected(self) -> np.ndarray:
        """int64 ``(n,)``: the correct action of each input (0..3 = E, N, W, S)."""
        return np.array([int(case.expected) for case in self.cases], dtype=np.int64)

    @property
    def walls(self) -> np.ndarray:
        """uint8 ``(n, 4)``: the walls E, N, W, S of each input."""
        return np.array([case.walls for case in self.cases], dtype=np.uint8).reshape(-1, 4)

    @property
    def arrivals(self) -> np.ndarray:
        """int64 ``(n,)``: the arrival side of each input, -1 where there is none."""
        return np.array([_side(case.arrival) for case in self.cases], dtype=np.int64)

    @property
    def sign_directions(self) -> np.ndarray:
        """int64 ``(n,)``: where each input's sign points, -1 where there is no sign."""
        return np.array([_side(case.sign_direction) for case in self.cases], dtype=np.int64)

    @property
    def input_types(self) -> tuple[InputType, ...]:
        return tuple(case.input_type for case in self.cases)

    @property
    def classes(self) -> tuple[InputClass, ...]:
        """The paper's class of each input."""
        return tuple(case.input_class for case in self.cases)

    def totals(self) -> dict[InputClass, int]:
        """How many inputs each class holds (classes without inputs are left out)."""
        totals: dict[InputClass, int] = {}
        for input_class in self.classes:
            totals[input_class] = totals.get(input_class, 0) + 1
        return {c: totals[c] for c in InputClass if c in totals}


# -- enumeration ---------------------------------------------------------------------


def enumerate_inputs(
    robot: Robot | str,
    clues: Iterable[Sign | str] = (),
    lures: Iterable[Sign | str] = (),
    traps: Iterable[Sign | str] = (),
    *,
    empty_intersections: bool = False,
) -> InputSet:
    """All inputs for these sign types, in the reference's order (see the module docstring).

    ``robot`` is a discrete (``DD``) or hybrid (``H15``...) robot; signs are
    :class:`~amaze.maze.signs.Sign` objects or sign strings (``"1"``, ``"point-.5"``).
    ``empty_intersections`` adds the sign-less intersections.

    :raises InputRecognitionError: for a continuous robot or a value that is not a sign.
    """
    name = robot_name(robot)
    robot = as_robot(robot)
    if not robot.discrete_outputs:
        raise InputRecognitionError(
            f"robot {name}: the input-recognition test needs discrete actions"
            " (a DD or hybrid robot); continuous inputs cannot be enumerated"
        )
    clues = _as_signs("clues", clues)
    lures = _as_signs("lures", lures)
    traps = _as_signs("traps", traps)
    if not isinstance(empty_intersections, bool):
        raise InputRecognitionError(f"empty_intersections={empty_intersections!r} is not a bool")
    cases = tuple(_all_cases(clues, lures, traps, empty_intersections))
    observations = _observations(robot, cases)
    observations.flags.writeable = False
    return InputSet(robot, cases, observations, clues, lures, traps)


def inputs_for_maze(
    maze: Maze | MazeSpec | str, robot: Robot | str, *, empty_intersections: bool = False
) -> InputSet:
    """All inputs for the sign types of a maze (a :class:`Maze`, its spec or its string).

    The sign lists are the spec's: as in maze generation, lures (traps) only
    count when the maze has a lure (trap) probability.
    """
    if isinstance(maze, Maze):
        spec = maze.spec
    elif isinstance(maze, MazeSpec):
        spec = maze
    elif isinstance(maze, str):
        spec = MazeSpec.from_string(maze)
    else:
        raise InputRecognitionError(f"expected a Maze, a MazeSpec or a maze string, not {maze!r}")
    return enumerate_inputs(
        robot, spec.clue, spec.lure, spec.trap, empty_intersections=empty_intersections
    )


#: The signs of the paper's input set: one clue, one lure, one trap (their lightness).
PAPER_INPUT_SIGNS: tuple[str, str, str] = ("1", ".25", ".5")


def in_paper_set(case: InputCase) -> bool:
    """Whether the paper's script shows this kind of input: all but lures in dead ends."""
    return not (case.kind is SignKind.LURE and case.input_type is InputType.DEAD_END)


def paper_input_set(robot: Robot | str) -> InputSet:
    """The inputs of the paper's evaluation script, in its order: 116 for one sign of each kind.

    Dead ends (started in and arrived at), corridors with and without a lure
    pointing anywhere but the way out, intersections with a clue or a trap
    (``eval.py``'s ``generate_inputs`` as of commit 6cb352f; see the module
    docstring). For a DD robot the observations are the script's arrays.
    """
    clue, lure, trap = PAPER_INPUT_SIGNS
    full = enumerate_inputs(robot, [clue], [lure], [trap])
    keep = [in_paper_set(case) for case in full.cases]
    observations = full.observations[np.array(keep)]
    observations.flags.writeable = False
    cases = tuple(case for case, kept in zip(full.cases, keep, strict=True) if kept)
    return InputSet(full.robot, cases, observations, full.clues, full.lures, full.traps)


def _as_signs(name: str, signs: object) -> tuple[Sign, ...]:
    if isinstance(signs, (str, Sign)) or not isinstance(signs, Iterable):
        raise InputRecognitionError(f"{name} must be a sequence of signs, not {signs!r}")
    result = []
    for sign in signs:
        if isinstance(sign, str):
            sign = Sign.from_string(sign)
        if not isinstance(sign, Sign):
            raise InputRecognitionError(f"{name}: {sign!r} is neither a Sign nor a sign string")
        result.append(sign)
    return tuple(result)


def _all_cases(
    clues: tuple[Sign, ...],
    lures: tuple[Sign, ...],
    traps: tuple[Sign, ...],
    empty_intersections: bool,
) -> Iterable[InputCase]:
    """The reference's ``_all_inputs``; side sets are walked in ascending order as it does."""
    d = Direction
    sides = range(4)

    def walls_of(walled: Iterable[int]) -> tuple[int, int, int, int]:
        walled = set(walled)
        return tuple(int(s in walled) for s in sides)  # type: ignore[return-value]

    # Dead ends: one open side, the way out.
    for exit_ in sides:
        walls = walls_of(s for s in sides if s != exit_)
        for arrival in (None, d(exit_)):
            yield InputCase(walls, arrival, d(exit_))
            for lure in lures:
                for pointing in (s for s in sides if s != exit_):
                    yield InputCase(walls, arrival, d(exit_), SignKind.LURE, lure, d(pointing))

    # Corridors: two open sides, in through one, out through the other.
    for first in range(3):
        for second in range(first + 1, 4):
            walls = walls_of((first, second))
            openings = [s for s in sides if s not in (first, second)]
            for arrival in openings:
                exit_ = next(s for s in openings if s != arrival)
                yield InputCase(walls, d(arrival), d(exit_))
                for lure in lures:
                    for pointing in (s for s in sides if s != exit_):
                        yield InputCase(
                            walls, d(arrival), d(exit_), SignKind.LURE, lure, d(pointing)
                        )

    # Intersections: one wall; a sign pointing j, arrival through k.
    for wall in sides:
        walls = walls_of((wall,))
        openings = [s for s in sides if s != wall]
        for j in openings:
            for k in openings:
                for clue in clues:
                    yield InputCase(walls, d(k), d(j), SignKind.CLUE, clue, d(j))
                remaining = next(s for s in openings if s not in (j, k))
                if j != k:
                    for trap in traps:
                        yield InputCase(walls, d(k), d(remaining), SignKind.TRAP, trap, d(j))
                if empty_intersections:
                    yield InputCase(walls, d(k), d(remaining))


def _observations(robot: Robot, cases: Sequence[InputCase]) -> np.ndarray:
    """The policy-format observations of ``cases`` for ``robot``."""
    if robot.discrete_inputs:
        obs = np.zeros((len(cases), 8), dtype=np.float32)
        for k, case in enumerate(cases):
            value = None if case.sign is None else case.sign.value
            obs[k] = discrete_input(
                case.walls, _opt_int(case.arrival), value, _opt_int(case.sign_direction)
            )
        return obs
    v = int(robot.vision)
    images = np.zeros((len(cases), 1, v, v), dtype=np.uint8)
    for k, case in enumerate(cases):
        image = draw_cell(
            case.walls,
            v,
            _opt_int(case.arrival),
            case.sign,
            _opt_int(case.sign_direction),
        )
        images[k, 0] = np.rint(image * 255.0).astype(np.uint8)
    return images


def _opt_int(direction: Direction | None) -> int | None:
    return None if direction is None else int(direction)


def _side(direction: Direction | None) -> int:
    return -1 if direction is None else int(direction)


def _name(value: Direction | SignKind | None) -> str:
    """Enum names as the reference writes them (``EAST``, ``LURE``), ``"None"`` for none."""
    return NO_VALUE if value is None else value.name


# -- evaluation -----------------------------------------------------------------------


def evaluate_inputs(policy: Any, inputs: InputSet) -> InputRecognition:
    """Show every input of ``inputs`` to ``policy`` (one batch call) and score its actions.

    The policy gets a writable copy of the observations; if it has a
    ``reset(n_agents)`` method it is called first, so that a recurrent policy
    meets each input afresh. ``bind`` is not called: there is no maze.

    :raises InputRecognitionError: if the policy does not return one action 0..3 per input.
    """
    if not isinstance(inputs, InputSet):
        raise InputRecognitionError(f"expected an InputSet, not {inputs!r}")
    n = len(inputs)
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset(n)
    actions = np.asarray(policy(inputs.observations.copy()))
    if actions.size != n:
        raise InputRecognitionError(f"the policy returned {actions.size} actions for {n} inputs")
    actions = actions.reshape(n)
    if not np.issubdtype(actions.dtype, np.integer):
        raise InputRecognitionError(
            f"discrete actions must be integers, the policy returned {actions.dtype}"
        )
    bad = (actions < 0) | (actions > 3)
    if bad.any():
        raise InputRecognitionError(
            f"action {actions[bad][0]!r} is not a direction 0..3 (E, N, W, S)"
        )
    actions = actions.astype(np.int64)
    actions.flags.writeable = False
    return InputRecognition(inputs, actions)


@dataclass(frozen=True, eq=False)
class InputRecognition:
    """The actions a policy chose on an :class:`InputSet`, and how many were correct.

    Rates are fractions in [0, 1]. Per class: ``rates`` (the paper's classes,
    and ``empty_intersection`` when the set has them), with ``counts`` (correct
    inputs) and ``totals``. Per (cell type, sign kind) as the reference:
    ``rates_per_type`` etc., keyed like ``("Corridor", "LURE")`` or
    ``("Dead-end", "None")``. ``overall`` is the fraction of all inputs handled
    correctly; ``class_average`` the mean of the rates of the paper's classes
    present, so that each class weighs the same whatever its number of inputs.
    """

    inputs: InputSet
    actions: np.ndarray

    def __len__(self) -> int:
        return len(self.inputs)

    @property
    def success(self) -> np.ndarray:
        """bool ``(n,)``: whether each input got its correct action."""
        return self.actions == self.inputs.expected

    def _tally(self, keys: Sequence[Any]) -> tuple[dict[Any, int], dict[Any, int]]:
        correct: dict[Any, int] = {}
        totals: dict[Any, int] = {}
        for key, ok in zip(keys, self.success, strict=True):
            totals[key] = totals.get(key, 0) + 1
            correct[key] = correct.get(key, 0) + int(ok)
        return correct, totals

    @property
    def counts(self) -> dict[InputClass, int]:
        """Correct inputs per class (classes present in the set only)."""
        correct, totals = self._tally(self.inputs.classes)
        return {c: correct[c] for c in InputClass if c in totals}

    @property
    def totals(self) -> dict[InputClass, int]:
        """Inputs per class (classes present in the set only)."""
        return self.inputs.totals()

    @property
    def rates(self) -> dict[InputClass, float]:
        """Fraction of correct inputs per class (classes present in the set only)."""
        correct, totals = self._tally(self.inputs.classes)
        return {c: correct[c] / totals[c] for c in InputClass if c in totals}

    @property
    def counts_per_type(self) -> dict[tuple[str, str], int]:
        """Correct inputs per ``(Type, SignType)``, in the order of first appearance."""
        return self._tally([case.type_key for case in self.inputs.cases])[0]

    @property
    def totals_per_type(self) -> dict[tuple[str, str], int]:
        """Inputs per ``(Type, SignType)``, in the order of first appearance."""
        return self._tally([case.type_key for case in self.inputs.cases])[1]

    @property
    def rates_per_type(self) -> dict[tuple[str, str], float]:
        """Fraction of correct inputs per ``(Type, SignType)`` (the reference's ``ratios``)."""
        correct, totals = self._tally([case.type_key for case in self.inputs.cases])
        return {key: correct[key] / totals[key] for key in totals}

    @property
    def overall(self) -> float:
        """Fraction of all inputs handled correctly."""
        return float(self.success.mean()) if len(self) else math.nan

    @property
    def class_average(self) -> float:
        """Mean rate of the paper's four classes present in the set."""
        rates = [rate for c, rate in self.rates.items() if c in PAPER_CLASSES]
        return float(np.mean(rates)) if rates else math.nan

    @property
    def paper_rates(self) -> dict[InputClass, float]:
        """Rates of the paper's classes over the inputs its script shows (:func:`in_paper_set`)."""
        correct: dict[InputClass, int] = {}
        totals: dict[InputClass, int] = {}
        for case, ok in zip(self.inputs.cases, self.success, strict=True):
            if case.input_class in PAPER_CLASSES and in_paper_set(case):
                totals[case.input_class] = totals.get(case.input_class, 0) + 1
                correct[case.input_class] = correct.get(case.input_class, 0) + int(ok)
        return {c: correct[c] / totals[c] for c in PAPER_CLASSES if c in totals}

    @property
    def paper_input_recognition(self) -> float:
        """The paper's input recognition: the unweighted mean of :attr:`paper_rates`.

        Its script's "All"; on a set enumerated for the paper's signs
        (:data:`PAPER_INPUT_SIGNS`), the same answers scored on
        :func:`paper_input_set`.
        """
        rates = list(self.paper_rates.values())
        return float(np.mean(rates)) if rates else math.nan

    def summary(self) -> dict[str, Any]:
        """A JSON-ready digest: overall and class-average rates, per-class and per-type figures."""
        return {
            "robot": self.inputs.robot.to_string(),
            "n_inputs": len(self),
            "overall": self.overall,
            "class_average": self.class_average,
            "paper_input_recognition": self.paper_input_recognition,
            "rates": {c.value: r for c, r in self.rates.items()},
            "counts": {c.value: n for c, n in self.counts.items()},
            "totals": {c.value: n for c, n in self.totals.items()},
            "rates_per_type": {"|".join(k): r for k, r in self.rates_per_type.items()},
        }

    def rows(self) -> list[list[str]]:
        """One row of strings per input, in :data:`CSV_COLUMNS` (the reference's format)."""
        rows = []
        for case, action, ok in zip(self.inputs.cases, self.actions, self.success, strict=True):
            rows.append(
                [
                    case.wall_code,
                    case.input_type.value,
                    NO_VALUE if case.sign is None else case.sign.to_string(),
                    _name(case.kind),
                    _name(case.sign_direction),
                    _name(case.arrival),
                    _name(case.expected),
                    _name(Direction(int(action))),
                    str(bool(ok)),
                ]
            )
        return rows

    def write_csv(self, path: str | os.PathLike) -> Path:
        """Write :meth:`rows` with a header line to ``path`` (folders are created)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", newline="") as stream:
            writer = csv.writer(stream)
            writer.writerow(CSV_COLUMNS)
            writer.writerows(self.rows())
        return path
