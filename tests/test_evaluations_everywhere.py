"""Every regime of every trainer writes the same ``evaluations.csv``, on the same evaluation set.

Each regime x algorithm (A2C and PPO of both frameworks, sb3 and jax) runs
at a tiny budget with 4 anytime points; the file must have the same columns
everywhere, every point in order (the in-loop ones and the final agent's),
counts that only grow, and the digest of the one evaluation set every run of
the same family shares.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from amaze.curriculum.regimes import REGIMES
from amaze.runs.anytime import EVALUATION_FIELDS, EvaluationSet
from amaze.runs.folder import ProgressLog
from evolution.cli import main as evolve_main
from rl_baselines.cli import main as train_main

MAZE = "M3_6x6_C1"
POINTS = 4
FAMILY = 2
EVOLUTION = ("cmaes", "neat")
RL = ("a2c", "ppo")  # SB3's; "a2c-jax" and "ppo-jax" are the JAX framework's


def _argv(regime: str, algo: str, config: Path, out: Path) -> list[str]:
    algo, _, framework = algo.partition("-")  # "ppo-jax": PPO of the JAX framework
    argv = ["--algo", algo, "--regime", regime, "--seed", "1", "--no-progress"]
    argv += ["--framework", framework] if framework else []
    argv += ["--evaluation-points", str(POINTS), "--evaluation-family", str(FAMILY)]
    argv += ["--mazes", MAZE] if regime == "direct" else ["--target", MAZE]
    if regime in ("interpolation", "edhucat"):
        argv += ["--stages", "2"]
    if regime in ("edhucat", "edens"):
        argv += ["--branches", "2"]
    if regime == "edens":
        argv += ["--epochs", "2"]
    budget = "60000" if algo in EVOLUTION else "640"
    return [*argv, "--budget-steps", budget, "--config", str(config), "--out", str(out)]


def _options(algo: str, regime: str) -> dict:
    algo = algo.partition("-")[0]
    epochs = regime == "edens-populations"
    selector = {"selector": {"alternatives": 2, "epoch": 2}} if epochs else {}
    if algo in EVOLUTION and regime == "edens-populations":  # epochs of 2 x 2 generations
        return {"algorithm": {"population_size": 8}, **selector}
    if algo in EVOLUTION:
        return {"algorithm": {"population_size": 8}}
    rollout = {"n_steps": 8, **({"batch_size": 16} if algo == "ppo" else {})}
    return {"hyperparameters": rollout, **selector}


#: The JAX framework's runs compile, so they are in the slow tier; direct runs of both
#: frameworks stay in the fast one.
JAX_ALGOS = [pytest.param(a, marks=pytest.mark.slow) for a in ("a2c-jax", "ppo-jax")]


@pytest.mark.parametrize("algo", ["cmaes", "neat", "a2c", "ppo", *JAX_ALGOS])
@pytest.mark.parametrize("regime", REGIMES)
def test_every_run_folder_has_the_same_evaluations(tmp_path: Path, regime: str, algo: str) -> None:
    if algo in RL and regime == "edens-populations":
        pytest.skip("SB3 does not run the edens-populations regime (refused; JAX does)")
    config = tmp_path / "options.json"
    config.write_text(json.dumps(_options(algo, regime)))
    out = tmp_path / "run"
    main = evolve_main if algo in EVOLUTION else train_main
    assert main(_argv(regime, algo, config, out)) == 0

    assert (out / "evaluations.csv").read_text().splitlines()[0] == ",".join(EVALUATION_FIELDS)
    rows = ProgressLog(out / "evaluations.csv", EVALUATION_FIELDS).rows()
    assert [int(row["point"]) for row in rows] == list(range(1, POINTS + 1))
    digest = EvaluationSet.of([MAZE], "DD", FAMILY).digest
    assert {row["evaluation_set"] for row in rows} == {digest}
    for name in ("position", "env_steps", "training_seconds", "elapsed_seconds"):
        values = [float(row[name]) for row in rows]
        assert values == sorted(values), name
    for row in rows:
        assert float(row["evaluation_seconds"]) >= 0
        assert float(row["elapsed_seconds"]) >= float(row["training_seconds"])
        assert 0 <= float(row["success_rate"]) <= 1 and float(row["normalized_reward"]) <= 1
    assert float(rows[0]["evaluation_seconds"]) > 0 and float(rows[-1]["evaluation_seconds"]) > 0
    summary = json.loads((out / "summary.json").read_text())
    assert int(rows[-1]["env_steps"]) == summary["env_steps"]  # the last point: the final agent
    assert summary["anytime"]["points"] == POINTS
    assert summary["anytime"]["evaluation_set"] == digest
    cost = sum(float(row["evaluation_seconds"]) for row in rows)
    assert summary["anytime"]["seconds"] == pytest.approx(cost, abs=0.005)
