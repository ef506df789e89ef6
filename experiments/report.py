"""A study's report: every number recomputed from its runs' summaries and anytime evaluations.

``amaze-experiment report DIR`` (:func:`write_report`) writes, in ``DIR``:

* ``runs.csv``: one row per finished run (study, treatment, trainer,
  algorithm, condition, robot, seed, env steps, seconds, the share of its
  budget spent, wall-clock and core-seconds, suite success, R̄, input
  recognition and its rate per input class, the final agent's success and
  R̄ on the evaluation set and the set's digest, the run's folder);
* ``tests.csv``: every pairwise test (:mod:`experiments.stats`), with its n
  and why its stars are withheld where they are (both CSV files: UTF-8, one
  line a row, text a spreadsheet would run as a formula written with a
  leading ``'``: :func:`~experiments.report_runs.spreadsheet_cell`);
* ``figures/``: per comparison the study declares
  (:mod:`experiments.comparisons`), learning curves and a performance
  profile from the anytime evaluations (:mod:`experiments.curves`); the
  standard-suite distributions, input recognition and the best agent's
  trajectories (:mod:`experiments.figures`); each as PNG, PDF and SVG, every
  treatment in one colour (``colours.json``);
* ``report.md``, in this order: whether budgets were held equal (a treatment
  with a run outside 90-110% of its budget is flagged here and marked in
  every table), the final agents on the evaluation set (IQM and 95%
  bootstrap interval), each comparison (curves, profile, probability of
  improvement of its pairs), the paper's Table 3 from the study's suite
  (the standard one, or the paper's with ``suite = "paper"``, then input
  recognition as the paper scored it too) with the paper's own numbers
  beside it (:mod:`experiments.paper`), the paper's pairwise tests (stars
  only where a test can reach them), the suite's figures, how often
  advised curators took the advice, the runs' parts left out and the
  compute.

The tables are :mod:`experiments.report_tables`'; every one shows its n.

A run's file that cannot be read (a damaged ``summary.json`` or
``evaluations.csv``, a trajectory picture that is not a picture) does not
stop the report of the others: what it would have given is left out, and
the report says so, run by run, with the reason (:class:`LeftOut`: a
section of ``report.md``, and a warning each for the command); so is a run
evaluated on another evaluation set than the others of its comparison. A
file of the study itself (``study.toml``, ``state.json``) that cannot be
read is an error: without it there is no report to write.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from amaze.runs.folder import write_bytes
from experiments.ceiling import CEILING, ceiling_table
from experiments.comparisons import StudyComparison
from experiments.curves import write_comparison_figures
from experiments.evaluations import ComparisonData, comparison_data
from experiments.figures import save_figures
from experiments.paper import PAPER_CITATION
from experiments.plotting import FORMATS, Palette
from experiments.report_runs import (
    RUN_COLUMNS,
    LeftOut,
    budget_share,
    collect_rows,
    read_runs,
    read_summary,
    scored_on,
    to_csv,
)
from experiments.report_tables import (
    BUDGET_TOLERANCE,
    FLAG,
    METRICS,
    BudgetSpent,
    advice_table,
    budget_table,
    budgets_spent,
    compute_table,
    final_table,
    improvement_table,
    paper_comparison,
    significance,
    table3,
)
from experiments.runner import StudyFolder
from experiments.stats import MIN_SEEDS, Comparison, compare_pairs
from experiments.study import PlannedRun, Study

__all__ = [
    "METRICS",
    "RUN_COLUMNS",
    "LeftOut",
    "budget_share",
    "collect_rows",
    "read_runs",
    "read_summary",
    "table3",
    "write_report",
]

# -- the paper's pairwise tests -------------------------------------------------------------------


def pairs_of(study: Study, condition: str) -> list[tuple[str, str]]:
    """The treatments of one condition that differ in exactly one factor (trainer or algorithm)."""
    cells = list(
        dict.fromkeys((r.trainer, r.algorithm) for r in study.runs if r.condition == condition)
    )
    pairs = []
    for i, (t1, a1) in enumerate(cells):
        for t2, a2 in cells[i + 1 :]:
            if (t1 == t2) != (a1 == a2):
                pairs.append((f"{t1}/{a1}/{condition}", f"{t2}/{a2}/{condition}"))
    return pairs


def comparisons(rows: Sequence[dict[str, Any]], study: Study) -> list[Comparison]:
    """The pairwise tests of every metric; each metric is one family for the correction."""
    found: list[Comparison] = []
    for metric in METRICS:
        groups = {
            treatment: [row[metric] for row in rows if row["treatment"] == treatment]
            for treatment in study.treatments
        }
        pairs = [pair for condition in study.conditions for pair in pairs_of(study, condition)]
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
    "stars_withheld",
)


def _test_rows(found: Sequence[Comparison]) -> list[dict[str, Any]]:
    rows = []
    for comparison in found:
        row = asdict(comparison)
        row["t_stars"], row["u_stars"] = comparison.t_stars, comparison.u_stars
        row["stars_withheld"] = comparison.withheld or ""
        rows.append({k: (math.nan if v is None else v) for k, v in row.items()})
    return rows


# -- the report's sections ------------------------------------------------------------------------


@dataclass
class Findings:
    """What the report's sections are written from."""

    folder: StudyFolder
    study: Study
    rows: list[dict[str, Any]]
    spent: dict[str, BudgetSpent]
    #: Per comparison: its data and its figures (title, PNG path).
    compared: list[tuple[ComparisonData, list[tuple[str, Path]]]]
    #: Per condition: all its treatments' final agents on the evaluation set.
    finals: dict[str, ComparisonData]
    tests: list[Comparison]
    figures: list[tuple[str, Path]]
    left_out: list[LeftOut]

    @property
    def flagged(self) -> set[str]:
        return {t for t, s in self.spent.items() if s.flagged}

    def link(self, title: str, path: Path) -> list[str]:
        """A figure in ``report.md``: the PNG, with its PDF and SVG named beside it."""
        relative = path.relative_to(self.folder.out).as_posix()
        others = ", ".join(f"[{s}]({relative.removesuffix('.png')}.{s})" for s in FORMATS[1:])
        return [f"![{title}]({relative})", "", f"*{title}* (also {others})", ""]


