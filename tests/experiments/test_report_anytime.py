"""The report over time: curves from evaluations.csv, IQM bands, budgets, n, figures, colours."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy import stats as scipy_stats

from experiments.curves import draw_curves, draw_profile
from experiments.evaluations import comparison_data, read_evaluations
from experiments.plotting import COLUMN_WIDTH, Palette, paper_style
from experiments.report import read_runs, write_report
from experiments.report_tables import FLAG
from experiments.runner import StudyFolder
from experiments.study import PlannedRun, parse_study
from tests.experiments.synthetic import evaluation_rows, make_study, markdown_tables

STUDY = """
name = "anytime"
description = "Known curves."
seeds = 4
trainers = ["direct", "interpolation"]
algorithms = ["ppo", "cmaes"]

[budgets]
steps = { steps = 1000 }

[[comparisons]]
name = "algorithms-direct"
title = "PPO against CMA-ES, direct"
treatments = ["direct/ppo", "direct/cmaes"]

[[comparisons]]
name = "trainers-ppo"
title = "Trainers with PPO"
treatments = ["direct/ppo", "interpolation/ppo"]
pairs = [["interpolation/ppo", "direct/ppo"]]
"""
#: Each cell's success at the last point (it grows linearly from point 1).
BASE = {
    ("direct", "ppo"): 0.52,
    ("direct", "cmaes"): 0.8,
    ("interpolation", "ppo"): 0.6,
    ("interpolation", "cmaes"): 0.2,
}
POINTS = 4
#: The run played on another evaluation set than the others.
ODD_RUN = "direct_cmaes_steps_seed-3"
#: The treatment that spent 80 % of its budget.
SHORT = "interpolation/cmaes/steps"


def success(run: PlannedRun, point: int) -> float:
    return BASE[(run.trainer, run.algorithm)] * point / POINTS + 0.05 * run.seed


def summary(run: PlannedRun) -> dict:
    share = 0.8 if run.treatment == SHORT else 1.0
    return {
        "env_steps": int(1000 * share),
        "seconds": 4.0,
        "success_rate": 0.5,
        "normalized_reward": -1.0 - run.seed,
        "input_recognition": 0.7,
        "budget_spent": {"steps": share},
    }


def evaluations(run: PlannedRun) -> list[dict]:
    points = range(1, POINTS + 1)
    return evaluation_rows(
        success=[success(run, p) for p in points],
        rbar=[-5.0 + p + run.seed for p in points],
        steps=[250 * p + 10 * run.seed for p in points],
        seconds=[p * (1.0 + run.seed) for p in points],
        digest="ffff000011112222" if run.id == ODD_RUN else "0123456789abcdef",
    )


@pytest.fixture(scope="module")
def study_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = make_study(tmp_path_factory.mktemp("anytime"), STUDY, summary, evaluations)
    # a progress log that says something else: the curves must not read it
    for run in parse_study(STUDY).runs:
        (folder.run_folder(run) / "progress.csv").write_text("steps,seconds,eval_success_rate\n")
    write_report(folder.out)
    return folder.out


@pytest.fixture(scope="module")
def report(study_folder: Path) -> str:
    return (study_folder / "report.md").read_text()


def data_of(study_folder: Path, name: str):
    folder = StudyFolder(study_folder)
    study = folder.study()
    _, finished, curves = read_runs(folder, study, [])
    comparison = next(c for c in study.comparisons if c.name == name)
    return comparison_data(comparison, finished, curves), study


def test_the_curves_are_the_iqm_over_seeds_of_the_evaluations_at_median_steps(
    study_folder: Path,
) -> None:
    data, study = data_of(study_folder, "trainers-ppo")
    palette = Palette([run.cell for run in study.runs])
    with paper_style() as plt:
        figure = draw_curves(data, palette, plt)
    success_steps = figure.axes[0]  # success rate against env steps
    lines = {
        line.get_label(): line for line in success_steps.get_lines() if "n=" in line.get_label()
    }
    assert set(lines) == {"direct PPO (n=4)", "interpolation PPO (n=4)"}
    line = lines["interpolation PPO (n=4)"]
    points = np.arange(1, POINTS + 1)
    # seeds 0..3: 250 p + 10 s steps, median 250 p + 15
    assert line.get_xdata() == pytest.approx(250 * points + 15)
    # IQM of 4 values: the mean of the middle two (seeds 1 and 2: + 0.05 and + 0.10)
    by_hand = [
        scipy_stats.trim_mean([0.6 * p / 4 + 0.05 * s for s in range(4)], 0.25) for p in points
    ]
    assert line.get_ydata() == pytest.approx(by_hand)
    assert by_hand == pytest.approx(0.6 * points / 4 + 0.075)
    # against training time: the median seconds, p (1 + s) -> 2.5 p
    seconds = next(l for l in figure.axes[1].get_lines() if l.get_label().startswith("interp"))
    assert seconds.get_xdata() == pytest.approx(2.5 * points)
    # R̄ below: -5 + p + s, IQM -5 + p + 1.5
    reward = next(l for l in figure.axes[2].get_lines() if l.get_label().startswith("interp"))
    assert reward.get_ydata() == pytest.approx(-5 + points + 1.5)
    assert figure.axes[0].get_xscale() == "log"


def test_the_bands_are_the_stratified_bootstrap_of_curve_intervals(study_folder: Path) -> None:
    data, _ = data_of(study_folder, "trainers-ppo")
    curves = next(c for c in data.treatments if c.treatment == "direct/ppo/steps")
    bands = curves.bands("success_rate")
    assert np.all(bands.low <= bands.point + 1e-12) and np.all(bands.point <= bands.high + 1e-12)
    assert np.any(bands.high > bands.low)  # seeds differ: a band of some width
    assert curves.final("success_rate") == pytest.approx([0.52 + 0.05 * s for s in range(4)])


def test_the_old_progress_curves_are_gone(study_folder: Path) -> None:
    figures = study_folder / "figures"
    assert not (figures / "curves.png").exists()
    assert (figures / "curves-trainers-ppo.png").is_file()
    assert (figures / "curves-algorithms-direct.png").is_file()


def test_a_run_on_another_evaluation_set_is_left_out_with_the_reason(
    study_folder: Path, report: str
) -> None:
    data, _ = data_of(study_folder, "algorithms-direct")
    cmaes = next(c for c in data.treatments if c.treatment == "direct/cmaes/steps")
    assert ODD_RUN not in cmaes.runs and cmaes.n == 3
    assert [run for run, _ in data.left_out] == [ODD_RUN]
    left = report.split("## Left out", 1)[1]
    assert f"`{ODD_RUN}`" in left
    assert "played the evaluation set ffff000011112222, not 0123456789abcdef" in left
    assert "not the same mazes" in left
    # the trainers-ppo comparison has no run of it: nothing left out there
    assert data_of(study_folder, "trainers-ppo")[0].left_out == ()


def test_a_treatment_that_spent_80_percent_is_flagged_near_the_top_and_in_every_table(
    report: str,
) -> None:
    top = report.split("## Final agents", 1)[0]
    assert "## Budgets held equal" in top
    assert f"**{FLAG} 1 treatment(s) did not spend their budget within 10%**" in top
    assert f"`{SHORT}` (4 of 4 runs; median 80%, 80% – 80%)" in top
    assert f"| **{SHORT} {FLAG}** | steps | 4 | 80% | 80% – 80% | 4 |" in top
    assert "| direct/ppo/steps | steps | 4 | 100% | 100% – 100% | 0 |" in top
    # every table naming the treatment marks it
    for table in markdown_tables(report):
        text = "\n".join(table)
        if "interpolation/cmaes" in text or "interpolation<br>CMAES" in text:
            assert FLAG in text, text
    assert f"| interpolation<br>CMAES {FLAG} |" in report  # Table 3's column
    assert f"| direct<br>PPO {FLAG}" not in report


def test_every_table_shows_n(report: str) -> None:
    tables = markdown_tables(report)
    assert len(tables) >= 6
    for table in tables:
        cells = {cell.strip() for line in table for cell in line.split("|")}
        assert any(cell == "n" or cell.startswith("n (") for cell in cells), "\n".join(table)


def test_final_results_are_the_iqm_of_the_last_rows_with_n(report: str) -> None:
    final = report.split("## Final agents", 1)[1].split("## Comparisons", 1)[0]
    # interpolation/ppo: finals 0.6 + 0.05 s, IQM 0.675; R̄ -1 + s, IQM 0.5
    row = next(line for line in final.splitlines() if line.startswith("| interpolation/ppo"))
    assert row.startswith("| interpolation/ppo/steps | 4 | 0.675 [")
    assert "| 0.5 [" in row
    assert "| direct/cmaes/steps | 3 |" in final  # its odd run left out


def test_probability_of_improvement_of_the_declared_pairs(report: str) -> None:
    section = report.split("### Trainers with PPO", 1)[1].split("###", 1)[0]
    row = next(line for line in section.splitlines() if line.startswith("| interpolation/ppo"))
    assert row.startswith("| interpolation/ppo/steps | direct/ppo/steps | 4 vs 4 | ")
    # finals 0.6, 0.65, 0.7, 0.75 against 0.52, 0.57, 0.62, 0.67: 2 + 3 + 4 + 4 of 16 pairs won
    point = float(row.split("|")[4].split("[")[0])
    assert point == pytest.approx(13 / 16, abs=0.001)
    # the default pairs of algorithms-direct: ppo against cmaes, one run of cmaes left out
    assert "| direct/ppo/steps | direct/cmaes/steps | 4 vs 3 |" in report


def test_every_figure_is_png_at_300_dpi_pdf_and_svg(study_folder: Path, report: str) -> None:
    figures = study_folder / "figures"
    pngs = sorted(figures.glob("*.png"))
    names = {p.stem for p in pngs}
    assert {"distributions", "inputs", "curves-trainers-ppo", "profile-trainers-ppo"} <= names
    for png in pngs:
        assert f"(figures/{png.name})" in report
        for suffix in ("pdf", "svg"):
            assert png.with_suffix(f".{suffix}").stat().st_size > 1000
        with Image.open(png) as image:
            assert image.info["dpi"] == pytest.approx((300, 300), abs=0.1)
    assert png.with_suffix(".svg").read_text().lstrip().startswith("<?xml")
    with Image.open(figures / "curves-trainers-ppo.png") as image:  # a column wide
        assert image.width / 300 == pytest.approx(COLUMN_WIDTH, abs=0.02)


def test_r_bar_is_written_with_its_macron(study_folder: Path) -> None:
    svg = (study_folder / "figures" / "curves-trainers-ppo.svg").read_text()
    assert "normalized reward R\u0304" in svg
    assert "environment steps" in svg and "training time (s)" in svg


def test_a_treatment_has_one_colour_in_every_figure(study_folder: Path) -> None:
    colours = json.loads((study_folder / "figures" / "colours.json").read_text())
    assert set(colours) == {f"{t}/{a}" for t, a in BASE}
    assert len(set(colours.values())) == len(colours)
    seen: dict[str, set[str]] = {}
    from matplotlib.colors import to_hex

    for name in ("algorithms-direct", "trainers-ppo"):
        data, study = data_of(study_folder, name)
        palette = Palette([run.cell for run in study.runs])
        with paper_style() as plt:
            for figure in (draw_curves(data, palette, plt), draw_profile(data, palette, plt)):
                for line in figure.axes[0].get_lines():
                    if "n=" in line.get_label():
                        seen.setdefault(line.get_label().split(" (")[0], set()).add(
                            to_hex(line.get_color())
                        )
                plt.close(figure)
    assert seen["direct PPO"] == {colours["direct/ppo"]}  # in two comparisons, two figures each
    assert seen["direct CMAES"] == {colours["direct/cmaes"]}
    assert seen["interpolation PPO"] == {colours["interpolation/ppo"]}


def test_runs_csv_has_the_final_evaluation_set_figures_and_budget_spent(study_folder: Path) -> None:
    with (study_folder / "runs.csv").open() as handle:
        rows = {row["folder"].split("/")[-1]: row for row in csv.DictReader(handle)}
    row = rows["interpolation_ppo_steps_seed-2"]
    assert float(row["eval_set_success_rate"]) == pytest.approx(0.6 + 0.1)
    assert float(row["eval_set_normalized_reward"]) == pytest.approx(-1.0 + 2)
    assert row["evaluation_set"] == "0123456789abcdef"
    assert (row["budget_unit"], float(row["budget_spent"])) == ("steps", 1.0)
    assert float(rows["interpolation_cmaes_steps_seed-0"]["budget_spent"]) == 0.8


def test_a_run_that_stopped_early_holds_its_final_agent_to_the_end(tmp_path: Path) -> None:
    run = parse_study(STUDY).runs[0]
    rows = evaluation_rows(
        success=[0.1, 0.2, 0.5], rbar=[-3, -2, -1], steps=[10, 20, 25], seconds=[1, 2, 3],
        points=[1, 2, 5],
    )  # fmt: skip
    from tests.experiments.synthetic import write_evaluations

    write_evaluations(tmp_path / "evaluations.csv", rows)
    curve = read_evaluations(tmp_path, run)
    assert curve.points == 5 and curve.taken == (1, 2, 5)
    assert curve.columns["success_rate"] == pytest.approx([0.1, 0.2, 0.5, 0.5, 0.5])
    assert curve.columns["env_steps"] == pytest.approx([10, 20, 25, 25, 25])
    assert curve.final("success_rate") == 0.5
    assert read_evaluations(tmp_path / "nowhere", run) is None


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (b"garbage\x00\xff", "cannot be read"),
        (b"point,fraction\n1,0.5\n", "has no column"),
        (b"", None),  # no row: no curve, nothing wrong
    ],
)
def test_a_damaged_evaluations_file_is_refused_by_name(
    tmp_path: Path, content: bytes, reason: str | None
) -> None:
    from experiments.study import StudyError

    run = parse_study(STUDY).runs[0]
    (tmp_path / "evaluations.csv").write_bytes(content)
    if reason is None:
        assert read_evaluations(tmp_path, run) is None
        return
    with pytest.raises(StudyError, match=reason) as caught:
        read_evaluations(tmp_path, run)
    assert str(tmp_path / "evaluations.csv") in str(caught.value)
