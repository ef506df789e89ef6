"""Every option of both training commands has an effect in the regime chosen, or is refused.

The walk goes over every field of both trainers' configs and every regime: a
field declares the regimes it acts in (``option(regimes=...)``); set in any
other, the config is refused with one error naming it. Fields that act in
every regime are listed here, reviewed: a new field must join one side or the
other, or this test fails.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from amaze.curriculum.regimes import REGIMES
from amaze.runs.regime import DEFAULT_CURATOR
from evolution.cli import main as evolve_main
from evolution.config import EvolveConfig
from rl_baselines.cli import main as train_main
from rl_baselines.config import TrainConfig

#: Fields that act in every regime, by trainer.
EVERYWHERE = {
    EvolveConfig: {
        "robot", "seed", "regime", "algo", "fitness", "budget_steps", "budget_seconds",
        "checkpoint_seconds", "algorithm", "evaluation_points", "evaluation_family",
    },
    TrainConfig: {
        "robot", "seed", "regime", "algo", "budget_steps", "budget_seconds", "eval_every",
        "n_envs", "tensorboard", "hyperparameters", "evaluation_points", "evaluation_family",
        "framework", "network", "preset", "progress_reward",
    },
}  # fmt: skip
#: A value other than the default for each regime-bound field (per regime where it matters).
SAMPLES: dict[str, Any] = {
    "stages": 3,
    "branches": 2,
    "rehearsal": 1,
    "target": "M3_8x8_C1",
    "mazes": ["M1_5x5_C1"],
    "eval_mazes": ["M2_5x5_C1"],
    "evaluation_maze": "M4_8x8_C1",
    "agent_rule": "final",
    "final_training": False,
    "curator_options": {"seed_step": 1},
    "advisor": "edens",
    "advisor_options": {"validation": 2},
    "replay": "elsewhere",
    "coevolution": {"capacity": 8},
    "selector": {"epoch": 5},
    "max_generations": 3,
    "slip": 0.1,
    "protocol": "paper-code",
    "stage_eval_target": "M5_8x8_C1",
    "stage_evaluations": 5,
}


def _sample(name: str, regime: str, config_class: type = TrainConfig) -> dict[str, Any]:
    """A config setting ``name`` away from its default, valid where ``name`` acts in ``regime``."""
    if name == "curator":
        return {"curator": DEFAULT_CURATOR.get(regime, "random")}
    if name == "epochs":
        return {"epochs": 5, "stages": 0} if regime in ("edhucat", "edens") else {"epochs": 5}
    if name == "advisor_options" and regime == "edhucat":
        return {"advisor": "edens", "advisor_options": SAMPLES[name]}  # options need an advisor
    if name == "curator_options" and regime in ("interpolation", "edens"):
        return {"curator_options": {}}  # only the edhucat regime's default curator takes one
    series = config_class is TrainConfig and regime == "interpolation"
    if name in ("stage_evaluations", "agent_rule") and series:
        # in interpolation, both act on an evaluation series
        return {name: SAMPLES[name], "stage_eval_target": SAMPLES["stage_eval_target"]}
    return {name: SAMPLES[name]}


def _fields(config_class: type) -> list[dataclasses.Field]:
    return list(dataclasses.fields(config_class))


@pytest.mark.parametrize("config_class", [EvolveConfig, TrainConfig], ids=["evolve", "train"])
def test_every_field_is_either_bound_to_regimes_or_acts_everywhere(config_class: type) -> None:
    bound = {f.name for f in _fields(config_class) if f.metadata.get("regimes") is not None}
    free = {f.name for f in _fields(config_class)} - bound
    assert free == EVERYWHERE[config_class]
    assert bound <= set(SAMPLES) | {"curator", "epochs"}


CASES = [
    (config_class, f.name, regime)
    for config_class in (EvolveConfig, TrainConfig)
    for f in _fields(config_class)
    if f.metadata.get("regimes") is not None
    for regime in REGIMES
    if regime in config_class.supported_regimes
]


@pytest.mark.parametrize(
    ("config_class", "name", "regime"),
    CASES,
    ids=[f"{c.__name__}-{n}-{r}" for c, n, r in CASES],
)
def test_a_field_is_refused_where_it_has_no_effect(
    config_class: type, name: str, regime: str
) -> None:
    field = next(f for f in _fields(config_class) if f.name == name)
    data = {"regime": regime, "budget_steps": 10**6, **_sample(name, regime, config_class)}
    if config_class is TrainConfig and regime == "edens-populations":
        data.setdefault("framework", "jax")  # SB3 is refused in this regime, by name
    if regime in field.metadata["regimes"]:
        if name in ("epochs", "curator_options") and data.get(name) in (5, {}):
            if regime not in ("edhucat", "edens"):
                pytest.skip(f"{name} acts only in open-ended or edhucat runs of {regime}")
        if name == "replay":
            pytest.skip("replay is set by --replay, from a run folder")
        config_class.from_dict(data)  # accepted: the field acts in this regime
    else:
        with pytest.raises(config_class.error, match=f"has no effect in the {regime} regime"):
            config_class.from_dict(data)


@pytest.mark.parametrize(
    ("main", "argv", "words"),
    [
        (evolve_main, ["--target", "M4_10x10_C1"], "target (--target) 'M4_10x10_C1' has no effect"),
        (train_main, ["--target", "M4_10x10_C1"], "has no effect in the direct regime"),
        (evolve_main, ["--regime", "edhucat", "--mazes", "M1_5x5_U"], "mazes (--mazes)"),
        (train_main, ["--regime", "coevolution", "--eval-mazes", "M1_5x5_U"], "eval_mazes"),
        (evolve_main, ["--regime", "edhucat", "--max-generations", "3"], "max_generations"),
        (train_main, ["--agent-rule", "best-fitness"], "agent_rule 'best-fitness' is not one"),
        (evolve_main, ["--agent-rule", "best-eval"], "best-eval' needs eval_mazes"),
        (evolve_main, ["--workers", "2"], "--workers 2 runs replicates at once"),
    ],
)
def test_options_without_effect_are_one_error_line(
    main: Any, argv: list[str], words: str, tmp_path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*argv, "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "run").exists()
