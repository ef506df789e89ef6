"""A study's runs read for its report: one row each, and their anytime evaluations.

:func:`read_runs` reads every finished run of a study: its ``summary.json``
(a row of ``runs.csv``, :data:`RUN_COLUMNS`) and its ``evaluations.csv``
(:mod:`experiments.evaluations`), whose last row gives the row's
evaluation-set figures. A run's file that cannot be read leaves out what it
would have given (:class:`LeftOut`), not the others.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from amaze.errors import one_line
from amaze.runs.config import read_json_object
from amaze.runs.lifecycle import SUMMARY_FILE
from experiments.evaluations import MAX_FIGURE, EvaluationCurve, collect_curves
from experiments.runner import StudyFolder
from experiments.study import PlannedRun, Study, StudyError

__all__ = [
    "RUN_COLUMNS",
    "LeftOut",
    "budget_share",
    "collect_rows",
    "read_runs",
    "read_summary",
    "spreadsheet_cell",
    "to_csv",
]

#: The input classes of the input-recognition test.
INPUT_CLASSES = ("empty", "lure", "clue", "trap")
RUN_COLUMNS = (
    "study",
    "treatment",
    "trainer",
    "algorithm",
    "budget",
    "condition",
    "robot",
    "seed",
    "env_steps",
    "seconds",
    "budget_unit",
    "budget_spent",
    "stopped_early",
    "wall_seconds",
    "threads",
    "core_seconds",
    "success_rate",
    "normalized_reward",
    "input_recognition",
    *(f"input_{kind}" for kind in INPUT_CLASSES),
    "paper_input_recognition",
    "paper_suite_success_rate",
    "paper_suite_normalized_reward",
    "eval_set_success_rate",
    "eval_set_normalized_reward",
    "evaluation_set",
    "validation_success_rate",
    "validation_normalized_reward",
    "advice_selections_taken",
    "advice_mazes_kept",
    "folder",
)


@dataclass(frozen=True)
class LeftOut:
    """Part of a run the report could not read, so left out: which run, what, and why."""

    run: str
    #: What is missing from the report: ``"its row"``, ``"its evaluations"``...
    what: str
    reason: str

    def __str__(self) -> str:
        return f"run {self.run}: {self.what} left out of the report: {self.reason}"


def _number(value: Any) -> float:
    """``value`` as a float if it is a number within ±:data:`MAX_FIGURE`, else NaN (an empty cell).

    NaN, infinities, ``1e308`` and integers too large for a float (``10**400``)
    are odd figures, not numbers to average.
    """
    if isinstance(value, bool) or not isinstance(value, int | float):
        return math.nan
    if isinstance(value, int) and not -MAX_FIGURE <= value <= MAX_FIGURE:
        return math.nan  # before float(), which refuses integers beyond a float's range
    number = float(value)
    return number if -MAX_FIGURE <= number <= MAX_FIGURE else math.nan


def _shown(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters, for a message."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 4]}...{text[-1]}"


def read_summary(path: Path) -> dict[str, Any]:
    """The summary in ``path``: a JSON object with its ``env_steps``; StudyError naming it else.

    ``env_steps`` must be a number in ``0 .. MAX_FIGURE``. The other figures
    are read as numbers where they are numbers within ±:data:`MAX_FIGURE`
    (a missing or odd one, such as NaN, an infinity or ``10**400``, is an
    empty cell, as for a trainer that does not report it).
    """
    summary = read_json_object(path, StudyError, "summary")
    steps = summary.get("env_steps")
    if not 0 <= _number(steps):  # NaN is not
        raise StudyError(
            f"summary {str(path)!r}: env_steps {_shown(steps)} is not a number of steps"
        )
    return summary


def budget_share(run: PlannedRun, summary: dict[str, Any]) -> float:
    """The share of its budget a run spent, in its budget's unit (``PlannedRun.budget_unit``).

    ``summary.json``'s ``budget_spent`` for that unit where it has it; else
    from its env steps or seconds against the budget (summaries written before).
    """
    unit = run.budget_unit
    recorded = summary.get("budget_spent")
    if isinstance(recorded, dict) and not math.isnan(_number(recorded.get(unit))):
        return _number(recorded[unit])
    budgets = {"steps": (run.budget_steps, "env_steps"), "seconds": (run.budget_seconds, "seconds")}
    budget, used = budgets.get(unit or "", (None, ""))
    return _number(summary.get(used)) / float(budget) if budget else math.nan


def _row(
    folder: StudyFolder,
    study: Study,
    state: dict[str, Any],
    run: PlannedRun,
    summary: dict[str, Any],
) -> dict[str, Any]:
    """The ``runs.csv`` row of a run with its summary (evaluation-set columns empty)."""
    rates = summary.get("input_rates")
    rates = rates if isinstance(rates, dict) else {}
    advice = summary.get("advice")
    advice = advice if isinstance(advice, dict) else {}
    paper = summary.get("paper_suite")  # absent in summaries written before it existed
    paper = paper if isinstance(paper, dict) else {}
    wall = _number(state["wall_seconds"].get(run.id))
    threads = state["threads"].get(run.id)
    return {
        "study": study.name,
        "treatment": run.treatment,
        "trainer": run.trainer,
        "algorithm": run.algorithm,
        "budget": run.budget,
        "condition": run.condition,
        "robot": run.config.get("robot"),
        "seed": run.seed,
        "env_steps": int(summary["env_steps"]),
        "seconds": _number(summary.get("seconds")),
        "budget_unit": run.budget_unit or "",
        "budget_spent": budget_share(run, summary),
        "stopped_early": _text(summary.get("stopped_early")),
        "wall_seconds": wall,
        "threads": threads if isinstance(threads, int) else "",
        "core_seconds": wall * threads if isinstance(threads, int) else math.nan,
        "success_rate": _number(summary.get("success_rate")),
        "normalized_reward": _number(summary.get("normalized_reward")),
        "input_recognition": _number(summary.get("input_recognition")),
        **{f"input_{kind}": _number(rates.get(kind)) for kind in INPUT_CLASSES},
        "paper_input_recognition": _number(summary.get("paper_input_recognition")),
        "paper_suite_success_rate": _number(paper.get("success_rate")),
        "paper_suite_normalized_reward": _number(paper.get("normalized_reward")),
        "eval_set_success_rate": math.nan,
        "eval_set_normalized_reward": math.nan,
        "evaluation_set": "",
        # the champion's scores on the validation mazes (co-evolution regimes): what a
        # sweep may tune on, never the suite, the evaluation set or the unseen mazes
        "validation_success_rate": _number(summary.get("champion_validation_success_rate")),
        "validation_normalized_reward": _number(
            summary.get("champion_validation_normalized_reward")
        ),
        # the shares of an advisor's proposals the run's decider took (empty: not advised)
        "advice_selections_taken": _number(advice.get("selections_taken_share")),
        "advice_mazes_kept": _number(advice.get("mazes_kept_share")),
        "folder": str(folder.run_folder(run).relative_to(folder.out)),
    }


def scored_on(rows: Sequence[dict[str, Any]], suite: str) -> list[dict[str, Any]]:
    """``rows`` whose success rate, R̄ and input recognition are those of ``suite``.

    The standard suite's are the rows' own; with ``paper`` they become the
    ``paper_suite_*`` columns and ``paper_input_recognition`` (``runs.csv``
    keeps both), so every table, test and figure of the report scores as the
    paper did.
    """
    if suite == "standard":
        return list(rows)
    return [
        {
            **row,
            "success_rate": row["paper_suite_success_rate"],
            "normalized_reward": row["paper_suite_normalized_reward"],
            "input_recognition": row["paper_input_recognition"],
        }
        for row in rows
    ]


def read_runs(
    folder: StudyFolder, study: Study, left_out: list[LeftOut]
) -> tuple[list[dict[str, Any]], list[PlannedRun], dict[str, EvaluationCurve]]:
    """The rows of the finished runs whose summary reads, those runs, and their curves.

    A run whose summary or evaluations cannot be read is added to ``left_out``.
    """
    rows, finished = [], []
    state = folder.state()
    for run in study.runs:
        path = folder.run_folder(run) / SUMMARY_FILE
        if not path.is_file():
            continue
        try:
            summary = read_summary(path)
        except StudyError as problem:
            left_out.append(LeftOut(run.id, "its row", one_line(problem)))
            continue
        rows.append(_row(folder, study, state, run, summary))
        finished.append(run)

    def unreadable(run_id: str, what: str, reason: str) -> None:
        left_out.append(LeftOut(run_id, what, reason))

    curves = collect_curves([(run, folder.run_folder(run)) for run in finished], unreadable)
    for row, run in zip(rows, finished, strict=True):
        if run.id in curves:
            curve = curves[run.id]
            row["eval_set_success_rate"] = curve.final("success_rate")
            row["eval_set_normalized_reward"] = curve.final("normalized_reward")
            row["evaluation_set"] = curve.digest
    return rows, finished, curves


def collect_rows(
    folder: StudyFolder, study: Study, left_out: list[LeftOut] | None = None
) -> list[dict[str, Any]]:
    """One row per finished run of ``study`` in ``folder`` (see :data:`RUN_COLUMNS`).

    A run whose summary cannot be read has no row; it is added to ``left_out``.
    """
    found: list[LeftOut] = []
    rows = read_runs(folder, study, found)[0]
    if left_out is not None:
        left_out += found
    return rows


#: What a spreadsheet takes for the start of a formula in a text cell.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def spreadsheet_cell(value: Any) -> Any:
    """``value`` as a cell of the report's CSV files: NaN empty, text never a formula.

    Text that starts as a formula does (``=HYPERLINK(...)``, ``+cmd|...``,
    ``@SUM(1)``, ``-2+3``, a tab or a carriage return: a summary's
    ``stopped_early``, a study's name) gets a leading ``'``, which a
    spreadsheet shows as text; numbers stay numbers, negative ones included.
    Line breaks in text become spaces: a cell is one line, and a carriage
    return can never end a row and start a formula on the next.
    """
    if isinstance(value, float) and math.isnan(value):
        return ""
    if isinstance(value, str):
        if value.startswith(FORMULA_STARTS):
            value = "'" + value
        return value.replace("\r", " ").replace("\n", " ")
    return value


def _text(value: Any) -> str:
    """A summary's text figure (``stopped_early``): a string, else empty."""
    return value if isinstance(value, str) else ""


def to_csv(rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> bytes:
    """``rows`` as CSV (UTF-8) with ``columns``, each value a :func:`spreadsheet_cell`."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: spreadsheet_cell(v) for k, v in row.items()})
    return buffer.getvalue().encode("utf-8")
