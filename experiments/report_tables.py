"""The tables of a study's report, as Markdown: each shows its n, and marks unequal budgets.

* :func:`budget_table`: the budget each treatment spent (median, range, n),
  flagged where a run spent less than 90% or more than 110% of it
  (:func:`budgets_spent`); every other table marks a flagged treatment
  with :data:`FLAG`;
* :func:`final_table`: the final agents on the evaluation set, interquartile
  mean and 95% stratified bootstrap interval per treatment;
* :func:`improvement_table`: the probability of improvement of a
  comparison's pairs, with its interval;
* :func:`table3` and :func:`paper_comparison`: the paper's Table 3 from the
  standard suite, and the paper's own numbers beside it;
* :func:`significance`: the pairwise tests (:mod:`experiments.stats`) whose
  stars can be shown, and why the others have none;
* :func:`compute_table`: the compute each treatment took.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from experiments.evaluations import ComparisonData
from experiments.intervals import (
    Interval,
    iqm,
    probability_of_improvement_ci,
    stratified_bootstrap_ci,
)
from experiments.paper import PAPER_TABLE3, paper_trainer
from experiments.stats import MIN_SEEDS, Comparison
from experiments.study import Study

__all__ = [
    "BUDGET_TOLERANCE",
    "FLAG",
    "METRICS",
    "BudgetSpent",
    "budget_table",
    "budgets_spent",
    "compute_table",
    "final_table",
    "improvement_table",
    "paper_comparison",
    "significance",
    "table3",
]

#: The metrics of Table 3, in the paper's order, with their labels.
METRICS = {
    "normalized_reward": "Normalized reward R̄",
    "success_rate": "Success rate",
    "input_recognition": "Input recognition",
}
SHORT_METRICS = {"normalized_reward": "R̄", "success_rate": "success", "input_recognition": "IR"}
#: A run whose budget spent is outside ``[1 - BUDGET_TOLERANCE, 1 + BUDGET_TOLERANCE]`` (a
#: share of its budget, in the study's budget unit) flags its treatment: not at equal budget.
BUDGET_TOLERANCE = 0.10
#: The mark of a flagged treatment in every table.
FLAG = "⚠"
#: Most trainer x algorithm cells shown as the paper's columns; more are shown as rows.
WIDE_CELLS = 8
#: Bootstrap resamples of an interval.
REPS = 2000


def _fmt(value: float, mark: str = "") -> str:
    if math.isnan(value):
        return "–"
    text = f"{value:.3g}" if abs(value) >= 0.001 else f"{value:.3f}"
    return f"**{text}**" if mark == "bold" else f"*{text}*" if mark == "italic" else text


def _flagged(name: str, treatment: str, flagged: Collection[str]) -> str:
    """``name`` with :data:`FLAG` when ``treatment`` did not spend its budget within 10%."""
    return f"{name} {FLAG}" if treatment in flagged else name


# -- budgets --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BudgetSpent:
    """The shares of its budget a treatment's runs spent."""

    treatment: str
    unit: str
    n: int
    median: float
    low: float
    high: float
    #: Runs outside ``[0.9, 1.1]``.
    outside: int

    @property
    def flagged(self) -> bool:
        return self.outside > 0


def budgets_spent(rows: Sequence[dict[str, Any]], study: Study) -> dict[str, BudgetSpent]:
    """Each treatment's :class:`BudgetSpent` from its rows' ``budget_spent`` (where it has one)."""
    found = {}
    for treatment in study.treatments:
        mine = [r for r in rows if r["treatment"] == treatment]
        shares = [r["budget_spent"] for r in mine if not math.isnan(r["budget_spent"])]
        if not shares:
            continue
        outside = sum(abs(share - 1.0) > BUDGET_TOLERANCE + 1e-9 for share in shares)
        found[treatment] = BudgetSpent(
            treatment, mine[0]["budget_unit"], len(shares), float(np.median(shares)),
            float(min(shares)), float(max(shares)), outside,
        )  # fmt: skip
    return found


