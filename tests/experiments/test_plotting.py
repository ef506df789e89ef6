"""A treatment's colour: fixed by its name, the same in every report whatever else it holds."""

from __future__ import annotations

import json
from itertools import pairwise
from pathlib import Path

import pytest

from experiments.plotting import (
    ALGORITHM_SHIFTS,
    COLOURS,
    TRAINER_SLOTS,
    Palette,
    cell_colour,
    variant_shifts,
)
from experiments.report import write_report
from experiments.study import PlannedRun, load_study
from experiments.trainers import ALGORITHMS, TRAINERS
from tests.experiments.synthetic import evaluation_rows, make_study

ROOT = Path(__file__).resolve().parents[2]
#: Two studies that share one treatment, direct/ppo, among others: sorted, it is the
#: second cell of the first and the fourth of the second.
STUDIES = {
    "first": ("direct", "interpolation"),
    "second": ("coevolution", "direct"),
}
ALGORITHMS_OF = {"first": ("a2c", "ppo"), "second": ("cmaes", "ppo")}


def study_text(name: str) -> str:
    return f"""
name = "{name}"
description = "Colours."
seeds = 2
trainers = {json.dumps(list(STUDIES[name]))}
algorithms = {json.dumps(list(ALGORITHMS_OF[name]))}

[budgets]
steps = {{ steps = 1000 }}
"""


def summary(run: PlannedRun) -> dict:
    return {
        "env_steps": 1000,
        "seconds": 2.0,
        "success_rate": 0.25 * (run.seed + 1),
        "normalized_reward": -1.0 - run.seed,
        "input_recognition": 0.7,
    }


def evaluations(run: PlannedRun) -> list[dict]:
    return evaluation_rows(
        success=[0.1, 0.2 + 0.1 * run.seed],
        rbar=[-3.0, -2.0 + run.seed],
        steps=[500, 1000],
        seconds=[1.0, 2.0],
    )


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    written = {}
    for name in STUDIES:
        folder = make_study(tmp_path_factory.mktemp(name), study_text(name), summary, evaluations)
        write_report(folder.out)
        written[name] = folder.out
    return written


def test_a_shared_treatment_has_the_same_colour_in_two_reports(reports: dict[str, Path]) -> None:
    colours = {
        name: json.loads((out / "figures" / "colours.json").read_text())
        for name, out in reports.items()
    }
    assert sorted(colours["first"]).index("direct/ppo") == 1
    assert sorted(colours["second"]).index("direct/ppo") == 3
    shared = set(colours["first"]) & set(colours["second"])
    assert shared == {"direct/ppo"}
    assert colours["first"]["direct/ppo"] == colours["second"]["direct/ppo"]
    assert colours["first"]["direct/ppo"] == cell_colour("direct/ppo")
    for name, out in reports.items():
        assert len(set(colours[name].values())) == len(colours[name])  # four cells, four colours
        # the figures draw it in that colour
        drawn = "".join(path.read_text() for path in (out / "figures").rglob("*.svg"))
        for colour in colours[name].values():
            assert colour in drawn, (name, colour)


def test_every_trainer_and_algorithm_has_a_fixed_place() -> None:
    assert set(TRAINER_SLOTS) == set(TRAINERS)
    assert sorted(TRAINER_SLOTS.values()) == list(range(len(COLOURS)))
    assert set(ALGORITHM_SHIFTS) == set(ALGORITHMS)
    assert len(set(COLOURS)) == len(COLOURS)


def test_the_cells_of_one_trainer_or_one_algorithm_all_differ() -> None:
    for trainer in TRAINERS:
        row = {cell_colour(f"{trainer}/{algorithm}") for algorithm in ALGORITHMS}
        assert len(row) == len(ALGORITHMS), trainer
    for algorithm in ALGORITHMS:
        column = {cell_colour(f"{trainer}/{algorithm}") for trainer in TRAINERS}
        assert len(column) == len(TRAINERS), algorithm


@pytest.mark.parametrize("path", sorted((ROOT / "experiments" / "studies").glob("*.toml")))
def test_every_comparison_of_the_shipped_studies_has_distinct_colours(path: Path) -> None:
    study = load_study(path)
    cells = {run.cell for run in study.runs}
    palette = Palette(sorted(cells), study.variants)  # as the report makes it
    for comparison in study.comparisons:
        colours = [palette(treatment) for treatment in comparison.treatments]
        assert len(set(colours)) == len(colours), comparison.name
    if len(cells) <= len(COLOURS):  # a study that can have one colour per cell has it
        assert len({palette(cell) for cell in cells}) == len(cells)


def test_a_name_of_no_table_takes_a_stable_colour() -> None:
    """A plug-in's trainer or algorithm: from a hash of its name, not Python's ``hash``."""
    assert cell_colour("my-trainer/ppo") == cell_colour("my-trainer/ppo/steps")
    assert cell_colour("my-trainer/ppo") in COLOURS
    # pinned: the same in every process and every release
    assert [cell_colour(cell) for cell in ("my-trainer/ppo", "direct/my-algo")] == [
        "#d62728",
        "#9467bd",
    ]
    palette = Palette(["direct/ppo", "my-trainer/ppo"])
    assert palette("my-trainer/ppo/steps") == palette.colours["my-trainer/ppo"]
    assert list(palette.colours) == sorted(palette.colours)


def test_a_palette_does_not_depend_on_the_other_cells() -> None:
    cells = [f"{t}/{a}" for t in TRAINERS for a in ALGORITHMS]
    whole = Palette(cells)
    for first, second in pairwise(cells):
        assert Palette([first, second]).colours == {c: whole(c) for c in (first, second)}


def test_a_variant_takes_a_colour_beside_its_base_and_apart_from_every_algorithm() -> None:
    """A study's variants (name: base) sit between the algorithms' places, each its own."""
    variants = {f"ppo-s{i}": "ppo" for i in range(1, 9)}
    assert variant_shifts({"ppo-fast": "ppo"}) == {"ppo-fast": ALGORITHM_SHIFTS["ppo"] + 1}
    assert variant_shifts({"neat-big": "neat", "a2c-x": "a2c"}) == {"neat-big": 10, "a2c-x": 4}
    # in the order of the names, whatever the order given: ppo-a before ppo-b
    assert variant_shifts({"ppo-b": "ppo", "ppo-a": "ppo"}) == {"ppo-a": 7, "ppo-b": 8}
    assert sorted(variant_shifts(variants).values()) == [1, 2, 4, 5, 7, 8, 10, 11]
    for trainer in TRAINERS:  # 4 algorithms and 8 variants: 12 colours on each trainer
        row = [cell_colour(f"{trainer}/{a}", variants) for a in (*ALGORITHMS, *variants)]
        assert len(set(row)) == len(COLOURS), trainer
    for variant in variants:
        column = {cell_colour(f"{trainer}/{variant}", variants) for trainer in TRAINERS}
        assert len(column) == len(TRAINERS), variant
    assert variant_shifts({**variants, "ppo-s9": "ppo"})["ppo-s9"] == 7  # the 9th starts over
    palette = Palette(["direct/ppo", "direct/ppo-fast"], {"ppo-fast": "ppo"})
    assert palette("direct/ppo-fast/steps") == palette.colours["direct/ppo-fast"]
    assert palette.colours["direct/ppo-fast"] == COLOURS[TRAINER_SLOTS["direct"] + 7]
    assert palette.colours["direct/ppo-fast"] != palette.colours["direct/ppo"]
    assert cell_colour("direct/ppo", {"ppo-fast": "ppo"}) == cell_colour("direct/ppo")
