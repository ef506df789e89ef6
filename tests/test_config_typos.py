"""A typo in any config file a command reads is named with the key it was meant to be.

``amaze-train`` and ``amaze-evolve`` take ``--config`` files (JSON or YAML):
a whole config, or the options of the trainer alone (SB3 hyperparameters, a
search algorithm's settings). A file with one key of a config is a whole
config, so a misspelt key beside it is refused as an unknown config key,
never blamed on a valid one; each refusal names the closest known key.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from evolution.cli import main as evolve
from experiments.cli import main as experiment
from rl_baselines.cli import main as train


def _train(config: Path, out: Path) -> list[str]:
    return ["--config", str(config), "--out", str(out)]


CASES: list[tuple[Callable[[list[str]], int], str, object, str]] = [
    (
        train,
        "c.yml",
        "algo: ppo\nbudget_step: 8192\n",
        "'budget_step' (did you mean 'budget_steps'?)",
    ),
    (train, "c.json", {"algo": "ppo", "n_env": 8}, "'n_env' (did you mean 'n_envs'?)"),
    (train, "c.json", {"n_stepz": 16}, "'n_stepz' is not one of PPO's (did you mean 'n_steps'?)"),
    (evolve, "c.yml", "algo: cmaes\nbudget_steps: 100\nsed: 3\n", "'sed' (did you mean 'seed'?)"),
    (evolve, "c.json", {"popsize": 8}, "(did you mean"),
    (
        evolve,
        "c.json",
        {"algo": "cmaes", "algorithm": {"network": {"hiden": [8]}}},
        "hiden (did you mean 'hidden'?)",
    ),
    (
        evolve,
        "c.json",
        {"regime": "coevolution", "coevolution": {"capacty": 8}},
        "'capacty' (did you mean 'capacity'?)",
    ),
]


@pytest.mark.parametrize(("command", "name", "content", "words"), CASES)
def test_a_typo_is_named_with_the_key_it_was_meant_to_be(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command, name, content, words: str
) -> None:
    config = tmp_path / name
    config.write_text(content if isinstance(content, str) else json.dumps(content))
    assert command(_train(config, tmp_path / "run")) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "run").exists()


def test_a_typo_in_a_study_file_is_named_with_the_key_it_was_meant_to_be(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = tmp_path / "typo.toml"
    study.write_text('name = "typo"\nseds = 3\n')
    assert experiment(["run", str(study), "--out", str(tmp_path / "study")]) == 2
    err = capsys.readouterr().err
    assert "seds (did you mean 'seeds'?)" in err, err