def budget_table(spent: dict[str, BudgetSpent]) -> str:
    """Budget spent per treatment: unit, n, median and range, flagged runs."""
    lines = [
        "| treatment | budget | n | spent (median) | range | runs outside 90%-110% |",
        "|---|---|---|---|---|---|",
    ]
    for s in spent.values():
        name = f"**{s.treatment} {FLAG}**" if s.flagged else s.treatment
        lines.append(
            f"| {name} | {s.unit} | {s.n} | {s.median:.0%} | {s.low:.0%} – {s.high:.0%}"
            f" | {s.outside} |"
        )
    return "\n".join(lines)


# -- final results on the evaluation set ----------------------------------------------------------


def _interval(interval: Interval | None) -> str:
    if interval is None:
        return "–"
    return f"{_fmt(interval.point)} [{_fmt(interval.low)}, {_fmt(interval.high)}]"


def final_intervals(data: ComparisonData, quantity: str) -> dict[str, Interval]:
    """Each treatment's IQM of its runs' final ``quantity``, with its 95% bootstrap interval."""
    return {
        curves.treatment: stratified_bootstrap_ci(curves.final(quantity), iqm, reps=REPS, seed=0)
        for curves in data.treatments
    }


def final_table(data: ComparisonData, flagged: Collection[str]) -> str:
    """The final agents on the evaluation set: IQM [95% CI] of success rate and R̄, with n."""
    success = final_intervals(data, "success_rate")
    reward = final_intervals(data, "normalized_reward")
    lines = [
        "| treatment | n | success rate, IQM [95% CI] | R̄, IQM [95% CI] |",
        "|---|---|---|---|",
    ]
    for curves in data.treatments:
        t = curves.treatment
        lines.append(
            f"| {_flagged(t, t, flagged)} | {curves.n} | {_interval(success[t])}"
            f" | {_interval(reward[t])} |"
        )
    return "\n".join(lines)


def improvement_table(data: ComparisonData, flagged: Collection[str]) -> str | None:
    """P(first > second) on the final success rate and R̄ of each pair, with its 95% CI."""
    found = {curves.treatment: curves for curves in data.treatments}
    pairs = [(a, b) for a, b in data.comparison.pairs if a in found and b in found]
    if not pairs:
        return None
    lines = [
        "| first | second | n | P(first > second), success rate [95% CI]"
        " | P(first > second), R̄ [95% CI] |",
        "|---|---|---|---|---|",
    ]
    for a, b in pairs:
        x, y = found[a], found[b]
        cells = [
            _interval(probability_of_improvement_ci(x.final(q), y.final(q), reps=REPS, seed=0))
            for q in ("success_rate", "normalized_reward")
        ]
        lines.append(
            f"| {_flagged(a, a, flagged)} | {_flagged(b, b, flagged)} | {x.n} vs {y.n}"
            f" | {cells[0]} | {cells[1]} |"
        )
    return "\n".join(lines)


# -- the paper's Table 3 --------------------------------------------------------------------------


def _cells(study: Study, condition: str) -> list[tuple[str, str]]:
    """The (trainer, algorithm) cells of one condition, in the study's order."""
    return list(
        dict.fromkeys((r.trainer, r.algorithm) for r in study.runs if r.condition == condition)
    )


def values_of(
    rows: Sequence[dict[str, Any]], trainer: str, algorithm: str, condition: str, metric: str
) -> list[float]:
    """The ``metric`` of each run of a cell under ``condition`` (NaN left out)."""
    return [
        row[metric]
        for row in rows
        if (row["trainer"], row["algorithm"], row["condition"]) == (trainer, algorithm, condition)
        and not math.isnan(row[metric])
    ]


def statistic(values: Sequence[float], name: str) -> float:
    """``max`` or ``median`` of ``values`` (NaN for none)."""
    if not values:
        return math.nan
    return float(np.max(values)) if name == "max" else float(np.median(values))


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


TITLES = {"max": "Maximum", "median": "Median"}


