"""A study's [[comparisons]]: the form, the defaults, and bad ones refused by name."""

from __future__ import annotations

import pytest

from experiments.comparisons import MAX_LINES, Grid, default_comparisons
from experiments.study import StudyError, load_study, parse_study, study_names

BASE = """
name = "t"
seeds = 2
trainers = ["direct", "interpolation", "edhucat-careful"]
algorithms = ["ppo", "cmaes"]
[budgets]
steps = { steps = 50_000 }
clock = { seconds = 30 }
"""
#: Every trainer x every algorithm: 32 cells, to refuse a comparison of 9.
WIDE = """
name = "wide"
trainers = ["direct", "interpolation", "edhucat-careful", "edhucat-moderate", "edhucat-risky",
            "edhucat-random", "edens", "coevolution"]
algorithms = ["a2c", "ppo", "cmaes", "neat"]
[budgets]
steps = { steps = 50_000 }
"""


def test_a_declared_comparison_names_its_treatments_budget_and_pairs() -> None:
    study = parse_study(
        BASE
        + """
[[comparisons]]
name = "trainers-ppo"
title = "Trainers with PPO"
budget = "clock"
treatments = ["direct/ppo", "interpolation/ppo", "edhucat-careful/ppo"]
pairs = [["interpolation/ppo", "direct/ppo"]]

[[comparisons]]
name = "direct"
budget = "steps"
treatments = ["direct/ppo", "direct/cmaes", "interpolation/cmaes"]
"""
    )
    first, second = study.comparisons
    assert (first.name, first.title, first.condition) == (
        "trainers-ppo",
        "Trainers with PPO",
        "clock",
    )
    assert first.treatments == (
        "direct/ppo/clock",
        "interpolation/ppo/clock",
        "edhucat-careful/ppo/clock",
    )
    assert first.pairs == (("interpolation/ppo/clock", "direct/ppo/clock"),)
    assert first.declared
    assert set(first.treatments) <= set(study.treatments)
    # no pairs given: those that differ in one factor
    assert second.title == "direct"
    assert second.pairs == (
        ("direct/ppo/steps", "direct/cmaes/steps"),
        ("direct/cmaes/steps", "interpolation/cmaes/steps"),
    )


def test_without_comparisons_the_defaults_are_algorithms_and_trainers_in_each_other() -> None:
    study = parse_study(BASE)
    names = [c.name for c in study.comparisons]
    assert names == [
        f"{kind}-{condition}"
        for condition in ("steps", "clock")
        for kind in (
            "algorithms-direct",
            "algorithms-interpolation",
            "algorithms-edhucat-careful",
            "trainers-ppo",
            "trainers-cmaes",
        )
    ]
    trainers_ppo = next(c for c in study.comparisons if c.name == "trainers-ppo-clock")
    assert trainers_ppo.treatments == (
        "direct/ppo/clock",
        "interpolation/ppo/clock",
        "edhucat-careful/ppo/clock",
    )
    assert len(trainers_ppo.pairs) == 3 and not trainers_ppo.declared
    assert all(len(c.treatments) <= MAX_LINES for c in study.comparisons)


def test_the_defaults_cover_every_cell_and_split_groups_of_more_than_8() -> None:
    cells = (*((f"t{i}", "ppo") for i in range(10)), ("lonely", "neat"))
    found = default_comparisons(Grid(("steps",), ("DD",), cells))
    assert [c.name for c in found] == [
        "trainers-ppo-1-steps",
        "trainers-ppo-2-steps",
        "others-steps",
    ]
    assert [len(c.treatments) for c in found] == [8, 2, 1]
    one = default_comparisons(Grid(("steps",), ("DD",), (("direct", "ppo"),)))
    assert [(c.name, c.treatments) for c in one] == [("all-steps", ("direct/ppo/steps",))]


def test_several_robots_get_a_comparison_each_unless_one_is_named() -> None:
    text = (
        BASE.replace("seeds = 2", 'seeds = 1\nrobot = ["DD", "H15"]')
        + """
[[comparisons]]
name = "ppo"
budget = "steps"
treatments = ["direct/ppo", "interpolation/ppo"]

[[comparisons]]
name = "cmaes-h15"
budget = "steps"
robot = "H15"
treatments = ["direct/cmaes", "interpolation/cmaes"]
"""
    )
    study = parse_study(text)
    assert [(c.name, c.condition) for c in study.comparisons] == [
        ("ppo-DD", "steps-DD"),
        ("ppo-H15", "steps-H15"),
        ("cmaes-h15", "steps-H15"),
    ]
    assert study.comparisons[1].treatments == (
        "direct/ppo/steps-H15",
        "interpolation/ppo/steps-H15",
    )


