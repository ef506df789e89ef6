"""``--protocol paper-code`` and the options it sets, each of which does what it names.

The protocol fills only what a config leaves unset; an interpolation's evaluation series
(``stage_eval_target``) judges every stage on the same stage of another maze's
interpolation, at ``stage_evaluations`` evaluations per stage, and ``agent_rule`` picks the
last stage's best or its final model; a direct run's ``best-eval-reward`` is SB3's
``EvalCallback`` best model.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from amaze.curriculum.interpolation import curriculum
from amaze.evaluation.suite import PAPER_EVALUATION_MAZE, PAPER_TRAINING_MAZE
from amaze.maze import rotations
from amaze.maze.spec import MazeSpec
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent
from rl_baselines.cli import main
from rl_baselines.config import TrainConfig
from rl_baselines.jax.learner import load_jax_learner
from rl_baselines.protocols import PAPER_CODE_LEARNING_RATE


def _canonical(maze: str) -> str:
    return MazeSpec.from_string(maze).to_string()


def test_paper_code_fills_each_regimes_options() -> None:
    direct = TrainConfig.from_dict({"protocol": "paper-code", "budget_steps": 1_000_000})
    assert direct.agent_rule == "best-eval-reward" and direct.eval_every == 10_000
    assert direct.hyperparameters["learning_rate"] == PAPER_CODE_LEARNING_RATE
    interpolation = TrainConfig.from_dict({"protocol": "paper-code", "regime": "interpolation"})
    assert interpolation.target == _canonical(PAPER_EVALUATION_MAZE)
    assert interpolation.stage_eval_target == _canonical(PAPER_TRAINING_MAZE)
    assert interpolation.stage_evaluations == 100 and not interpolation.final_training
    assert interpolation.agent_rule == "best-eval-reward"
    edhucat = TrainConfig.from_dict({"protocol": "paper-code", "regime": "edhucat"})
    assert not edhucat.final_training and edhucat.hyperparameters["learning_rate"] == 1e-3
    plain = TrainConfig.from_dict({"regime": "interpolation"})
    assert plain.final_training and plain.stage_eval_target is None
    assert plain.hyperparameters["learning_rate"] == 3e-4  # SB3's PPO default


def test_given_options_win_over_the_protocol_and_a_saved_config_reads_the_same() -> None:
    config = TrainConfig.from_dict(
        {
            "protocol": "paper-code",
            "agent_rule": "final",
            "eval_every": 50_000,
            "hyperparameters": {"learning_rate": 3e-4},
        }
    )
    assert config.agent_rule == "final" and config.eval_every == 50_000
    assert config.hyperparameters["learning_rate"] == 3e-4
    again = TrainConfig.from_dict(json.loads(json.dumps(config.to_dict())))
    assert again == config
    # a config built in Python: a field at its default counts as unset
    built = TrainConfig(protocol="paper-code", regime="interpolation").validate()
    assert built.stage_eval_target == _canonical(PAPER_TRAINING_MAZE)


@pytest.mark.parametrize(
    ("data", "words"),
    [
        ({"protocol": "paper-code", "regime": "coevolution"}, "no effect in the coevolution"),
        ({"protocol": "paper-plain"}, "unknown protocol 'paper-plain'"),
        (
            {"protocol": "paper-code", "budget_steps": None, "budget_seconds": 60},
            "spaces its 100 evaluations by budget_steps",
        ),
        (
            {"regime": "interpolation", "stage_evaluations": 5},
            "stage_evaluations (--stage-evaluations) 5 needs an evaluation series",
        ),
        (
            {"regime": "interpolation", "agent_rule": "best-eval"},
            "agent_rule (--agent-rule) 'best-eval' needs an evaluation series",
        ),
        (
            {
                "regime": "interpolation",
                "stage_eval_target": "M1_5x5_C1",
                "agent_rule": "best-eval",
            },
            "give --no-final-training",
        ),
        (
            {"regime": "interpolation", "stage_eval_target": "M1_5x5_C1", "stage_evaluations": 0},
            "stage_evaluations",
        ),
        (
            {
                "regime": "interpolation",
                "stage_eval_target": "M1_5x5_C1",
                "budget_steps": None,
                "budget_seconds": 60.0,
            },
            "stage_eval_target needs budget_steps",
        ),
        ({"regime": "edhucat", "stage_eval_target": "M1_5x5_C1"}, "no effect in the edhucat"),
        ({"agent_rule": "best-luck"}, "agent_rule 'best-luck' is not one of"),
    ],
)
def test_what_the_options_cannot_do_is_refused_by_name(data: dict, words: str) -> None:
    with pytest.raises(RLConfigError, match=words.replace("(", "\\(").replace(")", "\\)")):
        TrainConfig.from_dict(data)


#: A small interpolation (3 stages of 6x6 mazes) with an evaluation series of another seed.
SERIES = ["--regime", "interpolation", "--framework", "jax", "--algo", "a2c", "--stages", "3"]
SERIES += ["--target", "M5_6x6_C1", "--stage-eval-target", "M6_6x6_C1", "--budget-steps", "3000"]
SERIES += ["--evaluation-points", "0", "--no-progress", "--no-final-training"]


def _run(out: Path, *options: str) -> dict:
    assert main([*SERIES, *options, "--out", str(out)]) == 0
    return json.loads((out / "summary.json").read_text())


def _watch(branch: Path) -> dict:
    return json.loads((branch / "best" / "learner.json").read_text())["session"]["watch"]


def _actions(agent: object) -> np.ndarray:
    """The agent's actions on fixed random observations (a fingerprint of its weights)."""
    observations = np.random.default_rng(0).random((256, 8)).astype(np.float32)
    return np.asarray(agent(observations))  # type: ignore[operator]


