"""The JAX trainer on a continuous robot: it learns, resumes bit for bit, saves an evolved agent.

* a short PPO run (200 k env steps, seconds) solves the four rotations of a
  2 x 2 maze with the CC7 robot, acting deterministically (the Gaussian's
  mean), where the untrained policy does not move (its accelerations are
  under the dead zone) and fails every one;
* the agent it hands over is an evolved agent's file: read by
  :func:`evolution.agent_file.load_agent` it accelerates as the trainer's
  policy and succeeds the same;
* a run cut in two and resumed from a saved trainer ends in the state of one
  uncut run, bit for bit (the log standard deviations and their moments
  included);
* a 3 x 3 maze that AMaze's reward does not teach in 200 k env steps
  (the goal, nine cells away, is seldom reached by chance) is solved in as
  many with the progress reward, which pays each new share of the solution;
* what has no effect for a continuous robot is refused by name, and the
  progress reward for a discrete one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from amaze.evaluation.protocol import Evaluator  # noqa: E402
from amaze.maze.maze import rotations  # noqa: E402
from evolution.agent_file import load_agent  # noqa: E402
from rl_baselines import RLConfigError  # noqa: E402
from rl_baselines.jax import JaxTrainer  # noqa: E402
from rl_baselines.jax.agent import JaxAgent  # noqa: E402

TINY = rotations("M0_2x2_U")
NETWORK = {"hidden": [16], "symmetry": "rotations", "pool": 5}
HPS = {"n_steps": 256, "batch_size": 256, "ent_coef": 0.0}


def _trainer(seed: int = 0, **kwargs: object) -> JaxTrainer:
    return JaxTrainer("ppo", "CC7", TINY, HPS, seed=seed, n_envs=8, network=NETWORK, **kwargs)


def test_a_short_run_solves_a_tiny_maze(tmp_path: Path) -> None:
    trainer = _trainer()
    evaluate = Evaluator("CC7", TINY)
    before = evaluate(trainer.policy())
    assert not any(e.success for e in before.episodes)
    assert trainer.params()["log_std"]["data"].tolist() == [0.0, 0.0]
    trainer.learn(200_000)
    policy = trainer.policy()
    after = evaluate(policy)
    assert all(e.success for e in after.episodes), after.episodes
    assert np.all(trainer.params()["log_std"]["data"] < -0.3)  # exploration narrowed
    path = JaxAgent(trainer).save(tmp_path / "agent.npz")
    evolved = load_agent(path)
    assert evolved.robot.to_string() == "CC7"
    images = np.random.default_rng(0).integers(0, 256, (64, 1, 7, 7)).astype(np.uint8)
    np.testing.assert_allclose(evolved(images), policy(images), rtol=0, atol=1e-5)
    again = evaluate(evolved)
    assert [e.success for e in again.episodes] == [True] * 4
    assert [e.steps for e in again.episodes] == [e.steps for e in after.episodes]


def _same_state(a: JaxTrainer, b: JaxTrainer) -> bool:
    x, y = a.state_arrays(), b.state_arrays()
    return x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)


def test_a_continuous_run_resumes_bit_for_bit(tmp_path: Path) -> None:
    rollout = 256 * 8
    whole = _trainer(seed=3, chunk_steps=2 * rollout)
    whole.learn(5 * rollout)
    first = _trainer(seed=3, chunk_steps=2 * rollout)
    first.learn(2 * rollout)
    assert "params/log_std/data" in first.state_arrays()
    first.save(tmp_path / "trainer")
    resumed = JaxTrainer.load(tmp_path / "trainer")
    assert _same_state(resumed, first)
    resumed.learn(3 * rollout)
    assert _same_state(resumed, whole)
    assert not _same_state(first, whole)


def test_the_progress_reward_teaches_what_the_papers_reward_does_not() -> None:
    small = rotations("M0_3x3_U")
    evaluate = Evaluator("CC7", small)
    for reward, solved in ((0.0, [False] * 4), (1.0, [True] * 4)):
        trainer = JaxTrainer(
            "ppo", "CC7", small, HPS, n_envs=8, network=NETWORK, progress_reward=reward
        )
        assert trainer.static.env.progress_reward == reward
        assert trainer.settings()["progress_reward"] == reward
        trainer.learn(200_000)
        report = evaluate(trainer.policy())
        assert [e.success for e in report.episodes] == solved, reward


def test_the_progress_reward_is_for_continuous_robots() -> None:
    with pytest.raises(RLConfigError, match=r"progress_reward 1\.0 has no effect with robot DD"):
        JaxTrainer("ppo", "DD", TINY, HPS, n_envs=8, progress_reward=1.0)
    with pytest.raises(RLConfigError, match="progress_reward"):
        _trainer(progress_reward=-0.5)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"network": None}, "robot CC7 has continuous actions"),
        ({"max_codes": 64}, "max_codes 64 has no effect with robot CC7"),
        ({"max_cells": 2}, "max_side 1 must hold the largest maze (2 cells a side)"),
        ({"max_cells": "9"}, "max_cells"),
    ],
)
def test_what_a_continuous_robot_cannot_use_is_refused(kwargs: dict, words: str) -> None:
    settings = {"n_envs": 8, "network": NETWORK, **kwargs}
    with pytest.raises(RLConfigError) as caught:
        JaxTrainer("ppo", "CC7", TINY, HPS, **settings)
    assert words in str(caught.value)
