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
    assert {r.algorithm for r in evo.runs} == {"cmaes", "neat", "ppo", "ppo-fast", "a2c-fast"}
    assert {r.budget for r in evo.runs} == {"steps", "clock"}
    assert len(evo.runs) == 4 * 5 * 2 * 5
    jax = [r.config for r in evo.runs if r.algorithm in ("ppo", "ppo-fast", "a2c-fast")]
    assert {c["framework"] for c in jax} == {"jax"}  # edens-populations copies the learner


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


#: PPO at the study's [options.ppo], a variant of it at settings of its own, and CMA-ES.
VARIANTS = """
name = "v"
seeds = 2
trainers = ["direct", "edhucat-careful"]
algorithms = ["ppo", "ppo-fast", "cmaes"]
[variants]
ppo-fast = "ppo"
[budgets]
steps = { steps = 50_000 }
[options.all]
target = "M3_8x8_C1"
[options.ppo]
n_envs = 8
hyperparameters = { n_steps = 512, learning_rate = 1e-3 }
[options.ppo-fast]
n_envs = 16
hyperparameters = { n_steps = 64, batch_size = 256, n_epochs = 4 }
[options."edhucat-careful/ppo-fast"]
stages = 3
[[exclude]]
trainer = "direct"
algorithm = "cmaes"
[[comparisons]]
name = "settings"
treatments = ["direct/ppo", "direct/ppo-fast", "edhucat-careful/ppo-fast"]
pairs = [["direct/ppo-fast", "direct/ppo"]]
"""


def test_a_variant_runs_its_base_algorithm_with_its_own_options_under_its_own_name() -> None:
    study = parse_study(VARIANTS)
    assert study.variants == {"ppo-fast": "ppo"}
    assert len(study.runs) == 5 * 2  # 2 trainers x 3 algorithms, less direct/cmaes, x 2 seeds
    fast = next(r for r in study.runs if r.id == "direct_ppo-fast_steps_seed-1")
    assert (fast.algorithm, fast.base_algorithm, fast.treatment) == (
        "ppo-fast",
        "ppo",
        "direct/ppo-fast/steps",
    )
    assert fast.config["algo"] == "ppo"
    assert fast.config["n_envs"] == 16
    hyper = fast.config["hyperparameters"]
    assert (hyper["n_steps"], hyper["batch_size"], hyper["n_epochs"]) == (64, 256, 4)
    assert hyper["learning_rate"] == 3e-4  # SB3's default: [options.ppo] is not the variant's
    plain = next(r for r in study.runs if r.id == "direct_ppo_steps_seed-1").config
    assert (plain["algo"], plain["n_envs"], plain["hyperparameters"]["n_steps"]) == ("ppo", 8, 512)
    assert plain["hyperparameters"]["learning_rate"] == 1e-3
    assert plain["hyperparameters"]["batch_size"] == 64  # nor the variant's the base's
    careful = next(r for r in study.runs if r.id == "edhucat-careful_ppo-fast_steps_seed-0")
    assert (careful.config["stages"], careful.config["target"]) == (3, "M3_8x8_C1")
    assert next(r for r in study.runs if r.algorithm == "ppo").config["stages"] != 3
    settings = study.comparisons[0]
    assert settings.pairs == (("direct/ppo-fast/steps", "direct/ppo/steps"),)
    # the default comparisons set the variant beside its base and the other algorithms
    default = parse_study(VARIANTS.split("[[comparisons]]")[0]).comparisons
    trainers = next(c for c in default if c.name == "trainers-ppo-fast-steps")
    assert trainers.treatments == ("direct/ppo-fast/steps", "edhucat-careful/ppo-fast/steps")


def test_an_evolution_variant_is_checked_as_its_base() -> None:
    text = BASE.replace('"cmaes"]', '"cmaes", "cmaes-small"]')
    text += "[variants]\ncmaes-small = 'cmaes'\n"
    small = parse_study(
        text
        + "[options.cmaes-small]\nalgorithm = { population_size = 6 }\n"
        + "[[exclude]]\ntrainer = 'edhucat-careful'\nalgorithm = 'cmaes-small'\n"
    )
    assert {r.cell for r in small.runs if r.algorithm == "cmaes-small"} == {"direct/cmaes-small"}
    config = next(r for r in small.runs if r.algorithm == "cmaes-small").config
    assert (config["algo"], config["algorithm"]["population_size"]) == ("cmaes", 6)
    base = next(r for r in small.runs if r.algorithm == "cmaes").config
    assert base["algorithm"]["population_size"] != 6
    with pytest.raises(StudyError, match=r"run direct_cmaes-small_steps_seed-0: .*population_size"):
        parse_study(text + "[options.cmaes-small]\nalgorithm = { population_size = -2 }\n")


