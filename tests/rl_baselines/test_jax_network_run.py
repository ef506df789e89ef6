"""``amaze-train --framework jax`` with a ``network`` spec: evolution's network, trained by RL.

A direct run trains the spec's actor-critic, hands over an evolved agent's
file (``agent.npz``) that ``amaze evaluate`` plays with evolution's compiled
networks to the figures the run reported, records the architecture in
``summary.json``, and killed then resumed ends with the same agent bit for
bit; what a network spec cannot do is refused in one line.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

pytest.importorskip("jax")

from amaze.cli.main import main as amaze_main
from evolution.agent_file import read_agent
from rl_baselines.cli import main
from rl_baselines.jax.agent import NetworkAgent
from rl_baselines.train import resume
from tests.rl_baselines.jax_kill import Killed
from tests.rl_baselines.test_jax_framework import COEVOLUTION, CURRICULUM, DIRECT

pytestmark = pytest.mark.slow

NETWORK = {"hidden": [16], "symmetry": "rotations"}


def _config(tmp_path: Path, algo: str = "ppo", **extra: Any) -> list[str]:
    path = tmp_path / "config.json"
    hyperparameters = {"n_steps": 16}
    if algo == "ppo":
        hyperparameters.update(batch_size=32, n_epochs=2)
    path.write_text(json.dumps({"hyperparameters": hyperparameters, **extra}))
    return ["--config", str(path)]


def test_a_direct_run_with_a_network_hands_over_an_evolved_agents_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    options = _config(tmp_path, network=NETWORK, agent_rule="best-eval")
    assert main([*DIRECT, *options, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["agent"] == "agent.npz" and not (out / "agent.zip").exists()
    assert summary["network"] == {
        "type": "mlp",
        "robot": "DD",
        "hidden": [16],
        "activation": "tanh",
        "pool": None,
        "symmetry": "rotations",
        "filters": 0,
        "stride": None,
        "pooling": "mean",
    }
    assert (out / "checkpoints" / "champion.npz").is_file()
    arrays, metadata = read_agent(out / "agent.npz")
    assert arrays["params"].shape == (8 * 16 + 16 + 16 + 1,)
    assert metadata["trainer"] == "rl" and metadata["algorithm"] == "ppo"
    capsys.readouterr()
    # played by evolution's compiled network: the figures the run reported
    assert amaze_main(["evaluate", str(out / "agent.npz"), "suite", "--json"]) == 0
    evaluated = json.loads(capsys.readouterr().out)
    assert evaluated["success_rate"] == summary["success_rate"]
    # the run scores its file as evolution replays it: the same trajectories, to the bit
    assert evaluated["normalized_reward"] == summary["normalized_reward"]


def test_a_convolutional_network_trains_an_image_robot_and_evolution_plays_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    network = {"hidden": [8], "filters": 2, "symmetry": "rotations"}
    options = _config(tmp_path, network=network)
    assert main([*DIRECT, "--robot", "H7", *options, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["network"]["filters"] == 2 and summary["network"]["stride"] == 2
    arrays = read_agent(out / "agent.npz")[0]
    # 2 filters of 3 x 3 and their biases, then 2 maps of 3 x 3 positions into 8 units, then 1
    assert arrays["params"].shape == (2 * 9 + 2 + 18 * 8 + 8 + 8 + 1,)
    capsys.readouterr()
    assert amaze_main(["evaluate", str(out / "agent.npz"), "suite", "--json"]) == 0
    evaluated = json.loads(capsys.readouterr().out)
    assert evaluated["success_rate"] == summary["success_rate"]
    # the run scores its file as evolution replays it: the same trajectories, to the bit
    assert evaluated["normalized_reward"] == summary["normalized_reward"]


@pytest.mark.parametrize("regime", ["edhucat", "coevolution"])
def test_the_curricula_and_coevolution_train_a_network_and_hand_it_over(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], regime: str
) -> None:
    out = tmp_path / "run"
    argv = CURRICULUM if regime == "edhucat" else COEVOLUTION
    network = {"hidden": [8], "symmetry": "rotations"}
    algo = "ppo" if regime == "edhucat" else "a2c"
    assert main([*argv, *_config(tmp_path, algo, network=network), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["agent"] == "agent.npz" and not (out / "agent.zip").exists()
    assert summary["network"]["hidden"] == [8] and summary["network"]["symmetry"] == "rotations"
    capsys.readouterr()
    assert amaze_main(["evaluate", str(out / "agent.npz"), "suite", "--json"]) == 0
    evaluated = json.loads(capsys.readouterr().out)
    assert evaluated["success_rate"] == summary["success_rate"]


def test_a_continuous_robot_trains_and_evolution_plays_its_agent(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """CC7 with a Gaussian policy, co-evolved, paid the progress reward: the run hands over
    an evolved agent's file whose accelerations are the mean the run evaluated, and says
    what it trained for."""
    out = tmp_path / "run"
    options = _config(tmp_path, "a2c", network={"hidden": [8], "symmetry": "rotations"})
    progress = ["--progress-reward", "0.5"]
    assert main([*COEVOLUTION, "--robot", "CC7", *options, *progress, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "plus the progress reward (k = 0.5)" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert summary["agent"] == "agent.npz" and summary["network"]["robot"] == "CC7"
    assert summary["progress_reward"] == 0.5
    arrays, metadata = read_agent(out / "agent.npz")
    assert metadata["robot"] == "CC7"
    assert arrays["params"].shape == (25 * 8 + 8 + 8 + 1,)  # log_std is not the actor's
    capsys.readouterr()
    assert amaze_main(["evaluate", str(out / "agent.npz"), "suite", "--json"]) == 0
    evaluated = json.loads(capsys.readouterr().out)
    assert evaluated["success_rate"] == summary["success_rate"]
    # the run scores its file as evolution replays it: the same trajectories, to the bit
    assert evaluated["normalized_reward"] == summary["normalized_reward"]


def test_a_killed_run_with_a_network_resumes_to_the_same_agent_bit_for_bit(
    tmp_path: Path, kill_at: Any
) -> None:
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    options = _config(tmp_path, network={**NETWORK, "activation": "relu"})
    assert main([*DIRECT, *options, "--out", str(whole)]) == 0
    kill_at(4)
    with pytest.raises(Killed):
        main([*DIRECT, *options, "--out", str(cut)])
    resume(cut)
    a, b = NetworkAgent.load(whole / "agent.npz"), NetworkAgent.load(cut / "agent.npz")
    assert a.policy.spec == b.policy.spec and a.policy.spec.activation == "relu"
    for module, layer in a.policy.params.items():
        for kind, value in layer.items():
            assert np.array_equal(value, b.policy.params[module][kind]), (module, kind)


@pytest.mark.parametrize(
    ("extra", "options", "words"),
    [
        ({}, ["--framework", "sb3"], "has no effect with framework sb3"),
        ({"network": {"hidden": [16], "pool": 3}}, [], "robot DD has no image to read"),
        ({"hyperparameters": {"policy_kwargs": {"net_arch": [8]}}}, [], "give one of them"),
        ({"network": {"hidden": [16], "filters": 2}}, [], "filters 2: robot DD has no image"),
    ],
)
def test_what_a_network_spec_cannot_do_is_refused_in_one_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    extra: dict,
    options: list[str],
    words: str,
) -> None:
    path = tmp_path / "config.json"
    path.write_text(json.dumps({"network": NETWORK, **extra}))
    argv = ["--framework", "jax", "--config", str(path), *options, "--out", str(tmp_path / "r")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err


def test_a_network_run_scores_its_agent_as_amaze_evaluate_replays_it(tmp_path: Path) -> None:
    """numpy's float32 sums and evolution's compiled network part in the last bits, and a
    continuous robot's trajectories then go their own ways: a network run scores its file
    as ``amaze evaluate`` plays it (evolution's network), not with the numpy policy."""
    import jax

    from amaze.evaluation.controllers import make_controller
    from amaze.evaluation.protocol import Evaluator
    from rl_baselines.jax.agent import NetworkRunFiles
    from rl_baselines.jax.networks import as_numpy, init_params
    from rl_baselines.jax.spec import network_spec

    network = {"hidden": [8], "symmetry": "rotations"}
    spec = network_spec("CC7", network)
    params = as_numpy(init_params(spec, jax.random.key(3)))
    params["action_net"]["weight"] = params["action_net"]["weight"] * 100  # it drives
    path = NetworkAgent(spec, params, "ppo", 0).save(tmp_path / "agent.npz")
    numpy_agent = NetworkAgent.load(path)
    run = SimpleNamespace(config=SimpleNamespace(network=network, robot="CC7"))
    replayed = NetworkRunFiles.replayed_agent(run, path, numpy_agent)  # type: ignore[arg-type]
    scored = [
        Evaluator("CC7", inputs=False).evaluate(agent).summary()["normalized_reward"]
        for agent in (numpy_agent, replayed, make_controller(str(path), "CC7"))
    ]
    assert scored[0] != scored[1]  # the two players part on this agent's episodes
    assert scored[1] == scored[2]
    sb3 = SimpleNamespace(config=SimpleNamespace(network=None, robot="DD"))
    assert NetworkRunFiles.replayed_agent(sb3, path, numpy_agent) is numpy_agent  # type: ignore[arg-type]
