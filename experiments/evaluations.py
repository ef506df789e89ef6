"""The runs' anytime evaluations (``evaluations.csv``), read and aligned for the report.

Every run plays the agent it would hand over on one fixed evaluation set at
``N`` evenly spaced fractions of its budget (:mod:`amaze.runs.anytime`); its
last row (point ``N``) is its final agent. The report compares treatments on
that one quantity (success rate, R̄ on the evaluation set) over time:

* :func:`read_evaluations` reads one run's file (:class:`EvaluationCurve`);
* :func:`comparison_data` gathers the runs of a comparison's treatments:
  runs played on another evaluation set than the others (another digest)
  are left out with the reason, so are runs whose point grid is not their
  treatment's; each treatment's runs are aligned by point index
  (:class:`TreatmentCurves`), each point placed at the median over seeds of
  its env steps (or training seconds), and summarised by the interquartile
  mean with a 95 % stratified bootstrap band (:func:`~experiments.intervals.curve_intervals`).

A run that stopped early has no rows between its last point reached and
its final point ``N``: its agent there is its final agent, so those points
take the final row's values (the run's curve stays flat where it stopped).
"""

from __future__ import annotations

import csv
import io
import re
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from pathlib import Path

import numpy as np

from amaze.errors import one_line
from amaze.runs.anytime import EVALUATIONS_FILE
from experiments.comparisons import StudyComparison
from experiments.intervals import Bands, curve_intervals, iqm
from experiments.study import PlannedRun, StudyError

__all__ = [
    "AXES",
    "MAX_FIGURE",
    "QUANTITIES",
    "ComparisonData",
    "EvaluationCurve",
    "TreatmentCurves",
    "collect_curves",
    "comparison_data",
    "read_evaluations",
    "same_set",
]

#: The quantities of the curves: a column of ``evaluations.csv`` and its label.
QUANTITIES = {"success_rate": "success rate", "normalized_reward": "normalized reward R\u0304"}
#: The x axes: a column of ``evaluations.csv`` and its label.
AXES = {"env_steps": "environment steps", "training_seconds": "training time (s)"}
#: Columns read as numbers.
NUMBERS = ("fraction", *AXES, *QUANTITIES)
#: The most points a run's grid may have.
MAX_POINTS = 10_000
#: Largest ``evaluations.csv`` read (a row is a few hundred bytes; MAX_POINTS rows at most).
MAX_EVALUATIONS_BYTES = 16 * 2**20
#: Largest magnitude of a figure the report reads (steps, seconds, rates, rewards): beyond
#: it a value is odd (``1e308``), and means, squares and axes would overflow.
MAX_FIGURE = 1e15
#: An evaluation set's digest: 16 hexadecimal digits as runs write it; any short name of
#: ASCII letters, digits and dashes is read (it is a cell of ``runs.csv`` and a word of
#: the report).
DIGEST = re.compile(r"[A-Za-z0-9][A-Za-z0-9-]{0,63}")
#: Bootstrap resamples of a band.
REPS = 2000


@dataclass(frozen=True)
class EvaluationCurve:
    """One run's ``evaluations.csv``: a value per point (points ``1 .. N``, gaps filled)."""

    run: str
    treatment: str
    #: The evaluation set's digest (one per file).
    digest: str
    #: ``N``, the number of points of the run's grid.
    points: int
    #: The points the run took itself (the others are filled from the next one taken).
    taken: tuple[int, ...]
    #: ``columns[name]``: a float array of ``points`` values, per :data:`NUMBERS` column.
    columns: Mapping[str, np.ndarray] = field(repr=False)

    def final(self, quantity: str) -> float:
        """The final agent's figure (the last row): what the run hands over."""
        return float(self.columns[quantity][-1])