#: How the report names the suite it scores the final agents on (a study's ``suite``).
SUITE_WORDS = {
    "standard": "standard evaluation suite (18 mazes x 4 rotations)",
    "paper": "paper's evaluation suite (the 18 mazes its evaluation script built, x 4 rotations)",
}


def _header(f: Findings) -> list[str]:
    unread = sum(part.what == "its row" for part in f.left_out)
    finished = f"{len(f.rows)} of {len(f.study.runs)} runs finished"
    if unread:
        finished += f" and read ({unread} more finished but cannot be read: see 'Left out')"
    return [
        f"# Study `{f.study.name}`: report",
        "",
        f.study.description.strip(),
        "",
        f"{finished}; written {datetime.now(UTC).isoformat(timespec='seconds')} from their"
        " `summary.json` and `evaluations.csv` files (`runs.csv`). Each run's agent is played"
        " as it trains on one evaluation set (family mazes with new seeds and the training"
        " maze, 4 rotations each; `evaluations.csv`), and its final agent on the"
        f" {SUITE_WORDS[f.study.suite]} and the input-recognition test (Table 3);"
        " `runs.csv` holds the final agents on both suites.",
        "",
    ]


def _budget_section(f: Findings) -> list[str]:
    flagged = [s for s in f.spent.values() if s.flagged]
    low, high = 1 - BUDGET_TOLERANCE, 1 + BUDGET_TOLERANCE
    if flagged:
        names = "; ".join(
            f"`{s.treatment}` ({s.outside} of {s.n} runs; median {s.median:.0%},"
            f" {s.low:.0%} – {s.high:.0%})"
            for s in flagged
        )
        verdict = (
            f"**{FLAG} {len(flagged)} treatment(s) did not spend their budget within"
            f" {BUDGET_TOLERANCE:.0%}**: {names}. A comparison with them is not at equal"
            f" budget; they are marked {FLAG} in every table."
        )
    else:
        verdict = f"Every run spent between {low:.0%} and {high:.0%} of its budget."
    return [
        "## Budgets held equal",
        "",
        verdict,
        "",
        f"The share of its budget each run spent, in the budget's unit (env steps for a steps"
        f" budget, else training seconds), per treatment; a treatment is flagged when a run"
        f" spent less than {low:.0%} or more than {high:.0%}. Runs say why they stopped early"
        " in `summary.json` (`stopped_early`, in `runs.csv`).",
        "",
        budget_table(f.spent),
        "",
    ]