def test_a_comparison_of_9_treatments_is_refused_naming_it() -> None:
    trainers = list(dict.fromkeys(t.split("/")[0] for t in parse_study(WIDE).treatments))
    nine = ", ".join([*(f'"{t}/ppo"' for t in trainers), '"direct/a2c"'])
    text = (
        WIDE
        + f"""
[[comparisons]]
name = "too-many"
treatments = [{nine}]
"""
    )
    eight = text.replace(', "direct/a2c"', "")
    assert len(parse_study(eight).comparisons[0].treatments) == 8
    with pytest.raises(StudyError, match=r"comparison 'too-many': 9 treatments; .* at most 8"):
        parse_study(text)


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ('name = "x"\nbudget = "steps"\ntreatments = ["direct/a2c"]',
         r"comparison 'x': treatment 'direct/a2c' is not a trainer/algorithm cell of the study"),
        ('name = "x"\nbudget = "steps"\ntreatments = ["direct/ppo/steps"]',
         "treatment 'direct/ppo/steps' is not a trainer/algorithm cell"),
        ('name = "x"\nbudget = "hours"\ntreatments = ["direct/ppo"]',
         r"comparison 'x': budget 'hours' is not one of the study's budgets \(steps, clock\)"),
        ('name = "x"\ntreatments = ["direct/ppo"]',
         r"comparison 'x': no budget \(the study has several: steps, clock\)"),
        ('name = "x"\nbudget = "steps"\nrobot = "H15"\ntreatments = ["direct/ppo"]',
         "robot 'H15' is not one of the study's robots"),
        ('name = "x y"\nbudget = "steps"\ntreatments = ["direct/ppo"]',
         r"comparisons\[0\]: name 'x y' is not made of letters, digits and dashes"),
        ('budget = "steps"\ntreatments = ["direct/ppo"]', r"comparisons\[0\]: name None"),
        ('name = "x"\nbudget = "steps"\ntreatments = []', "treatments \\[\\] is not a non-empty"),
        ('name = "x"\nbudget = "steps"\ntreatments = ["direct/ppo", "direct/ppo"]',
         "names one twice"),
        ('name = "x"\nbudget = "steps"\ntreatments = ["direct/ppo"]\ncolour = "red"',
         r"comparisons\[0\]: unknown key\(s\) colour"),
        ('name = "x"\nbudget = "steps"\ntreatments = ["direct/ppo", "direct/cmaes"]\n'
         'pairs = [["direct/ppo", "interpolation/ppo"]]',
         "'interpolation/ppo' is not one of the comparison's treatments"),
        ('name = "x"\nbudget = "steps"\ntreatments = ["direct/ppo"]\n'
         'pairs = [["direct/ppo", "direct/ppo"]]',
         "compares a treatment with itself"),
        ('name = "x"\nbudget = "steps"\ntreatments = ["direct/ppo"]\npairs = ["direct/ppo"]',
         "is not a \\[first, second\\] pair"),
    ],
)  # fmt: skip
def test_a_bad_comparison_is_refused_naming_the_value(table: str, message: str) -> None:
    with pytest.raises(StudyError, match=message):
        parse_study(BASE + "[[comparisons]]\n" + table + "\n")


def test_two_comparisons_of_one_name_are_refused() -> None:
    table = '[[comparisons]]\nname = "x"\nbudget = "steps"\ntreatments = ["direct/ppo"]\n'
    with pytest.raises(StudyError, match="the name\\(s\\) 'x' are used twice"):
        parse_study(BASE + table + table)
    with pytest.raises(StudyError, match="is not a list of tables"):
        parse_study(BASE.replace("[budgets]", 'comparisons = "all"\n[budgets]'))


def test_the_shipped_studies_declare_comparisons_of_at_most_8() -> None:
    for name in study_names():
        study = load_study(name)
        declared = [c for c in study.comparisons if c.declared]
        assert declared, name
        for comparison in declared:
            assert 1 <= len(comparison.treatments) <= MAX_LINES
            assert set(comparison.treatments) <= set(study.treatments)
