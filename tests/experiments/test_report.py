"""A study's report recomputed from a synthetic study whose numbers are known."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from amaze.runs.folder import write_json
from experiments.report import collect_rows, table3, write_report
from experiments.runner import STATE_FILE, STUDY_FILE, StudyFolder
from experiments.study import parse_study
from tests.experiments.test_stats import benjamini_hochberg, student_p

STUDY = """
name = "synthetic"
description = "Known numbers."
seeds = 3
trainers = ["direct", "interpolation"]
algorithms = ["a2c", "ppo"]

[budgets]
steps = { steps = 100_000 }
"""
#: Suite success, R̄ and input recognition of seeds 0, 1, 2 of each cell.
NUMBERS = {
    ("direct", "a2c"): ([0.10, 0.20, 0.30], [-5.0, -4.0, -3.0], [0.70, 0.71, 0.72]),
    ("direct", "ppo"): ([0.40, 0.50, 0.90], [-2.0, -1.0, -3.5], [0.75, 0.74, 0.73]),
    ("interpolation", "a2c"): ([0.05, 0.05, 0.10], [-6.0, -6.5, -5.5], [0.60, 0.65, 0.62]),
    ("interpolation", "ppo"): ([0.60, 0.70, 0.65], [-1.5, -0.5, -1.0], [0.80, 0.78, 0.79]),
}


@pytest.fixture(scope="module")
def study_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("synthetic")
    (out / STUDY_FILE).write_text(STUDY)
    study = parse_study(STUDY)
    folder = StudyFolder(out)
    wall = {}
    for run in study.runs:
        success, rbar, inputs = (
            values[run.seed] for values in NUMBERS[(run.trainer, run.algorithm)]
        )
        summary = {
            "success_rate": success,
            "normalized_reward": rbar,
            "input_recognition": inputs,
            "input_rates": {"empty": 1.0, "lure": 0.9, "clue": inputs, "trap": 0.1},
            "env_steps": 100_000 + run.seed,
            "seconds": 10.0 * (run.seed + 1),
        }
        if run.trainer == "interpolation" and run.algorithm == "ppo":  # as if advised
            summary["advice"] = {"selections_taken_share": run.seed / 2, "mazes_kept_share": 0.25}
        write_json(folder.run_folder(run) / "summary.json", summary)
        write_json(folder.run_folder(run) / "config.json", run.config)
        wall[run.id] = 20.0 + run.seed
    write_json(
        out / STATE_FILE,
        {
            "runner": None,
            "running": [],
            "failed": {},
            "wall_seconds": wall,
            "threads": dict.fromkeys(wall, 2),
        },
    )
    write_report(out)
    return out


def test_runs_csv_has_one_row_per_run_from_its_summary(study_folder: Path) -> None:
    with (study_folder / "runs.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 12
    row = next(r for r in rows if r["treatment"] == "direct/ppo/steps" and r["seed"] == "2")
    assert float(row["success_rate"]) == 0.90
    assert float(row["normalized_reward"]) == -3.5
    assert float(row["input_clue"]) == 0.73
    assert row["env_steps"] == "100002"
    assert float(row["core_seconds"]) == 2 * 22.0
    assert row["folder"] == "runs/direct_ppo_steps_seed-2"


def test_table3_holds_the_maximum_and_median_of_each_cell(study_folder: Path) -> None:
    folder = StudyFolder(study_folder)
    study = folder.study()
    text, numbers = table3(collect_rows(folder, study), study, "steps")
    cells = [
        ("direct", "a2c"),
        ("direct", "ppo"),
        ("interpolation", "a2c"),
        ("interpolation", "ppo"),
    ]
    for metric_index, metric in enumerate(
        ("success_rate", "normalized_reward", "input_recognition")
    ):
        expected_max = [max(NUMBERS[c][metric_index]) for c in cells]
        expected_median = [float(np.median(NUMBERS[c][metric_index])) for c in cells]
        assert numbers["max"][metric] == pytest.approx(expected_max)
        assert numbers["median"][metric] == pytest.approx(expected_median)
    lines = text.splitlines()
    success_max = next(line for line in lines if line.startswith("| Maximum | Success rate"))
    assert success_max == "| Maximum | Success rate | 0.3 | **0.9** | 0.1 | *0.7* |"
    rbar_median = next(line for line in lines if line.startswith("| Median | Normalized"))
    assert rbar_median == "| Median | Normalized reward R̄ | -4 | *-2* | -6 | **-1** |"
    assert lines[-1] == "| | n (runs) | 3 | 3 | 3 | 3 |"


def test_the_tests_are_recomputed_and_corrected_per_metric(study_folder: Path) -> None:
    with (study_folder / "tests.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    # 4 cells, pairs that differ in one factor: 2 by algorithm + 2 by trainer, x 3 metrics
    assert len(rows) == 12
    success = [r for r in rows if r["metric"] == "success_rate"]
    raw = []
    for row in success:
        first, second = (tuple(row[k].split("/")[:2]) for k in ("first", "second"))
        raw.append(student_p(NUMBERS[first][0], NUMBERS[second][0]))
        assert float(row["t_p"]) == pytest.approx(raw[-1])
    corrected = benjamini_hochberg(raw)
    assert [float(r["t_p_corrected"]) for r in success] == pytest.approx(corrected)
    pairs = {(r["first"], r["second"]) for r in success}
    assert pairs == {
        ("direct/a2c/steps", "direct/ppo/steps"),
        ("direct/a2c/steps", "interpolation/a2c/steps"),
        ("direct/ppo/steps", "interpolation/ppo/steps"),
        ("interpolation/a2c/steps", "interpolation/ppo/steps"),
    }


def test_the_report_shows_the_table_the_paper_the_figures_and_the_compute(
    study_folder: Path,
) -> None:
    report = (study_folder / "report.md").read_text()
    assert "12 of 12 runs finished" in report
    assert "| Maximum | Success rate | 0.3 | **0.9** | 0.1 | *0.7* |" in report
    # beside the paper's Table 3: direct A2C max success 0.347
    assert (
        "| Maximum | Success rate | 0.3 / 0.347 | 0.9 / 0.778 | 0.1 / 0.403 | 0.7 / 0.708 |"
        in report
    )
    for figure in ("distributions", "inputs"):
        assert f"(figures/{figure}.png)" in report
        assert (study_folder / "figures" / f"{figure}.png").stat().st_size > 1000
    # no evaluations.csv (runs from before anytime evaluations): no curves, and said so
    assert "curves.png" not in report and "(figures/curves-" not in report
    assert "No run of these treatments has evaluations to draw." in report
    # median steps and training seconds; wall-clock 20 + 21 + 22 s on 2 threads each
    assert "| direct/a2c/steps | 3 | 100,001 | 20.0 | 63 | 126 |" in report


def test_with_3_seeds_no_stars_and_the_reason_is_printed(study_folder: Path) -> None:
    report = (study_folder / "report.md").read_text()
    assert "**No stars for 12 of 12 pair(s)**: 3 vs 3 seeds, fewer than 5 in a group" in report
    assert "a two-sided Mann-Whitney U test of 3 against 3 values cannot reach p < 0.1" in report
    assert "| metric | first | second | n |" not in report  # no table of significant pairs
    with (study_folder / "tests.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    # some corrected p-values are below 0.05, yet no stars are shown
    assert any(row["t_p_corrected"] and float(row["t_p_corrected"]) < 0.05 for row in rows)
    assert all(row["t_stars"] == "" and row["u_stars"] == "" for row in rows)
    assert all(row["stars_withheld"].startswith("3 vs 3 seeds") for row in rows)
    assert all((row["n_first"], row["n_second"]) == ("3", "3") for row in rows)


def test_the_report_says_how_often_advised_runs_took_the_advice(study_folder: Path) -> None:
    with (study_folder / "runs.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    advised = [r for r in rows if r["treatment"] == "interpolation/ppo/steps"]
    assert sorted(r["advice_selections_taken"] for r in advised) == ["0.0", "0.5", "1.0"]
    assert {r["advice_mazes_kept"] for r in rows if r not in advised} == {""}
    report = (study_folder / "report.md").read_text()
    section = report.split("## Advice taken")[1].split("## ")[0]
    assert "| interpolation/ppo/steps | 3 | 0.50 | 0.25 |" in section
    assert "direct/" not in section  # treatments without an advisor have no row


def test_a_study_on_the_paper_suite_reports_the_paper_suites_figures(tmp_path: Path) -> None:
    out = tmp_path / "paper"
    text = STUDY.replace("seeds = 3", 'seeds = 3\nsuite = "paper"')
    (out).mkdir()
    (out / STUDY_FILE).write_text(text)
    folder = StudyFolder(out)
    for run in parse_study(text).runs:
        success, rbar, inputs = (
            values[run.seed] for values in NUMBERS[(run.trainer, run.algorithm)]
        )
        summary = {
            "success_rate": 0.0,  # the standard suite's: not what this report scores
            "normalized_reward": -9.0,
            "input_recognition": 0.0,
            "paper_input_recognition": inputs,
            "paper_suite": {"success_rate": success, "normalized_reward": rbar},
            "env_steps": 100_000,
            "seconds": 10.0,
        }
        write_json(folder.run_folder(run) / "summary.json", summary)
        write_json(folder.run_folder(run) / "config.json", run.config)
    write_json(out / STATE_FILE, {"runner": None, "running": [], "failed": {}})
    report = write_report(out).read_text()
    assert "final agents on the paper's evaluation suite" in report
    line = next(x for x in report.splitlines() if x.startswith("| Maximum | Success rate"))
    assert line == "| Maximum | Success rate | 0.3 | **0.9** | 0.1 | *0.7* |"
    with (out / "runs.csv").open() as handle:
        row = next(csv.DictReader(handle))
    assert float(row["success_rate"]) == 0.0  # runs.csv keeps both suites
    assert float(row["paper_suite_success_rate"]) == 0.10