def _learner_agent(folder: Path) -> object:
    return load_jax_learner(folder, algo="a2c", robot="DD", n_envs=4).agent()


def test_an_interpolation_is_watched_on_its_evaluation_series(tmp_path: Path) -> None:
    best = _run(tmp_path / "best", "--agent-rule", "best-eval-reward", "--stage-evaluations", "4")
    series = [m.to_string() for m in curriculum("M6_6x6_C1", 3)]
    stages = best["stage_evaluation"]["stages"]
    assert [s["maze"] for s in stages] == series  # each stage on the same stage of the series
    for stage in stages:
        folder = tmp_path / "best" / "stages" / f"stage-{stage['stage']}" / "branch-0"
        watch = _watch(folder)
        assert watch["mazes"] == rotations(series[stage["stage"]])
        assert watch["every"] == 1000 // 4  # the stage's allowance / stage_evaluations
        assert stage["best_steps"] == watch["best_steps"] and stage["best"] == watch["best"]
    assert best["agent_rule"].startswith("best-eval-reward: the last stage's best")
    # the option walk: fewer evaluations per stage space them further apart
    _run(tmp_path / "fewer", "--agent-rule", "best-eval-reward", "--stage-evaluations", "1")
    assert _watch(tmp_path / "fewer" / "stages" / "stage-0" / "branch-0")["every"] == 1000
    # the agent rule: the last stage's best, or its final model (the same training)
    final = _run(tmp_path / "final", "--stage-evaluations", "4")
    assert final["agent_rule"].startswith("the curator's final choice")
    last = Path("stages") / "stage-2" / "branch-0"
    handed = _actions(SB3Agent.load(tmp_path / "best" / "agent.zip"))
    assert np.array_equal(handed, _actions(_learner_agent(tmp_path / "best" / last / "best")))
    handed = _actions(SB3Agent.load(tmp_path / "final" / "agent.zip"))
    assert np.array_equal(handed, _actions(_learner_agent(tmp_path / "final" / last / "agent")))


def test_a_direct_run_hands_over_evalcallbacks_best(tmp_path: Path) -> None:
    out = tmp_path / "direct"
    options = ["--framework", "jax", "--algo", "a2c", "--protocol", "paper-code"]
    options += ["--mazes", "M5_6x6_C1", "--eval-mazes", "M6_6x6_C1", "--budget-steps", "2000"]
    assert main([*options, "--evaluation-points", "0", "--no-progress", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    config = json.loads((out / "config.json").read_text())
    assert config["eval_every"] == 20 and config["agent_rule"] == "best-eval-reward"
    rows = (out / "progress.csv").read_text().splitlines()[1:]
    rewards = {int(r.split(",")[0]): float(r.split(",")[3]) for r in rows}
    trained = {steps: reward for steps, reward in rewards.items() if steps > 0}
    # the first of the best rewards after training began (never the untrained model)
    best = max(trained.values())
    assert summary["agent_steps"] == min(s for s, r in trained.items() if r == best)
    assert summary["paper_suite"]["success_rate"] >= 0.0