def read_evaluations(folder: Path, run: PlannedRun) -> EvaluationCurve | None:
    """The run's ``evaluations.csv`` in ``folder``; ``None`` without one (or without a row).

    :class:`~experiments.study.StudyError` naming the file when it cannot be
    read: larger than :data:`MAX_EVALUATIONS_BYTES`, not UTF-8 CSV, a
    missing column or cell, a value that is not a finite number within
    ±:data:`MAX_FIGURE`, points that do not increase, rows of several
    evaluation sets, a digest that is not one (:data:`DIGEST`).
    """
    path = folder / EVALUATIONS_FILE
    try:
        with path.open("rb") as stream:
            data = stream.read(MAX_EVALUATIONS_BYTES + 1)
        text = data.decode("utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeError) as problem:
        raise StudyError(f"evaluations {str(path)!r} cannot be read: {one_line(problem)}") from None
    if len(data) > MAX_EVALUATIONS_BYTES:
        raise StudyError(
            f"evaluations {str(path)!r} holds more than the {MAX_EVALUATIONS_BYTES:,} bytes"
            " a run's evaluations may"
        )
    try:
        rows = list(csv.DictReader(io.StringIO(text)))
        return _curve(rows, run) if rows else None
    except csv.Error as problem:
        raise StudyError(f"evaluations {str(path)!r} is not CSV: {one_line(problem)}") from None
    except KeyError as problem:
        raise StudyError(f"evaluations {str(path)!r} has no column {problem}") from None
    except ValueError as problem:
        raise StudyError(f"evaluations {str(path)!r}: {one_line(problem)}") from None


def _curve(rows: list[dict[str, str]], run: PlannedRun) -> EvaluationCurve:
    """The curve of the rows of an ``evaluations.csv`` (ValueError/KeyError when not one)."""
    for index, row in enumerate(rows, start=2):  # line 1 is the header
        if None in row or None in row.values():  # more cells than the header, or fewer
            raise ValueError(f"line {index} has more or fewer cells than the header")
    points = [_point(row["point"]) for row in rows]
    if points[0] < 1 or any(b <= a for a, b in pairwise(points)) or points[-1] > MAX_POINTS:
        raise ValueError(f"points {_cut(points)} do not increase from 1 to at most {MAX_POINTS}")
    digests = sorted({row["evaluation_set"] for row in rows})
    if len(digests) != 1:
        raise ValueError(f"rows of several evaluation sets ({_cut(list(map(_shown, digests)))})")
    if not DIGEST.fullmatch(digests[0]):
        raise ValueError(f"evaluation set {_shown(digests[0])} is not a digest")
    # point p takes the first row at or after it: a stopped run's final agent fills the gap
    filled = np.searchsorted(points, np.arange(1, points[-1] + 1))
    columns = {}
    for name in NUMBERS:
        values = np.array([_float(row[name]) for row in rows])
        bad = np.flatnonzero(~(np.abs(values) <= MAX_FIGURE))  # NaN and infinities too
        if bad.size:
            raise ValueError(f"{name} {_shown(rows[bad[0]][name])} at point {points[bad[0]]}")
        columns[name] = values[filled]
    return EvaluationCurve(run.id, run.treatment, digests[0], points[-1], tuple(points), columns)


def _point(text: str) -> int:
    """A point of the grid: a whole number of at most 18 digits (else ValueError naming it)."""
    if not (text.isascii() and text.isdigit() and len(text) <= 18):
        raise ValueError(f"point {_shown(text)} is not a whole number")
    return int(text)


def _float(text: str) -> float:
    """``text`` as a float, NaN if it is not a number (the caller names it)."""
    try:
        return float(text)
    except ValueError:
        return float("nan")


def _shown(value: object, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters, for a message."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 4]}...{text[-1]}"


def _cut(values: Sequence[object], limit: int = 6) -> str:
    shown = ", ".join(map(str, values[:limit]))
    return shown + (", ..." if len(values) > limit else "")


def same_set(curves: Sequence[EvaluationCurve]) -> tuple[str | None, list[tuple[str, str]]]:
    """The evaluation set most of ``curves`` played, and the runs that played another, with why.

    The most frequent digest (on a tie, the first met) is the reference; a
    run with another digest was not scored on the same mazes, so it cannot
    be set beside the others.
    """
    if not curves:
        return None, []
    counts = Counter(curve.digest for curve in curves)
    reference = max(counts, key=lambda digest: counts[digest])  # first met on a tie
    left = [
        (
            curve.run,
            f"played the evaluation set {curve.digest}, not {reference} as the other"
            f" {counts[reference]} run(s): not the same mazes",
        )
        for curve in curves
        if curve.digest != reference
    ]
    return reference, left


@dataclass(frozen=True)
class TreatmentCurves:
    """A treatment's runs aligned by point index: ``(runs, points)`` arrays and their x."""

    treatment: str
    runs: tuple[str, ...]
    #: ``values[column]``: (runs, points), per :data:`NUMBERS` column.
    values: Mapping[str, np.ndarray] = field(repr=False)

    @property
    def n(self) -> int:
        return len(self.runs)

    def x(self, axis: str) -> np.ndarray:
        """Each point's place on ``axis`` (a column of :data:`AXES`): the median over seeds."""
        return np.median(self.values[axis], axis=0)

    def bands(self, quantity: str, seed: int = 0) -> Bands:
        """The IQM over seeds at each point, with its 95 % stratified bootstrap band."""
        return curve_intervals(self.values[quantity], iqm, reps=REPS, seed=seed)

    def final(self, quantity: str) -> np.ndarray:
        """Each run's final figure (the last point), in the order of :attr:`runs`."""
        return self.values[quantity][:, -1]


@dataclass(frozen=True)
class ComparisonData:
    """What a comparison's figures and tables draw from: a :class:`TreatmentCurves` each."""

    comparison: StudyComparison
    #: Treatments with at least one run kept, in the comparison's order.
    treatments: tuple[TreatmentCurves, ...]
    #: The evaluation set's digest of the runs kept.
    digest: str | None
    #: ``(run, reason)`` of each finished run with an ``evaluations.csv`` left out.
    left_out: tuple[tuple[str, str], ...]
    #: Finished runs without evaluations (no ``evaluations.csv``, or one not read).
    without: tuple[str, ...]
    #: The budget on each axis of :data:`AXES` that has one (the comparison's condition's).
    budgets: Mapping[str, float] = field(default_factory=dict)


def comparison_data(
    comparison: StudyComparison,
    finished: Sequence[PlannedRun],
    curves: Mapping[str, EvaluationCurve],
) -> ComparisonData:
    """The comparison's runs among ``finished`` with their ``curves`` (by run id), aligned."""
    mine = [run for run in finished if run.treatment in comparison.treatments]
    found = [curves[run.id] for run in mine if run.id in curves]
    digest, left_out = same_set(found)
    kept = [curve for curve in found if curve.digest == digest]
    treatments = []
    for treatment in comparison.treatments:
        aligned, left = _aligned([c for c in kept if c.treatment == treatment])
        left_out += left
        if aligned is not None:
            treatments.append(aligned)
    without = tuple(run.id for run in mine if run.id not in curves)
    budgets = {}
    if mine:
        steps, seconds = mine[0].budget_steps, mine[0].budget_seconds
        budgets = {a: float(b) for a, b in zip(AXES, (steps, seconds), strict=True) if b}
    return ComparisonData(comparison, tuple(treatments), digest, tuple(left_out), without, budgets)


def _aligned(
    curves: Sequence[EvaluationCurve],
) -> tuple[TreatmentCurves | None, list[tuple[str, str]]]:
    """A treatment's curves on their common point grid (the most frequent ``N``), and those left."""
    if not curves:
        return None, []
    counts = Counter(curve.points for curve in curves)
    points = max(counts, key=lambda n: counts[n])
    kept = [curve for curve in curves if curve.points == points]
    left = [
        (
            curve.run,
            f"has {curve.points} evaluation points, the other {len(kept)} run(s) of its"
            f" treatment {points}: its points are not theirs",
        )
        for curve in curves
        if curve.points != points
    ]
    values = {name: np.vstack([curve.columns[name] for curve in kept]) for name in NUMBERS}
    return TreatmentCurves(curves[0].treatment, tuple(c.run for c in kept), values), left


#: Hears of a run's file that cannot be read: the run's id, what is left out, why.
Unreadable = Callable[[str, str, str], None]


def collect_curves(
    runs: Sequence[tuple[PlannedRun, Path]], unreadable: Unreadable
) -> dict[str, EvaluationCurve]:
    """The curve of each ``(run, its folder)`` that has one; ``unreadable`` hears of the others."""
    found = {}
    for run, folder in runs:
        try:
            curve = read_evaluations(folder, run)
        except StudyError as problem:
            what = "its evaluations (curves, evaluation-set results)"
            unreadable(run.id, what, one_line(problem))
            continue
        if curve is not None:
            found[run.id] = curve
    return found
