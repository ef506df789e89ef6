"""A study's report: every number recomputed from its runs' ``summary.json`` files.

``amaze-experiment report DIR`` (:func:`write_report`) writes, in ``DIR``:

* ``runs.csv``: one row per finished run (study, treatment, trainer,
  algorithm, condition, robot, seed, env steps, seconds, wall-clock and
  core-seconds, suite success, R̄, input recognition and its rate per input
  class, the run's folder);
* ``tests.csv``: every pairwise comparison (:mod:`experiments.stats`);
* ``figures/``: distributions of R̄ and success per treatment, input
  recognition per class, learning curves (against env steps and wall-clock
  seconds) and the best agent's trajectories;
* ``report.md``: the paper's Table 3 for the study (maximum and median of R̄,
  success and input recognition per trainer x algorithm, best in bold,
  second in italics) with the paper's own numbers beside it
  (:mod:`experiments.paper`), the significant pairwise differences, the
  figures and the compute each treatment took.

Pairs are compared when they differ in one factor (trainer or algorithm)
under the same condition: the comparisons a reader makes, and a family small
enough for the correction to leave some power.

A run's file that cannot be read (a damaged ``summary.json``, a
``progress.csv`` that is not a progress log, a trajectory picture that is
not a picture) does not stop the report of the others: what it would have
given is left out, and the report says so, run by run, with the reason
(:class:`LeftOut`: a section of ``report.md``, and a warning each for the
command). A file of the study itself (``study.toml``, ``state.json``) that
cannot be read is an error: without it there is no report to write.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from amaze.errors import one_line
from amaze.runs.config import read_json_object
from amaze.runs.folder import write_bytes
from amaze.runs.lifecycle import SUMMARY_FILE
from experiments.paper import PAPER_CITATION, PAPER_TABLE3, paper_trainer
from experiments.runner import StudyFolder
from experiments.stats import Comparison, compare_pairs
from experiments.study import PlannedRun, Study, StudyError

__all__ = ["METRICS", "LeftOut", "collect_rows", "read_summary", "table3", "write_report"]

#: The metrics of Table 3, in the paper's order, with their labels.
METRICS = {
    "normalized_reward": "Normalized reward R̄",
    "success_rate": "Success rate",
    "input_recognition": "Input recognition",
}
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
    "budget_spent",
    "stopped_early",
    "wall_seconds",
    "threads",
    "core_seconds",
    "success_rate",
    "normalized_reward",
    "input_recognition",
    *(f"input_{kind}" for kind in INPUT_CLASSES),
    "folder",
)


@dataclass(frozen=True)
class LeftOut:
    """Part of a run the report could not read, so left out: which run, what, and why."""

    run: str
    #: What is missing from the report: ``"its row"``, ``"its learning curve"``...
    what: str
    reason: str

    def __str__(self) -> str:
        return f"run {self.run}: {self.what} left out of the report: {self.reason}"


def _number(value: Any) -> float:
    return (
        float(value) if isinstance(value, int | float) and not isinstance(value, bool) else math.nan
    )


def read_summary(path: Path) -> dict[str, Any]:
    """The summary in ``path``: a JSON object with its ``env_steps``; StudyError naming it else.

    The other figures are read as numbers where they are numbers (a missing
    or odd one is an empty cell, as for a trainer that does not report it).
    """
    summary = read_json_object(path, StudyError, "summary")
    steps = summary.get("env_steps")
    if isinstance(steps, bool) or not isinstance(steps, int | float) or not 0 <= steps < math.inf:
        raise StudyError(f"summary {str(path)!r}: env_steps {steps!r} is not a number of steps")
    return summary


#: Treatments whose median budget spent differs from the rest of their condition by more
#: than this (a share of the budget) are flagged: their comparison is not at equal budget.
BUDGET_TOLERANCE = 0.10


def budget_spent(run: PlannedRun, summary: dict[str, Any]) -> float:
    """The share of its budget a run spent: the most of any budget it was given.

    ``summary.json``'s ``budget_spent`` where it has one; else from its env
    steps and seconds against the run's budgets (summaries written before).
    """
    recorded = summary.get("budget_spent")
    if isinstance(recorded, dict):
        shares = [_number(v) for v in recorded.values()]
        shares = [share for share in shares if not math.isnan(share)]
        if shares:
            return max(shares)
    shares = []
    for budget, used in ((run.budget_steps, "env_steps"), (run.budget_seconds, "seconds")):
        if budget:
            shares.append(_number(summary.get(used)) / float(budget))
    return max(shares) if shares else math.nan


def collect_rows(
    folder: StudyFolder, study: Study, left_out: list[LeftOut] | None = None
) -> list[dict[str, Any]]:
    """One row per finished run of ``study`` in ``folder`` (see :data:`RUN_COLUMNS`).

    A run whose summary cannot be read has no row; it is added to ``left_out``.
    """
    state = folder.state()
    rows = []
    for run in study.runs:
        path = folder.run_folder(run) / SUMMARY_FILE
        if not path.is_file():
            continue
        try:
            summary = read_summary(path)
        except StudyError as problem:
            if left_out is not None:
                left_out.append(LeftOut(run.id, "its row", one_line(problem)))
            continue
        rates = summary.get("input_rates")
        rates = rates if isinstance(rates, dict) else {}
        wall = _number(state["wall_seconds"].get(run.id))
        threads = state["threads"].get(run.id)
        rows.append(
            {
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
                "budget_spent": budget_spent(run, summary),
                "stopped_early": summary.get("stopped_early") or "",
                "wall_seconds": wall,
                "threads": threads if isinstance(threads, int) else "",
                "core_seconds": wall * threads if isinstance(threads, int) else math.nan,
                "success_rate": _number(summary.get("success_rate")),
                "normalized_reward": _number(summary.get("normalized_reward")),
                "input_recognition": _number(summary.get("input_recognition")),
                **{f"input_{kind}": _number(rates.get(kind)) for kind in INPUT_CLASSES},
                "folder": str(folder.run_folder(run).relative_to(folder.out)),
            }
        )
    return rows


def _csv(rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> bytes:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(
            {k: ("" if isinstance(v, float) and math.isnan(v) else v) for k, v in row.items()}
        )
    return buffer.getvalue().encode("utf-8")


def _cells(study: Study, condition: str) -> list[tuple[str, str]]:
    """The (trainer, algorithm) cells of one condition, in the study's order."""
    return list(
        dict.fromkeys((r.trainer, r.algorithm) for r in study.runs if r.condition == condition)
    )