def _final_section(f: Findings) -> list[str]:
    parts = [
        "## Final agents on the evaluation set",
        "",
        "The last row of each run's `evaluations.csv` (its final agent): interquartile mean"
        " over seeds with a 95% stratified bootstrap interval (2000 resamples), n runs.",
        "",
    ]
    for condition, data in f.finals.items():
        if not data.treatments:
            continue
        parts += [f"### `{condition}`", "", final_table(data, f.flagged), ""]
        parts += _set_notes(data)
    return parts


def _set_notes(data: ComparisonData) -> list[str]:
    """What a comparison's runs left out and without evaluations are, in words."""
    notes = []
    if data.digest:
        notes.append(f"Evaluation set `{data.digest}`.")
    if data.left_out:
        notes.append(
            f"{len(data.left_out)} run(s) left out (see 'Left out'): "
            + "; ".join(f"`{run}` {reason}" for run, reason in data.left_out)
            + "."
        )
    if data.without:
        notes.append(
            f"{len(data.without)} finished run(s) without readable evaluations (no"
            " `evaluations.csv`: a run from before anytime evaluations, or `evaluation_points ="
            " 0`; or one left out) are not in it."
        )
    return [" ".join(notes), ""] if notes else []


def _comparison_section(f: Findings) -> list[str]:
    parts = [
        "## Comparisons over time",
        "",
        "Per comparison: learning curves of the agent each run would hand over, played on the"
        " evaluation set at evenly spaced fractions of its budget: the interquartile mean over"
        " seeds at each point (runs aligned by point index, the point placed at the seeds'"
        " median env steps or training seconds) in a 95% stratified bootstrap band, against"
        " env steps and training time (log scales; the budget dotted); the performance"
        " profile of the final agents (fraction of runs whose success rate exceeds each"
        " threshold, 95% bands); and the probability that a run of the first treatment beats"
        " one of the second (final agents; 0.5: neither), with its 95% interval.",
        "",
    ]
    declared = any(data.comparison.declared for data, _ in f.compared)
    if f.compared and not declared:
        parts += [
            "The study declares no comparison (`[[comparisons]]`): these are the default ones,"
            " the algorithms within each trainer and the trainers with each algorithm.",
            "",
        ]
    for data, figures in f.compared:
        parts += _one_comparison(f, data.comparison, data, figures)
    return parts


def _one_comparison(
    f: Findings, comparison: StudyComparison, data: ComparisonData, figures: list
) -> list[str]:
    names = ", ".join(f"`{t}`" for t in comparison.treatments)
    parts = [f"### {comparison.title}", "", f"`{comparison.name}`: {names}.", ""]
    if not data.treatments:
        return [*parts, "No run of these treatments has evaluations to draw.", ""]
    for title, path in figures:
        parts += f.link(title, path)
    table = improvement_table(data, f.flagged)
    if table:
        parts += ["Probability of improvement (final agents, evaluation set):", "", table, ""]
    parts += [
        f"How soon the runs reach the ceiling (success >= {CEILING:g} on the evaluation set,"
        " first anytime point where the agent does; medians over the runs that get there):",
        "",
        ceiling_table(data),
        "",
    ]
    return parts + _set_notes(data)


def _table3_section(f: Findings) -> list[str]:
    parts = []
    for condition in f.study.conditions:
        spec = next(r for r in f.study.runs if r.condition == condition)
        parts += [
            f"## Table 3, `{condition}` ({_budget_words(spec)})",
            "",
            f"The final agents on the {SUITE_WORDS[f.study.suite]}, as the paper: maximum and"
            " median over the seeds of each treatment; the best value of each statistic in"
            " **bold**, the second in *italics* (higher is better everywhere).",
            "",
            table3(f.rows, f.study, condition, f.flagged)[0],
            "",
        ]
        # the paper's agents were DD robots (discrete inputs and moves)
        paper = None
        if spec.config["robot"] == "DD":
            paper = paper_comparison(f.rows, f.study, condition, f.flagged)
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
    return parts


def _tests_section(f: Findings) -> list[str]:
    return [
        "## Pairwise tests (the paper's statistics)",
        "",
        "Treatments under the same condition that differ in one factor, compared per"
        f" metric of the {SUITE_WORDS[f.study.suite]} with an independent t-test (as the"
        " paper) and a Mann-Whitney U test, each corrected with Benjamini-Hochberg over the"
        " metric's pairs; effect sizes Cohen's d and the rank-biserial correlation (first vs"
        " second). Stars: * p < 0.05,"
        f" ** < 1e-2, *** < 1e-3, **** < 1e-4, shown only for pairs of at least {MIN_SEEDS}"
        " seeds each. Every pair is in `tests.csv`; the significant ones:",
        "",
        significance(f.tests, f.flagged),
        "",
    ]


