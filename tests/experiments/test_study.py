"""Studies as TOML files: the grid, the options, and bad studies refused by name."""

from __future__ import annotations

import pytest

from experiments.study import StudyError, load_study, parse_study, study_names

BASE = """
name = "t"
seeds = 2
trainers = ["direct", "edhucat-careful"]
algorithms = ["ppo", "cmaes"]
[budgets]
steps = { steps = 50_000 }
"""


def test_the_grid_crosses_budgets_trainers_algorithms_and_seeds() -> None:
    study = parse_study(
        BASE
        + """
clock = { seconds = 30 }
[options.all]
target = "M3_8x8_C1"
[options.cmaes]
algorithm = { population_size = 12 }
[options.edhucat-careful]
stages = 4
[options."edhucat-careful/ppo"]
n_envs = 8
[[exclude]]
trainer = "direct"
algorithm = "ppo"
"""
    )
    assert len(study.runs) == 2 * 3 * 2  # budgets x cells (4 less the excluded one) x seeds
    assert study.treatments[:3] == [
        "direct/cmaes/steps",
        "edhucat-careful/ppo/steps",
        "edhucat-careful/cmaes/steps",
    ]
    run = next(r for r in study.runs if r.id == "edhucat-careful_ppo_clock_seed-1")
    c = run.config
    assert (c["regime"], c["curator"], c["stages"], c["n_envs"]) == ("edhucat", "careful", 4, 8)
    assert (c["budget_seconds"], c["budget_steps"], c["seed"]) == (30, None, 1)
    assert c["target"] == "M3_8x8_C1"
    cma = next(r for r in study.runs if r.id == "direct_cmaes_steps_seed-0").config
    assert cma["algorithm"]["population_size"] == 12
    assert cma["budget_steps"] == 50_000 and cma.get("budget_seconds") is None
    assert "stages" not in cma or cma["stages"] is None  # the direct regime has none
    assert cma["target"] != "M3_8x8_C1"  # options.all gives each run what acts in its regime


def test_several_robots_make_conditions_of_their_own() -> None:
    study = parse_study(_with(BASE, 'robot = ["DD", "H15"]\n'))
    assert len(study.runs) == 2 * 4 * 2
    run = next(r for r in study.runs if r.id == "direct_ppo_steps-H15_seed-0")
    assert (run.robot, run.condition) == ("H15", "steps-H15")
    assert run.config["robot"] == "CD15"  # the hybrid robot, canonical
    assert run.treatment == "direct/ppo/steps-H15"
    single = parse_study(BASE).runs[0]
    assert (single.robot, single.condition, single.config["robot"]) == (None, "steps", "DD")


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ("name = 3\n", "name 3"),
        ("colour = 'red'\n", "colour"),
        ("seeds = 0\n", "seeds 0"),
        ("robot = ['DD', 'DD']\n", "twice"),
        ("robot = 3\n", "robot 3"),
        ("robot = 'XY'\n", "XY"),
        ("seeds = [1, 1]\n", "repeats"),
        ("trainers = ['sideways']\n", "'sideways'"),
        ("algorithms = ['sarsa']\n", "'sarsa'"),
        ("algorithms = []\n", "algorithms []"),
        ("[budgets]\nsteps = { minutes = 3 }\n", "minutes"),
        ("[options.ppo]\nseed = 4\n", "'seed'"),
        ("[options.walking]\nx = 1\n", "options.walking"),
        ("[options.ppo]\nn_envs = 3\n", "n_envs 3"),
        ("[options.cmaes]\nalgorithm = { population_size = -2 }\n", "population_size"),
        ("[[exclude]]\ntrainer = 'direct'\n", "exclude"),
        ("suite = 'best'\n", "suite 'best' is not one of standard, paper"),
        ("this is not toml", "not valid TOML"),
    ],
)
def test_a_bad_study_is_refused_naming_the_value(change: str, named: str) -> None:
    text = change if change == "this is not toml" else _with(BASE, change)
    with pytest.raises(StudyError) as problem:
        parse_study(text, "study file 'x.toml'")
    assert named in str(problem.value)
    assert "x.toml" in str(problem.value)


def _with(base: str, change: str) -> str:
    """``base`` with the top-level key of ``change`` replaced (tables are appended)."""
    if change.startswith("["):
        if change.startswith("[budgets]"):
            return base.split("[budgets]")[0] + change
        return base + change
    key = change.split("=")[0].strip()
    kept = [line for line in base.splitlines() if not line.startswith(f"{key} ")]
    return change + "\n".join(kept)


def test_a_config_error_names_the_run() -> None:
    with pytest.raises(StudyError, match="run direct_cmaes_steps_seed-0"):
        parse_study(BASE + "[options.cmaes]\nfitness = 'speed'\n")


def test_every_shipped_study_loads() -> None:
    assert set(study_names()) >= {"smoke", "paper", "evo-vs-rl", "curators"}
    for name in study_names():
        study = load_study(name)
        assert study.runs and study.description
    paper = load_study("paper")
    assert {r.config["budget_steps"] for r in paper.runs} == {3_000_000}
    assert len(paper.runs) == 3 * 2 * 10
    evo = load_study("evo-vs-rl")
    assert {r.algorithm for r in evo.runs} == {"a2c", "ppo", "cmaes", "neat"}
    assert {r.budget for r in evo.runs} == {"steps", "clock"}


def test_the_mixed_study_compares_a_strategy_an_algorithm_and_both_at_an_equal_budget() -> None:
    mixed = load_study("mixed")
    assert len(mixed.runs) == 3 * 2 * 5
    assert {r.algorithm for r in mixed.runs} == {"cmaes", "ppo"}
    assert len({r.config["budget_steps"] for r in mixed.runs}) == 1  # one budget for all
    by_trainer = {r.trainer: r.config for r in mixed.runs}
    assert by_trainer["edhucat-careful"]["curator"] == "careful"
    assert by_trainer["edhucat-careful"]["advisor"] is None
    assert by_trainer["edhucat-edens"]["curator"] == "edens"
    both = by_trainer["edhucat-follow-edens"]
    assert (both["curator"], both["advisor"]) == ("follow", "edens")
    assert both["curator_options"] == {"p": 0.5, "base": "careful"}
    loops = {(c["regime"], c["stages"], c["branches"]) for c in by_trainer.values()}
    assert loops == {("edhucat", 5, 3)}  # the same loop for the three


def test_domain_randomisation_plays_the_curricula_s_evaluation_set() -> None:
    """Its runs train on other family mazes, but their anytime evaluations are comparable."""
    from amaze.runs.anytime import EvaluationSet
    from experiments.trainers import run_class

    for name in ("regimes-evolution", "rl-automated"):
        digests = {}
        for run in load_study(name).runs:
            config = run_class(run.algorithm).config_class.from_dict(run.config).validate()
            digests.setdefault(run.trainer, set()).add(EvaluationSet.for_config(config).digest)
        assert len(set().union(*digests.values())) == 1, (name, digests)
        assert "domain-randomisation" in digests
