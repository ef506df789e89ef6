"""A study's comparisons: which treatments one figure of its report sets side by side.

A study file declares them as ``[[comparisons]]`` tables (see
:mod:`experiments.study`)::

    [[comparisons]]
    name = "regimes-ppo"             # letters, digits, dashes: the figures' file names
    title = "Regimes with PPO"       # optional (default: made from the name)
    budget = "steps"                 # one of the study's [budgets]; optional when it has one
    robot = "H15"                    # optional; see below
    treatments = ["direct/ppo", "interpolation/ppo", "edhucat-careful/ppo"]
    pairs = [["interpolation/ppo", "direct/ppo"]]

``treatments`` are 1 to :data:`MAX_LINES` trainer/algorithm cells of the grid
(one line each in a panel: more would not be read); ``pairs`` the pairs of
them whose probability of improvement the report gives, first over second
(default: the pairs that differ in one factor, trainer or algorithm, else
every pair; ``pairs = []``: none). In a study of several robots, ``robot``
picks one; without it, the comparison is made once per robot, named
``name-robot``. Each value is checked, and a bad one is a
:class:`~experiments.study.StudyError` naming it, when the study is read.

A study without ``[[comparisons]]`` gets :func:`default_comparisons`: per
budget (and robot), the algorithms within each trainer and the trainers with
each algorithm.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import combinations
from typing import Any, NamedTuple

__all__ = [
    "COMPARISON_KEYS",
    "MAX_LINES",
    "Grid",
    "StudyComparison",
    "default_comparisons",
    "is_name",
    "is_text",
    "key_shown",
    "one_factor_pairs",
    "parse_comparisons",
]

#: Most treatments in one comparison: the lines of one panel.
MAX_LINES = 8
#: The keys of a ``[[comparisons]]`` table.
COMPARISON_KEYS = frozenset({"name", "title", "budget", "robot", "treatments", "pairs"})
#: Most comparisons a study declares.
MAX_COMPARISONS = 200
#: Longest title of a comparison (a heading of the report).
MAX_TITLE = 200

#: How a value's problem becomes the error naming the study file.
Bad = Callable[[str], Exception]

#: A name in a study (a budget's, a comparison's): it becomes part of file names and
#: of the report's CSV files, so ASCII letters, digits and dashes, starting with a
#: letter or a digit, at most 64 characters.
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9-]{0,63}")
#: What a message says a name is.
NAME_RULE = "made of letters, digits and dashes (ASCII, at most 64, starting with no dash)"


def is_name(value: Any) -> bool:
    """Whether ``value`` is a name of :data:`NAME`'s form."""
    return isinstance(value, str) and NAME.fullmatch(value) is not None


def is_text(value: Any, lines: bool = False) -> bool:
    """Whether ``value`` is a printable string: no control or format character (an escape,
    a bidi override); ``lines``: tabs and newlines allowed. A terminal, the report and a
    spreadsheet show such a string as it is."""
    if not isinstance(value, str):
        return False
    if lines:
        value = value.translate(dict.fromkeys(map(ord, "\t\r\n"), " "))
    return value.isprintable()


def key_shown(key: str) -> str:
    """A key of a table as a message names it: as it is when short printable text, else
    escaped (``'\\x1b[2J'``)."""
    return key if key and len(key) <= 64 and is_text(key) else ascii(key)


class Grid(NamedTuple):
    """What a study's comparisons may name: its budgets, robots and trainer/algorithm cells."""

    budgets: tuple[str, ...]
    robots: tuple[str, ...]
    cells: tuple[tuple[str, str], ...]

    def condition(self, budget: str, robot: str) -> str:
        """The condition of ``budget`` for ``robot`` (as :class:`~experiments.study.PlannedRun`)."""
        return budget if len(self.robots) == 1 else f"{budget}-{robot}"


@dataclass(frozen=True)
class StudyComparison:
    """What one figure of the report compares: treatments of one condition, and pairs of them."""

    name: str
    title: str
    #: The condition all its treatments share (the budget, with the robot when several).
    condition: str
    #: Full treatment names (``trainer/algorithm/condition``), at most :data:`MAX_LINES`.
    treatments: tuple[str, ...]
    #: The pairs (first, second) whose probability of improvement is reported.
    pairs: tuple[tuple[str, str], ...]
    #: ``True`` when the study file declared it, ``False`` for a default one.
    declared: bool = True


