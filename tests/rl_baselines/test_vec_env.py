"""SB3VecEnv: SB3 semantics checked against the native gymnasium vector env and the engine."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
import torch
from stable_baselines3 import A2C, PPO
from stable_baselines3.common.vec_env import VecCheckNan

import amaze  # noqa: F401  (registers AMaze-v0)
from amaze.agents.engine import BatchEngine
from rl_baselines import RLConfigError
from rl_baselines.networks import SmallCNN, small_cnn_kwargs
from rl_baselines.vec_env import SB3VecEnv

torch.set_num_threads(1)

MAZES = ["M1_5x5_U", "M2_6x5_C1", "M3_5x5_C1_l.2_L.25"]


@pytest.mark.parametrize("robot", ["DD", "H", "H11"])
def test_observations_match_spaces(robot: str) -> None:
    env = SB3VecEnv(MAZES, robot, 5, seed=0)
    obs = env.reset()
    assert obs.shape == (5, *env.observation_space.shape)
    assert obs.dtype == env.observation_space.dtype
    assert all(env.observation_space.contains(o) for o in obs)
    rng = np.random.default_rng(0)
    actions = rng.integers(0, 4, size=5)
    obs, rewards, dones, infos = env.step(actions)
    assert obs.shape == (5, *env.observation_space.shape)
    assert rewards.dtype == np.float32 and rewards.shape == (5,)
    assert dones.dtype == np.bool_ and dones.shape == (5,)
    assert isinstance(infos, list) and len(infos) == 5
    assert all(isinstance(info, dict) for info in infos)


@pytest.mark.parametrize("robot", ["DD", "H"])
def test_steps_match_native_vector_env(robot: str) -> None:
    """Observations, rewards, ends and terminal observations equal the gymnasium vector env's."""
    n = 6
    env = SB3VecEnv(MAZES, robot, n, seed=0)
    native = gymnasium.make_vec(
        "AMaze-v0", num_envs=n, vectorization_mode="vector_entry_point", maze=MAZES, robot=robot
    )
    rng = np.random.default_rng(1)
    obs = env.reset()
    ref_obs, _ = native.reset(seed=0)
    np.testing.assert_array_equal(obs, ref_obs)
    ended = truncated_seen = terminated_seen = 0
    for _ in range(400):
        actions = rng.integers(0, 4, size=n)
        obs, rewards, dones, infos = env.step(actions)
        ref_obs, ref_rewards, term, trunc, ref_infos = native.step(actions)
        np.testing.assert_array_equal(obs, ref_obs)
        np.testing.assert_allclose(rewards, ref_rewards.astype(np.float32))
        np.testing.assert_array_equal(dones, term | trunc)
        for k in range(n):
            if not dones[k]:
                assert "terminal_observation" not in infos[k]
                continue
            ended += 1
            info = infos[k]
            np.testing.assert_array_equal(info["terminal_observation"], ref_infos["final_obs"][k])
            assert info["TimeLimit.truncated"] == bool(trunc[k] and not term[k])
            final = ref_infos["final_info"]
            assert info["success"] == bool(final["success"][k])
            assert info["normalized_reward"] == pytest.approx(final["normalized_reward"][k])
            assert info["pretty_reward"] == pytest.approx(final["pretty_reward"][k])
            assert info["episode"]["l"] == int(final["steps"][k])
            truncated_seen += info["TimeLimit.truncated"]
            terminated_seen += not info["TimeLimit.truncated"]
    assert ended > 0 and truncated_seen > 0 and terminated_seen > 0


def test_terminal_observation_is_the_engine_last_observation() -> None:
    """Each environment against its own engine without auto-reset, which keeps the last view."""
    mazes = ["M1_5x5_U", "M2_6x5_C1"]
    env = SB3VecEnv(mazes, "DD", 2)
    engines = [BatchEngine([m], "DD", 1, auto_reset=False) for m in mazes]
    env.reset()
    rng = np.random.default_rng(2)
    checked = [False, False]
    for _ in range(1000):
        actions = rng.integers(0, 4, size=2)
        _, rewards, dones, infos = env.step(actions)
        for k, engine in enumerate(engines):
            if checked[k]:
                continue
            result = engine.step(actions[k : k + 1])
            assert rewards[k] == np.float32(result.rewards[0])
            assert dones[k] == result.done[0]
            if dones[k]:
                np.testing.assert_array_equal(
                    infos[k]["terminal_observation"], result.observations[0]
                )
                checked[k] = True
        if all(checked):
            return
    pytest.fail("episodes did not end in 1000 steps")


def test_auto_reset_gives_first_observation_of_new_episode() -> None:
    env = SB3VecEnv(["M1_5x5_U"], "DD", 2)
    first = env.reset()
    rng = np.random.default_rng(3)
    for _ in range(500):
        obs, _, dones, _ = env.step(rng.integers(0, 4, size=2))
        if dones.any():
            k = int(np.flatnonzero(dones)[0])
            np.testing.assert_array_equal(obs[k], first[k])
            return
    pytest.fail("no episode ended in 500 steps")


def test_bad_input_names_the_value() -> None:
    with pytest.raises(RLConfigError, match="-3"):
        SB3VecEnv(MAZES, "DD", -3)
    with pytest.raises(ValueError, match="'Q'"):
        SB3VecEnv(MAZES, "Q", 2)


def test_a2c_and_ppo_learn_on_the_adapter() -> None:
    env = VecCheckNan(SB3VecEnv(MAZES, "DD", 4, seed=0), raise_exception=True)
    A2C("MlpPolicy", env, seed=0, device="cpu").learn(200)
    model = PPO("MlpPolicy", env, seed=0, n_steps=64, batch_size=64, n_epochs=1, device="cpu")
    model.learn(256)
    assert model.num_timesteps >= 256


def test_small_cnn_on_hybrid_images() -> None:
    env = SB3VecEnv(MAZES, "H", 4, seed=0)
    model = PPO(
        "CnnPolicy",
        env,
        seed=0,
        n_steps=32,
        batch_size=64,
        n_epochs=1,
        device="cpu",
        policy_kwargs=small_cnn_kwargs(32),
    )
    assert isinstance(model.policy.features_extractor, SmallCNN)
    model.learn(128)
    assert model.policy.features_extractor.features_dim == 32