def _values(
    rows: Sequence[dict[str, Any]], trainer: str, algorithm: str, condition: str, metric: str
) -> list[float]:
    return [
        row[metric]
        for row in rows
        if (row["trainer"], row["algorithm"], row["condition"]) == (trainer, algorithm, condition)
        and not math.isnan(row[metric])
    ]


def _statistic(values: Sequence[float], statistic: str) -> float:
    if not values:
        return math.nan
    return float(np.max(values)) if statistic == "max" else float(np.median(values))


def _ranked(row: Sequence[float]) -> list[str]:
    """``bold``/``italic``/``""`` per value: the best and second-best distinct values of a row."""
    distinct = sorted({v for v in row if not math.isnan(v)}, reverse=True)
    marks = []
    for value in row:
        if distinct and value == distinct[0]:
            marks.append("bold")
        elif len(distinct) > 1 and value == distinct[1]:
            marks.append("italic")
        else:
            marks.append("")
    return marks


def _fmt(value: float, mark: str = "") -> str:
    if math.isnan(value):
        return "–"
    text = f"{value:.3g}" if abs(value) >= 0.001 else f"{value:.3f}"
    return f"**{text}**" if mark == "bold" else f"*{text}*" if mark == "italic" else text


#: Most trainer x algorithm cells shown as the paper's columns; more are shown as rows.
WIDE_CELLS = 8
SHORT_METRICS = {"normalized_reward": "R̄", "success_rate": "success", "input_recognition": "IR"}