def _variants(declared: str, algorithms: str = '["ppo", "ppo-fast"]', rest: str = "") -> str:
    """A study whose ``[variants]`` table (or top-level ``variants`` key) is ``declared``."""
    head = f'name = "v"\ntrainers = ["direct"]\nalgorithms = {algorithms}\n'
    if not declared.startswith("["):
        head, declared = declared + head, ""
    return head + declared + "[budgets]\nsteps = { steps = 50_000 }\n" + rest


#: Bad variants, each a study and what its error names.
BAD_VARIANTS = [
    (_variants("variants = 3\n"), "variants 3 is not a table"),
    (_variants("variants = ['ppo']\n"), "variants ['ppo'] is not a table"),
    (_variants("[variants]\nppo-fast = 3\n"), "variant 'ppo-fast' = 3: its base is not one"),
    (_variants("[variants]\nppo-fast = 'sarsa'\n"), "'sarsa': its base is not one of a2c,"),
    (_variants("[variants]\nppo-fast = { algo = 'ppo' }\n"), "its base is not one of"),
    (
        _variants(
            "[variants]\nppo-fast = 'ppo'\nppo-faster = 'ppo-fast'\n",
            '["ppo-fast", "ppo-faster"]',
        ),
        "variant 'ppo-faster' = 'ppo-fast': its base is not one of a2c, ppo, cmaes, neat",
    ),
    (_variants("[variants]\nfast_ppo = 'ppo'\n", '["fast_ppo"]'), "name 'fast_ppo' is not"),
    (_variants("[variants]\n-fast = 'ppo'\n", '["-fast"]'), "name '-fast' is not made"),
    (_variants("[variants]\n'ppo/fast' = 'ppo'\n", '["ppo/fast"]'), "'ppo/fast' is not"),
    (_variants("[variants]\nppo = 'a2c'\n", '["ppo"]'), "variant name 'ppo' is already"),
    (_variants("[variants]\nPPO = 'ppo'\n", '["PPO"]'), "variant name 'PPO' is already"),
    (_variants("[variants]\ndirect = 'ppo'\n", '["direct"]'), "variant name 'direct' is"),
    (_variants("[variants]\nall = 'ppo'\n", '["all"]'), "variant name 'all' is already"),
    (
        _variants("[variants]\nppo-fast = 'ppo'\nPPO-Fast = 'ppo'\n", '["ppo-fast", "PPO-Fast"]'),
        "variant name 'PPO-Fast' is already",
    ),
    (
        _variants("[variants]\nppo-fast = 'ppo'\nppo-wide = 'ppo'\n"),
        "variants: 'ppo-wide' declared but not in algorithms",
    ),
    (_variants(""), "algorithms: 'ppo-fast' is not one of a2c, ppo, cmaes, neat"),
    (
        _variants("[variants]\nppo-fast = 'ppo'\n", rest="[options.ppo-slow]\nn_envs = 8\n"),
        "options.ppo-slow: not 'all', a trainer, an algorithm",
    ),
    (
        _variants(
            "[variants]\nppo-fast = 'ppo'\n", rest="[options.'direct/ppo-slow']\nn_envs = 8\n"
        ),
        "options.direct/ppo-slow: not 'all'",
    ),
    (
        _variants("[variants]\nppo-fast = 'ppo'\n", rest="[options.ppo-fast]\nalgo = 'a2c'\n"),
        "options.ppo-fast sets 'algo', which the study's grid decides",
    ),
    (
        _variants(
            "[variants]\nppo-fast = 'ppo'\n",
            rest="[[comparisons]]\nname = 'c'\ntreatments = ['direct/ppo-slow']\n",
        ),
        "treatment 'direct/ppo-slow' is not a trainer/algorithm cell",
    ),
]


@pytest.mark.parametrize(("text", "named"), BAD_VARIANTS, ids=[n for _, n in BAD_VARIANTS])
def test_a_bad_variant_is_refused_naming_the_file_and_the_value(text: str, named: str) -> None:
    with pytest.raises(StudyError) as problem:
        parse_study(text, "study file 'x.toml'")
    assert named in str(problem.value)
    assert str(problem.value).startswith("study file 'x.toml': ")


def test_a_good_variant_study_of_the_refusals_loads() -> None:
    """The refusals above are of the changed value alone: the study they change is good."""
    study = parse_study(_variants("[variants]\nppo-fast = 'ppo'\n", '["ppo-fast", "ppo"]'))
    assert [r.algorithm for r in study.runs] == ["ppo-fast", "ppo"]
