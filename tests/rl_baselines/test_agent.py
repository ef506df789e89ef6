"""SB3Agent: the shared policy protocol, save/load round trip, evaluation."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from stable_baselines3 import A2C

from amaze.evaluation.protocol import evaluate
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent, algorithm_class
from rl_baselines.vec_env import SB3VecEnv

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def agent() -> SB3Agent:
    env = SB3VecEnv(["M1_5x5_U", "M2_6x5_C1"], "DD", 4, seed=0)
    model = A2C("MlpPolicy", env, seed=0, device="cpu")
    model.learn(200)
    return SB3Agent(model, "DD")


def test_actions_follow_the_protocol(agent: SB3Agent) -> None:
    obs = np.random.default_rng(0).uniform(-1, 1, size=(7, 8)).astype(np.float32)
    actions = agent(obs)
    assert actions.shape == (7,) and actions.dtype == np.int64
    assert ((actions >= 0) & (actions <= 3)).all()
    np.testing.assert_array_equal(actions, agent(obs))  # deterministic


def test_save_load_gives_identical_actions(agent: SB3Agent, tmp_path: Path) -> None:
    path = agent.save(tmp_path / "agent")
    assert path.name == "agent.zip"
    meta = json.loads((tmp_path / "agent.json").read_text())
    assert meta["robot"] == "DD" and meta["algo"] == "a2c"
    loaded = SB3Agent.load(tmp_path / "agent.zip")
    obs = np.random.default_rng(1).uniform(-1, 1, size=(256, 8)).astype(np.float32)
    np.testing.assert_array_equal(loaded(obs), agent(obs))
    with torch.no_grad():
        for a, b in zip(
            agent.model.policy.state_dict().values(),
            loaded.model.policy.state_dict().values(),
            strict=True,
        ):
            assert torch.equal(a, b)
    assert not list(tmp_path.glob(".*tmp*"))  # no temporary file left behind


def test_shared_evaluation(agent: SB3Agent) -> None:
    summary = evaluate(agent, "DD").summary()
    assert summary["episodes"] == 72
    assert 0.0 <= summary["success_rate"] <= 1.0
    assert summary["input_recognition"] is not None


def test_bad_names(tmp_path: Path) -> None:
    with pytest.raises(RLConfigError, match="'dqn'"):
        algorithm_class("dqn")
    with pytest.raises(RLConfigError, match=r"missing\.zip"):
        SB3Agent.load(tmp_path / "missing")


def test_amaze_run_loads_saved_sb3_agents(agent: SB3Agent, tmp_path: Path, capsys) -> None:
    """`amaze run --controller agent.zip` finds the loader through its entry point."""
    from amaze.cli.main import main

    path = agent.save(tmp_path / "agent")
    assert main(["run", "M1_5x5_U", "--controller", str(path), "--json"]) == 0
    outcome = json.loads(capsys.readouterr().out)
    assert outcome["robot"] == "DD" and outcome["steps"] > 0
    assert main(["run", "M1_5x5_U", "--controller", str(path), "--robot", "H7"]) == 2
    assert "drives DD robots" in capsys.readouterr().err