def table3(rows: Sequence[dict[str, Any]], study: Study, condition: str) -> tuple[str, dict]:
    """The paper's Table 3 for one condition, as Markdown, and its numbers.

    The maximum and median of each metric over the seeds of each trainer x
    algorithm cell; the best value of a statistic is bold, the second italic
    (higher is better for every metric). Up to :data:`WIDE_CELLS` cells are
    columns, as in the paper; more are rows, which read better.
    ``numbers[statistic][metric]`` lists the values in the cells' order.
    """
    cells = _cells(study, condition)
    numbers: dict[str, dict[str, list[float]]] = {}
    marks: dict[str, dict[str, list[str]]] = {}
    for statistic in ("max", "median"):
        numbers[statistic], marks[statistic] = {}, {}
        for metric in METRICS:
            values = [
                _statistic(_values(rows, t, a, condition, metric), statistic) for t, a in cells
            ]
            numbers[statistic][metric] = values
            marks[statistic][metric] = _ranked(values)
    counts = [len(_values(rows, t, a, condition, "success_rate")) for t, a in cells]
    titles = {"max": "Maximum", "median": "Median"}
    if len(cells) <= WIDE_CELLS:
        lines = [
            "| | | " + " | ".join(f"{t}<br>{a.upper()}" for t, a in cells) + " |",
            "|---|---|" + "---|" * len(cells),
        ]
        for statistic, title in titles.items():
            for metric, label in METRICS.items():
                shown = zip(numbers[statistic][metric], marks[statistic][metric], strict=True)
                lines.append(
                    f"| {title} | {label} | " + " | ".join(_fmt(v, m) for v, m in shown) + " |"
                )
        lines.append("| | runs | " + " | ".join(str(c) for c in counts) + " |")
        return "\n".join(lines), numbers
    columns = [(s, m) for s in titles for m in METRICS]
    lines = [
        "| trainer | algorithm | "
        + " | ".join(f"{titles[s].lower()} {SHORT_METRICS[m]}" for s, m in columns)
        + " | runs |",
        "|---|---|" + "---|" * (len(columns) + 1),
    ]
    for index, (trainer, algorithm) in enumerate(cells):
        values = [_fmt(numbers[s][m][index], marks[s][m][index]) for s, m in columns]
        lines.append(
            f"| {trainer} | {algorithm.upper()} | " + " | ".join(values) + f" | {counts[index]} |"
        )
    return "\n".join(lines), numbers


def paper_comparison(rows: Sequence[dict[str, Any]], study: Study, condition: str) -> str | None:
    """This study's Table 3 cells beside the paper's (where the paper has the cell)."""
    cells = [
        (t, a)
        for t, a in _cells(study, condition)
        if (paper_trainer(t), a) in PAPER_TABLE3["max"]["success_rate"]
    ]
    if not cells:
        return None
    header = "| | | " + " | ".join(f"{t}<br>{a.upper()}" for t, a in cells) + " |"
    lines = [header, "|---|---|" + "---|" * len(cells)]
    for statistic, title in (("max", "Maximum"), ("median", "Median")):
        for metric, label in METRICS.items():
            values = []
            for trainer, algorithm in cells:
                ours = _statistic(_values(rows, trainer, algorithm, condition, metric), statistic)
                theirs = PAPER_TABLE3[statistic][metric][(paper_trainer(trainer), algorithm)]
                values.append(f"{_fmt(ours)} / {theirs:g}")
            lines.append(f"| {title} | {label} | " + " | ".join(values) + " |")
    return "\n".join(lines)


def pairs_of(study: Study, condition: str) -> list[tuple[str, str]]:
    """The treatments of one condition that differ in exactly one factor (trainer or algorithm)."""
    cells = _cells(study, condition)
    pairs = []
    for i, (t1, a1) in enumerate(cells):
        for t2, a2 in cells[i + 1 :]:
            if (t1 == t2) != (a1 == a2):
                pairs.append((f"{t1}/{a1}/{condition}", f"{t2}/{a2}/{condition}"))
    return pairs


def comparisons(rows: Sequence[dict[str, Any]], study: Study) -> list[Comparison]:
    """The pairwise tests of every metric; each metric is one family for the correction."""
    conditions = list(dict.fromkeys(r.condition for r in study.runs))
    found: list[Comparison] = []
    for metric in METRICS:
        groups = {
            treatment: [row[metric] for row in rows if row["treatment"] == treatment]
            for treatment in study.treatments
        }
        pairs = [pair for condition in conditions for pair in pairs_of(study, condition)]
        found += compare_pairs(metric, groups, pairs)
    return found