def _shown(value: Any, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 5]}...{text[-1]}"


def parse_comparisons(value: Any, grid: Grid, bad: Bad) -> tuple[StudyComparison, ...]:
    """The study's ``[[comparisons]]``, checked against its ``grid``; ``bad`` makes the errors."""
    if not isinstance(value, list) or not all(isinstance(c, dict) for c in value):
        raise bad(f"comparisons {_shown(value)} is not a list of tables ([[comparisons]])")
    if len(value) > MAX_COMPARISONS:
        raise bad(f"{len(value)} comparisons: a study declares at most {MAX_COMPARISONS}")
    found: list[StudyComparison] = []
    for index, table in enumerate(value):
        found += _comparison(table, index, grid, bad)
    names = [c.name for c in found]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise bad(f"comparisons: the name(s) {', '.join(map(repr, repeated))} are used twice")
    return tuple(found)


def _comparison(table: dict, index: int, grid: Grid, bad: Bad) -> list[StudyComparison]:
    """One ``[[comparisons]]`` table: a comparison per robot it covers."""
    where = f"comparisons[{index}]"
    unknown = set(table) - COMPARISON_KEYS
    if unknown:
        raise bad(
            f"{where}: unknown key(s) {', '.join(key_shown(k) for k in sorted(unknown))}"
            f" (known: {', '.join(sorted(COMPARISON_KEYS))})"
        )
    name = table.get("name")
    if not is_name(name):
        raise bad(f"{where}: name {_shown(name)} is not {NAME_RULE}")
    where = f"comparison {name!r}"
    title = table.get("title", name.replace("-", " "))
    if not isinstance(title, str) or not title.strip():
        raise bad(f"{where}: title {_shown(title)} is not a non-empty string")
    if len(title) > MAX_TITLE:
        raise bad(f"{where}: title {_shown(title)} is longer than {MAX_TITLE} characters")
    if not is_text(title):
        raise bad(f"{where}: title {_shown(title)} holds control characters")
    budget = _budget(table, grid, where, bad)
    robots = _robots(table, grid, where, bad)
    cells = _cells(table.get("treatments"), grid, where, bad)
    pairs = _pairs(table.get("pairs"), cells, where, bad)
    found = []
    for robot in robots:
        condition = grid.condition(budget, robot)
        suffix = "" if len(robots) == 1 or "robot" in table else f"-{robot}"
        found.append(
            StudyComparison(
                name + suffix,
                title.strip() + (f", {robot}" if suffix else ""),
                condition,
                tuple(f"{cell}/{condition}" for cell in cells),
                tuple((f"{a}/{condition}", f"{b}/{condition}") for a, b in pairs),
            )
        )
    return found


def _budget(table: dict, grid: Grid, where: str, bad: Bad) -> str:
    budget = table.get("budget")
    if budget is None and len(grid.budgets) == 1:
        return grid.budgets[0]
    if budget is None:
        raise bad(f"{where}: no budget (the study has several: {', '.join(grid.budgets)})")
    if not isinstance(budget, str) or budget not in grid.budgets:
        raise bad(
            f"{where}: budget {_shown(budget)} is not one of the study's budgets"
            f" ({', '.join(grid.budgets)})"
        )
    return budget


def _robots(table: dict, grid: Grid, where: str, bad: Bad) -> tuple[str, ...]:
    if "robot" not in table:
        return grid.robots
    robot = table["robot"]
    if not isinstance(robot, str) or robot not in grid.robots:
        raise bad(
            f"{where}: robot {_shown(robot)} is not one of the study's robots"
            f" ({', '.join(grid.robots)})"
        )
    return (robot,)


def _cells(value: Any, grid: Grid, where: str, bad: Bad) -> list[str]:
    """The comparison's ``trainer/algorithm`` cells, each in the grid, 1 to MAX_LINES of them."""
    if not isinstance(value, list) or not value:
        raise bad(f"{where}: treatments {_shown(value)} is not a non-empty list")
    if len(value) > MAX_LINES:
        raise bad(
            f"{where}: {len(value)} treatments; a comparison holds at most {MAX_LINES}"
            " (the lines one panel can show): split it"
        )
    known = {f"{t}/{a}" for t, a in grid.cells}
    for cell in value:
        if not isinstance(cell, str) or cell not in known:
            raise bad(
                f"{where}: treatment {_shown(cell)} is not a trainer/algorithm cell of the study"
                f" (cells: {_shown(', '.join(sorted(known)), 200)})"
            )
    if len(set(value)) != len(value):
        raise bad(f"{where}: treatments {_shown(value)} names one twice")
    return list(value)


