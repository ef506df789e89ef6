"""The native vector env of AMaze-v0 (make_vec, vector_entry_point) against single envs."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import amaze  # noqa: F401  (registers AMaze-v0)
from amaze.envs.vector_env import MazeVectorEnv

MAZES = ["M1_5x5_U", "M2_7x6_C1_l.25_L.25_t.5_T.5", "M3_4x9_NE_C1"]


def make_vec(num_envs: int, robot: str, maze=MAZES, **options):
    return gymnasium.make_vec(
        "AMaze-v0",
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        maze=maze,
        robot=robot,
        deadline_factor=1.5,
        **options,
    )


def test_make_vec_returns_the_native_vector_env():
    env = make_vec(5, "DD", maze="M1_10x10_C1")
    assert isinstance(env, MazeVectorEnv)
    obs, infos = env.reset(seed=3)
    assert env.observation_space.contains(obs) and infos == {}
    assert env.action_space.shape == (5,)


@pytest.mark.parametrize("robot", ["DD", "H11", "CC11"])
def test_vector_env_equals_single_envs(robot):
    n = 6
    vec = make_vec(n, robot)
    singles = [
        gymnasium.make("AMaze-v0", maze=MAZES[k % len(MAZES)], robot=robot, deadline_factor=1.5)
        for k in range(n)
    ]
    obs, _ = vec.reset(seed=0)
    single_obs = [env.reset()[0] for env in singles]
    np.testing.assert_array_equal(obs, np.stack(single_obs))
    vec.action_space.seed(1)
    finished = 0
    for _ in range(150):
        actions = vec.action_space.sample()
        obs, rewards, terminated, truncated, infos = vec.step(actions)
        for k, env in enumerate(singles):
            o, r, term, trunc, info = env.step(actions[k])
            assert rewards[k] == pytest.approx(r, abs=1e-12)
            assert (terminated[k], truncated[k]) == (term, trunc)
            if term or trunc:
                finished += 1
                assert infos["_final_obs"][k]
                np.testing.assert_array_equal(infos["final_obs"][k], o)
                final = infos["final_info"]
                assert final["pretty_reward"][k] == info["pretty_reward"]
                assert final["normalized_reward"][k] == pytest.approx(info["normalized_reward"])
                assert final["steps"][k] == info["steps"] and final["success"][k] == info["success"]
                o, _ = env.reset()
            elif infos:
                assert not infos["_final_obs"][k]
            np.testing.assert_array_equal(obs[k], o)
    assert finished > 0


def test_bad_arguments():
    with pytest.raises(ValueError):
        MazeVectorEnv(0, "M1_5x5")
    with pytest.raises(ValueError, match="q"):
        MazeVectorEnv(2, ["M1_5x5", "M2_q"])
    with pytest.raises(ValueError):
        MazeVectorEnv(2, [])
    with pytest.raises(ValueError, match="parallel 'yes'"):
        MazeVectorEnv(2, "M1_5x5", parallel="yes")


def test_kernel_families_give_the_same_steps_and_kept_results_stay_put():
    """``parallel`` changes which kernels run, not what a step returns; a step's arrays are
    the caller's: later steps leave them as they were."""
    envs = [make_vec(9, "DD", parallel=parallel) for parallel in (False, True, None)]
    assert [env.unwrapped.engine.parallel for env in envs[:2]] == [False, True]
    firsts = [env.reset()[0] for env in envs]
    actions = np.random.default_rng(4).integers(0, 4, size=(200, 9))
    kept = []
    ended = 0
    for t in range(200):
        results = [env.step(actions[t]) for env in envs]
        for other in results[1:]:
            for a, b in zip(results[0][:4], other[:4], strict=True):
                np.testing.assert_array_equal(a, b)
            assert results[0][4].keys() == other[4].keys()
        if results[0][4]:
            ended += 1
            for env_result in results[1:]:
                np.testing.assert_array_equal(
                    results[0][4]["_final_obs"], env_result[4]["_final_obs"]
                )
                for key, column in results[0][4]["final_info"].items():
                    np.testing.assert_array_equal(column, env_result[4]["final_info"][key])
        kept.append((results[0], [np.copy(x) for x in results[0][:4]]))
    assert ended > 0
    for result, copies in kept:
        for array, copy in zip(result[:4], copies, strict=True):
            np.testing.assert_array_equal(array, copy)
    for first, env in zip(firsts, envs, strict=True):
        np.testing.assert_array_equal(first, env.reset()[0])