TEST_COLUMNS = (
    "metric",
    "first",
    "second",
    "n_first",
    "n_second",
    "mean_first",
    "mean_second",
    "t_p",
    "t_p_corrected",
    "t_stars",
    "cohens_d",
    "u_p",
    "u_p_corrected",
    "u_stars",
    "rank_biserial",
)


def _test_rows(found: Sequence[Comparison]) -> list[dict[str, Any]]:
    rows = []
    for comparison in found:
        row = asdict(comparison)
        row["t_stars"], row["u_stars"] = comparison.t_stars, comparison.u_stars
        rows.append({k: (math.nan if v is None else v) for k, v in row.items()})
    return rows


def _significant(found: Sequence[Comparison]) -> str:
    chosen = [c for c in found if c.t_stars not in ("ns", "n/a") or c.u_stars not in ("ns", "n/a")]
    if not chosen:
        return "No pair differs significantly (corrected p < 0.05) in either test."
    lines = [
        "| metric | first | second | means | t-test (BH) | Cohen's d | Mann-Whitney (BH)"
        " | rank-biserial |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in chosen:
        lines.append(
            f"| {METRICS[c.metric]} | {c.first} | {c.second} |"
            f" {c.mean_first:.3g} vs {c.mean_second:.3g} |"
            f" {_p(c.t_p_corrected)} {c.t_stars} | {_signed(c.cohens_d)} |"
            f" {_p(c.u_p_corrected)} {c.u_stars} | {_signed(c.rank_biserial)} |"
        )
    return "\n".join(lines)


def _signed(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{value:+.2f}"


def _p(p: float | None) -> str:
    return "n/a" if p is None else f"{p:.2g}"


def _budget_table(rows: Sequence[dict[str, Any]], study: Study) -> str:
    """Median budget spent per treatment and condition, flagged where it is not like the rest."""
    lines = ["| condition | treatment | runs | budget spent (median) | |", "|---|---|---|---|---|"]
    for condition in dict.fromkeys(r.condition for r in study.runs):
        medians = {}
        for treatment in study.treatments:
            spent = [
                r["budget_spent"]
                for r in rows
                if r["treatment"] == treatment and r["condition"] == condition
                and not math.isnan(r["budget_spent"])
            ]  # fmt: skip
            if spent:
                medians[treatment] = (len(spent), float(np.median(spent)))
        for treatment, (count, median) in medians.items():
            others = [m for t, (_, m) in medians.items() if t != treatment]
            flag = ""
            if others and abs(median - float(np.median(others))) > BUDGET_TOLERANCE:
                flag = "**flagged**"
            lines.append(f"| {condition} | {treatment} | {count} | {median:.0%} | {flag} |")
    return "\n".join(lines)


def _compute(rows: Sequence[dict[str, Any]], study: Study) -> str:
    lines = [
        "| treatment | runs | env steps (median) | training s (median) | wall-clock s (sum)"
        " | core-s (sum) |",
        "|---|---|---|---|---|---|",
    ]
    for treatment in study.treatments:
        mine = [r for r in rows if r["treatment"] == treatment]
        if not mine:
            lines.append(f"| {treatment} | 0 | – | – | – | – |")
            continue
        steps = float(np.median([r["env_steps"] for r in mine]))
        seconds = _statistic([r["seconds"] for r in mine if not math.isnan(r["seconds"])], "median")
        shown = "–" if math.isnan(seconds) else f"{seconds:.1f}"  # a summary without seconds
        wall = float(np.nansum([r["wall_seconds"] for r in mine]))
        core = float(np.nansum([r["core_seconds"] for r in mine]))
        lines.append(
            f"| {treatment} | {len(mine)} | {steps:,.0f} | {shown} | {wall:.0f} | {core:.0f} |"
        )
    return "\n".join(lines)


def write_report(out: str | Path, warn: Callable[[str], None] | None = None) -> Path:
    """Write ``report.md``, ``runs.csv``, ``tests.csv`` and ``figures/`` in the study's folder.

    ``warn`` hears of each part of a run left out (:class:`LeftOut`), which
    ``report.md`` lists too.
    """
    from experiments.figures import save_figures

    folder = StudyFolder(out)
    study = folder.study()
    left_out: list[LeftOut] = []
    rows = collect_rows(folder, study, left_out)
    write_bytes(folder.out / "runs.csv", _csv(rows, RUN_COLUMNS))
    found = comparisons(rows, study)
    write_bytes(folder.out / "tests.csv", _csv(_test_rows(found), TEST_COLUMNS))

    def unreadable(run_id: str, what: str, reason: str) -> None:
        left_out.append(LeftOut(run_id, what, reason))

    figures = save_figures(folder, study, rows, unreadable)
    for part in left_out:
        if warn is not None:
            warn(str(part))
    conditions = list(dict.fromkeys(r.condition for r in study.runs))
    unread = sum(part.what == "its row" for part in left_out)
    finished = f"{len(rows)} of {len(study.runs)} runs finished"
    if unread:
        finished += f" and read ({unread} more finished but cannot be read: see 'Left out')"
    parts = [
        f"# Study `{study.name}`: report",
        "",
        study.description.strip(),
        "",
        f"{finished}; written {datetime.now(UTC).isoformat(timespec='seconds')} from their"
        " `summary.json` files (`runs.csv`). Every agent is scored on the standard evaluation"
        " suite (18 mazes x 4 rotations) and by the input-recognition test.",
        "",
    ]
    for condition in conditions:
        spec = next(r for r in study.runs if r.condition == condition)
        parts += [
            f"## Table 3, `{condition}` ({_budget_words(spec)})",
            "",
            "Maximum and median over the seeds of each treatment; the best value of each statistic"
            " in **bold**, the second in *italics* (higher is better everywhere).",
            "",
            table3(rows, study, condition)[0],
            "",
        ]
        # the paper's agents were DD robots (discrete inputs and moves)
        paper = paper_comparison(rows, study, condition) if spec.config["robot"] == "DD" else None
        if paper:
            parts += [
                f"### Beside the paper (this study / {PAPER_CITATION})",
                "",
                "The paper's EDHuCAT curator was a person; here `edhucat-*` are scripted"
                " strategies. The paper trained for 3 M env steps.",
                "",
                paper,
                "",
            ]
    parts += [
        "## Pairwise differences",
        "",
        "Treatments under the same condition that differ in one factor, compared per metric with"
        " an independent t-test (as the paper) and a Mann-Whitney U test, each corrected with"
        " Benjamini-Hochberg over the metric's pairs; effect sizes Cohen's d and the"
        " rank-biserial correlation (first vs second). Stars: * p < 0.05, ** < 1e-2,"
        " *** < 1e-3, **** < 1e-4. Every pair is in `tests.csv`; the significant ones:",
        "",
        _significant(found),
        "",
        "## Figures",
        "",
    ]
    for title, path in figures:
        parts += [f"### {title}", "", f"![{title}]({path.relative_to(folder.out).as_posix()})", ""]
    if left_out:
        parts += ["## Left out", "", _left_out(left_out), ""]
    parts += [
        "## Budget spent",
        "",
        "The share of its budget each run spent (the most of any budget it was given), median"
        f" per treatment; **flagged** where it differs from the other treatments' median under"
        f" the same condition by more than {BUDGET_TOLERANCE:.0%}: their comparison is not at"
        " equal budget. Runs record why they stopped early in `summary.json` (`stopped_early`,"
        " in `runs.csv`).",
        "",
        _budget_table(rows, study),
        "",
        "## Compute",
        "",
        "Env steps and training seconds from `summary.json`; wall-clock seconds of each run's"
        " process (over every resumed part) and core-seconds (wall-clock x the threads it was"
        " given) from the runner.",
        "",
        _compute(rows, study),
        "",
    ]
    path = folder.out / "report.md"
    write_bytes(path, "\n".join(parts).encode("utf-8"))
    return path


def _left_out(left_out: Sequence[LeftOut]) -> str:
    """The parts of runs the report could not read, one a line, with the reason."""
    lines = ["Files of these runs cannot be read; what they would have given is not above:", ""]
    lines += [f"* `{part.run}`: {part.what}: {part.reason}" for part in left_out]
    return "\n".join(lines)


def _budget_words(run: PlannedRun) -> str:
    words = []
    if run.budget_steps:
        words.append(f"{run.budget_steps:,} env steps")
    if run.budget_seconds:
        words.append(f"{run.budget_seconds:g} s")
    text = " or ".join(words) if words else "no budget"
    return text if run.robot is None else f"{text}, robot {run.robot}"
