"""``preset: fast``: the JAX learners' throughput setting fills what a config leaves unset."""

from __future__ import annotations

import pytest

from rl_baselines import RLConfigError
from rl_baselines.presets import PRESETS
from rl_baselines.train import TrainConfig


def test_the_fast_preset_fills_the_fields_a_config_leaves_unset() -> None:
    config = TrainConfig.from_dict({"preset": "fast", "regime": "coevolution"})
    fast = PRESETS["fast"]
    assert config.framework == "jax" and config.n_envs == fast["n_envs"]
    assert config.network == fast["network"] and config.tensorboard is False
    for name, value in fast["hyperparameters"].items():
        assert config.hyperparameters[name] == value, name


def test_given_fields_and_hyperparameters_win_over_the_preset() -> None:
    config = TrainConfig.from_dict(
        {
            "preset": "fast",
            "n_envs": 64,
            "network": {"hidden": [8]},
            "hyperparameters": {"learning_rate": 3e-4},
        }
    )
    assert config.n_envs == 64 and config.network == {"hidden": [8]}
    assert config.hyperparameters["learning_rate"] == 3e-4
    assert config.hyperparameters["n_steps"] == PRESETS["fast"]["hyperparameters"]["n_steps"]


def test_a2c_takes_the_preset_without_ppos_hyperparameters() -> None:
    config = TrainConfig.from_dict({"preset": "fast", "algo": "a2c"})
    assert "batch_size" not in config.hyperparameters and "n_epochs" not in config.hyperparameters
    assert config.hyperparameters["n_steps"] == PRESETS["fast"]["hyperparameters"]["n_steps"]


def test_a_recorded_config_reads_back_the_same() -> None:
    config = TrainConfig.from_dict({"preset": "fast", "seed": 3})
    assert TrainConfig.from_dict(config.to_dict()).to_dict() == config.to_dict()


@pytest.mark.parametrize(
    ("data", "words"),
    [
        ({"preset": "fast", "protocol": "paper-code"}, "give one of them"),
        ({"preset": "fast", "framework": "sb3"}, "setting of framework jax"),
        ({"preset": "fastest"}, "preset"),
    ],
)
def test_what_the_preset_cannot_do_is_refused_by_name(data: dict, words: str) -> None:
    with pytest.raises(RLConfigError) as caught:
        TrainConfig.from_dict(data)
    assert words in str(caught.value)


def test_ppo_at_the_fast_preset_solves_a_small_maze(tmp_path) -> None:
    """A short learning run of the preset: its agent plays every rotation of the maze optimally."""
    pytest.importorskip("jax")
    from amaze.evaluation.protocol import Evaluator
    from amaze.maze import rotations
    from rl_baselines.jax.agent import NetworkAgent
    from rl_baselines.jax.trainer import JaxTrainer
    from rl_baselines.train import train

    maze, seed = "M7_8x8_C1", 3
    evaluator = Evaluator("DD", mazes=list(rotations(maze)), inputs=False)
    # the untrained network of this seed fails the maze: what solves it is the training
    untrained = JaxTrainer("ppo", "DD", [maze], seed=seed, network=PRESETS["fast"]["network"])
    assert evaluator.evaluate(untrained.policy()).summary()["success_rate"] < 1.0
    config = {
        "preset": "fast",
        "seed": seed,
        "mazes": [maze],
        "eval_mazes": [maze],
        "agent_rule": "best-eval",
        "budget_steps": 1_048_576,
        "eval_every": 65_536,
        "evaluation_points": 2,
        "evaluation_family": 1,
    }
    result = train(config, tmp_path / "run", progress="off")
    assert result.summary["agent"] == "agent.npz"
    assert result.summary["agent_steps"] > 0
    agent = NetworkAgent.load(tmp_path / "run" / "agent.npz")
    assert evaluator.evaluate(agent).summary()["success_rate"] == 1.0