def _table3_numbers(
    rows: Sequence[dict[str, Any]], cells: Sequence[tuple[str, str]], condition: str
) -> tuple[dict, dict]:
    """``numbers[statistic][metric]`` per cell, and the bold/italic marks of each."""
    numbers: dict[str, dict[str, list[float]]] = {}
    marks: dict[str, dict[str, list[str]]] = {}
    for name in TITLES:
        numbers[name], marks[name] = {}, {}
        for metric in METRICS:
            values = [statistic(values_of(rows, t, a, condition, metric), name) for t, a in cells]
            numbers[name][metric] = values
            marks[name][metric] = _ranked(values)
    return numbers, marks


def table3(
    rows: Sequence[dict[str, Any]],
    study: Study,
    condition: str,
    flagged: Collection[str] = (),
) -> tuple[str, dict]:
    """The paper's Table 3 for one condition, as Markdown, and its numbers.

    The maximum and median of each metric over the seeds of each trainer x
    algorithm cell; the best value of a statistic is bold, the second italic
    (higher is better for every metric); n per cell. Up to :data:`WIDE_CELLS`
    cells are columns, as in the paper; more are rows, which read better.
    ``numbers[statistic][metric]`` lists the values in the cells' order.
    """
    cells = _cells(study, condition)
    numbers, marks = _table3_numbers(rows, cells, condition)
    counts = [len(values_of(rows, t, a, condition, "success_rate")) for t, a in cells]
    names = [_flagged(f"{t}<br>{a.upper()}", f"{t}/{a}/{condition}", flagged) for t, a in cells]
    if len(cells) <= WIDE_CELLS:
        lines = ["| | | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(cells)]
        for name, title in TITLES.items():
            for metric, label in METRICS.items():
                shown = zip(numbers[name][metric], marks[name][metric], strict=True)
                lines.append(
                    f"| {title} | {label} | " + " | ".join(_fmt(v, m) for v, m in shown) + " |"
                )
        lines.append("| | n (runs) | " + " | ".join(str(c) for c in counts) + " |")
        return "\n".join(lines), numbers
    columns = [(s, m) for s in TITLES for m in METRICS]
    lines = [
        "| trainer | algorithm | n | "
        + " | ".join(f"{TITLES[s].lower()} {SHORT_METRICS[m]}" for s, m in columns)
        + " |",
        "|---|---|---|" + "---|" * len(columns),
    ]
    for index, (trainer, algorithm) in enumerate(cells):
        values = [_fmt(numbers[s][m][index], marks[s][m][index]) for s, m in columns]
        shown = _flagged(algorithm.upper(), f"{trainer}/{algorithm}/{condition}", flagged)
        lines.append(f"| {trainer} | {shown} | {counts[index]} | " + " | ".join(values) + " |")
    return "\n".join(lines), numbers


def paper_comparison(
    rows: Sequence[dict[str, Any]], study: Study, condition: str, flagged: Collection[str] = ()
) -> str | None:
    """This study's Table 3 cells beside the paper's (where the paper has the cell), with n."""
    cells = [
        (t, a)
        for t, a in _cells(study, condition)
        if (paper_trainer(t), a) in PAPER_TABLE3["max"]["success_rate"]
    ]
    if not cells:
        return None
    names = [_flagged(f"{t}<br>{a.upper()}", f"{t}/{a}/{condition}", flagged) for t, a in cells]
    lines = ["| | | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(cells)]
    for name, title in TITLES.items():
        for metric, label in METRICS.items():
            values = []
            for trainer, algorithm in cells:
                ours = statistic(values_of(rows, trainer, algorithm, condition, metric), name)
                theirs = PAPER_TABLE3[name][metric][(paper_trainer(trainer), algorithm)]
                values.append(f"{_fmt(ours)} / {theirs:g}")
            lines.append(f"| {title} | {label} | " + " | ".join(values) + " |")
    counts = [len(values_of(rows, t, a, condition, "success_rate")) for t, a in cells]
    lines.append("| | n (runs; the paper's: not stated) | " + " | ".join(map(str, counts)) + " |")
    return "\n".join(lines)


# -- pairwise tests -------------------------------------------------------------------------------


def _signed(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{value:+.2f}"


def _p(p: float | None) -> str:
    return "n/a" if p is None else f"{p:.2g}"


def significance(found: Sequence[Comparison], flagged: Collection[str] = ()) -> str:
    """The pairs with stars (corrected p < 0.05 where a test can reach it); why others have none."""
    allowed = [c for c in found if c.withheld is None]
    chosen = [
        c for c in allowed if c.t_stars not in ("ns", "n/a") or c.u_stars not in ("ns", "n/a")
    ]
    parts = []
    withheld: dict[str, int] = {}
    for c in found:
        if c.withheld is not None:
            withheld[c.withheld] = withheld.get(c.withheld, 0) + 1
    for reason, count in withheld.items():
        parts.append(f"**No stars for {count} of {len(found)} pair(s)**: {reason}.")
    if withheld:
        parts.append("Their p-values are in `tests.csv`, not read as significance here.\n")
    if not allowed:
        return "\n".join(parts)
    if not chosen:
        parts.append(
            f"No pair of at least {MIN_SEEDS} seeds each differs significantly"
            " (corrected p < 0.05) in either test."
        )
        return "\n".join(parts)
    lines = [
        "| metric | first | second | n | means | t-test (BH) | Cohen's d | Mann-Whitney (BH)"
        " | rank-biserial |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for c in chosen:
        lines.append(
            f"| {METRICS[c.metric]} | {_flagged(c.first, c.first, flagged)}"
            f" | {_flagged(c.second, c.second, flagged)} | {c.n_first} vs {c.n_second} |"
            f" {c.mean_first:.3g} vs {c.mean_second:.3g} |"
            f" {_p(c.t_p_corrected)} {c.t_stars} | {_signed(c.cohens_d)} |"
            f" {_p(c.u_p_corrected)} {c.u_stars} | {_signed(c.rank_biserial)} |"
        )
    return "\n".join([*parts, *lines])


# -- compute --------------------------------------------------------------------------------------


def compute_table(
    rows: Sequence[dict[str, Any]], study: Study, flagged: Collection[str] = ()
) -> str:
    """Per treatment: n, median env steps and training seconds, summed wall-clock and core-s."""
    lines = [
        "| treatment | n | env steps (median) | training s (median) | wall-clock s (sum)"
        " | core-s (sum) |",
        "|---|---|---|---|---|---|",
    ]
    for treatment in study.treatments:
        name = _flagged(treatment, treatment, flagged)
        mine = [r for r in rows if r["treatment"] == treatment]
        if not mine:
            lines.append(f"| {name} | 0 | – | – | – | – |")
            continue
        steps = float(np.median([r["env_steps"] for r in mine]))
        seconds = statistic([r["seconds"] for r in mine if not math.isnan(r["seconds"])], "median")
        shown = "–" if math.isnan(seconds) else f"{seconds:.1f}"  # a summary without seconds
        wall = float(np.nansum([r["wall_seconds"] for r in mine]))
        core = float(np.nansum([r["core_seconds"] for r in mine]))
        lines.append(f"| {name} | {len(mine)} | {steps:,.0f} | {shown} | {wall:.0f} | {core:.0f} |")
    return "\n".join(lines)


def advice_table(rows: Sequence[dict[str, Any]], study: Study) -> str | None:
    """Per advised treatment: n, the mean share of proposed picks taken and of proposed mazes kept.

    None when no run was advised (no run's ``summary.json`` has ``advice``).
    """
    columns = ("advice_selections_taken", "advice_mazes_kept")
    lines = [
        "| treatment | n | proposed picks taken (mean) | proposed mazes kept (mean) |",
        "|---|---|---|---|",
    ]
    for treatment in study.treatments:
        mine = [r for r in rows if r["treatment"] == treatment]
        shares = [[r[c] for r in mine if not math.isnan(r.get(c, math.nan))] for c in columns]
        if not any(shares):
            continue
        shown = [f"{np.mean(s):.2f}" if s else "–" for s in shares]
        lines.append(f"| {treatment} | {len(mine)} | {shown[0]} | {shown[1]} |")
    return "\n".join(lines) if len(lines) > 2 else None