def _pairs(value: Any, cells: Sequence[str], where: str, bad: Bad) -> list[tuple[str, str]]:
    """The pairs given (each two distinct cells of the comparison), or the default pairs."""
    if value is None:
        return one_factor_pairs(cells)
    if not isinstance(value, list):
        raise bad(f"{where}: pairs {_shown(value)} is not a list of [first, second] pairs")
    pairs = []
    for pair in value:
        if not (isinstance(pair, list) and len(pair) == 2):
            raise bad(f"{where}: pair {_shown(pair)} is not a [first, second] pair")
        for cell in pair:
            if cell not in cells:
                raise bad(
                    f"{where}: pair {_shown(pair)}: {_shown(cell)} is not one of the"
                    f" comparison's treatments ({', '.join(cells)})"
                )
        if pair[0] == pair[1]:
            raise bad(f"{where}: pair {_shown(pair)} compares a treatment with itself")
        pairs.append((pair[0], pair[1]))
    if len(set(pairs)) != len(pairs):
        raise bad(f"{where}: pairs {_shown(value)} names a pair twice")
    return pairs


def one_factor_pairs(cells: Sequence[str]) -> list[tuple[str, str]]:
    """The pairs of ``cells`` that differ in one factor (trainer or algorithm), else every pair."""
    every = list(combinations(cells, 2))
    split = [tuple(cell.split("/")) for cell in cells]
    one = [
        (a, b)
        for (a, b), (x, y) in zip(every, combinations(split, 2), strict=True)
        if (x[0] == y[0]) != (x[1] == y[1])
    ]
    return one or every


def default_comparisons(grid: Grid) -> tuple[StudyComparison, ...]:
    """Per budget and robot: the algorithms within each trainer, the trainers with each algorithm.

    Groups of one cell are left out; the cells in no group (alone with their
    trainer and their algorithm) make one more group. Groups are cut into
    parts of at most :data:`MAX_LINES`.
    """
    found = []
    for budget in grid.budgets:
        for robot in grid.robots:
            condition = grid.condition(budget, robot)
            for name, title, cells in _default_groups(grid.cells):
                treatments = tuple(f"{cell}/{condition}" for cell in cells)
                pairs = tuple(
                    (f"{a}/{condition}", f"{b}/{condition}") for a, b in one_factor_pairs(cells)
                )
                found.append(
                    StudyComparison(
                        f"{name}-{condition}",
                        f"{title} ({condition})",
                        condition,
                        treatments,
                        pairs,
                        declared=False,
                    )
                )
    return tuple(found)


def _default_groups(cells: Sequence[tuple[str, str]]) -> list[tuple[str, str, list[str]]]:
    """(name, title, cells) of :func:`default_comparisons`, each at most MAX_LINES cells."""
    trainers = list(dict.fromkeys(t for t, _ in cells))
    algorithms = list(dict.fromkeys(a for _, a in cells))
    groups = [
        (
            f"algorithms-{trainer}",
            f"Algorithms with {trainer}",
            [c for c in cells if c[0] == trainer],
        )
        for trainer in trainers
    ]
    groups += [
        (
            f"trainers-{algorithm}",
            f"Trainers with {algorithm.upper()}",
            [c for c in cells if c[1] == algorithm],
        )
        for algorithm in algorithms
    ]
    kept = [group for group in groups if len(group[2]) > 1]
    covered = {cell for _, _, mine in kept for cell in mine}
    alone = [cell for cell in cells if cell not in covered]
    if alone:
        kept.append(("others" if kept else "all", "Others" if kept else "All", alone))
    found = []
    for name, title, mine in kept:
        names = [f"{t}/{a}" for t, a in mine]
        parts = range(0, len(names), MAX_LINES)
        for part, start in enumerate(parts):
            suffix = f"-{part + 1}" if len(parts) > 1 else ""
            found.append((name + suffix, title + suffix, names[start : start + MAX_LINES]))
    return found