def _figures_section(f: Findings) -> list[str]:
    parts = ["## Standard-suite figures", ""]
    for title, path in f.figures:
        parts += [f"### {title}", "", *f.link(title, path)]
    return parts


def _tail_sections(f: Findings) -> list[str]:
    parts = []
    advice = advice_table(f.rows, f.study)
    if advice is not None:
        parts += [
            "## Advice taken",
            "",
            "Of the runs whose curator was advised (`--advisor`): the share of the advisor's"
            " proposed picks the decider took, and of its proposed mazes the decider kept"
            " (`decisions.jsonl`'s `accepted`; `summary.json`'s `advice`).",
            "",
            advice,
            "",
        ]
    if f.left_out:
        parts += ["## Left out", "", _left_out(f.left_out), ""]
    return [
        *parts,
        "## Compute",
        "",
        "Env steps and training seconds from `summary.json`; wall-clock seconds of each run's"
        " process (over every resumed part) and core-seconds (wall-clock x the threads it was"
        " given) from the runner.",
        "",
        compute_table(f.rows, f.study, f.flagged),
        "",
    ]


def _left_out(left_out: Sequence[LeftOut]) -> str:
    """The parts of runs the report could not use, one a line, with the reason."""
    lines = ["These runs' files cannot be read or set beside the others; what they would have"]
    lines += ["given is not above:", ""]
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


# -- writing it -----------------------------------------------------------------------------------


def _set_apart(datas: Sequence[ComparisonData], left_out: list[LeftOut]) -> None:
    """Add the runs the comparisons set apart to ``left_out``: one entry per run and reason."""
    grouped: dict[tuple[str, str], list[str]] = {}
    for data in datas:
        for run, reason in data.left_out:
            grouped.setdefault((run, reason), []).append(data.comparison.name)
    for (run, reason), names in grouped.items():
        left_out.append(LeftOut(run, f"its evaluations in {', '.join(names)}", reason))


def _findings(folder: StudyFolder, study: Study) -> Findings:
    """Read the runs, write ``runs.csv``, ``tests.csv`` and the figures; what the text needs."""
    left_out: list[LeftOut] = []
    rows, finished, curves = read_runs(folder, study, left_out)
    write_bytes(folder.out / "runs.csv", to_csv(rows, RUN_COLUMNS))
    rows = scored_on(rows, study.suite)  # what every table, test and figure scores
    tests = comparisons(rows, study)
    write_bytes(folder.out / "tests.csv", to_csv(_test_rows(tests), TEST_COLUMNS))
    out = folder.out / "figures"
    palette = Palette([run.cell for run in study.runs], study.variants)
    palette.save(out / "colours.json")
    compared = []
    for comparison in study.comparisons:
        data = comparison_data(comparison, finished, curves)
        compared.append((data, write_comparison_figures(data, palette, out)))
    finals = {}
    for condition in study.conditions:
        mine = tuple(t for t in study.treatments if t.endswith(f"/{condition}"))
        whole = StudyComparison(condition, condition, condition, mine, (), declared=False)
        finals[condition] = comparison_data(whole, finished, curves)
    _set_apart([*(data for data, _ in compared), *finals.values()], left_out)

    def unreadable(run_id: str, what: str, reason: str) -> None:
        left_out.append(LeftOut(run_id, what, reason))

    figures = save_figures(out, folder.out, rows, study.treatments, palette, unreadable)
    spent = budgets_spent(rows, study)
    return Findings(folder, study, rows, spent, compared, finals, tests, figures, left_out)


def write_report(out: str | Path, warn: Callable[[str], None] | None = None) -> Path:
    """Write ``report.md``, ``runs.csv``, ``tests.csv`` and ``figures/`` in the study's folder.

    ``warn`` hears of each part of a run left out (:class:`LeftOut`), which
    ``report.md`` lists too.
    """
    folder = StudyFolder(out)
    findings = _findings(folder, folder.study())
    for part in findings.left_out:
        if warn is not None:
            warn(str(part))
    parts = [
        *_header(findings),
        *_budget_section(findings),
        *_final_section(findings),
        *_comparison_section(findings),
        *_table3_section(findings),
        *_tests_section(findings),
        *_figures_section(findings),
        *_tail_sections(findings),
    ]
    path = folder.out / "report.md"
    write_bytes(path, "\n".join(parts).encode("utf-8"))
    return path
