"""AMaze-v0 against the environment checkers of gymnasium and stable-baselines3.

The single environment goes through ``gymnasium.utils.env_checker.check_env``
and ``stable_baselines3.common.env_checker.check_env`` (stable-baselines3 is
optional: those tests are skipped without it). gymnasium 1.4 has no checker
for vector environments, so the native vector env is checked here with the
same building blocks (gymnasium's space and observation checks,
``data_equivalence``, ``data_shares_objects``) for what its ``check_env``
verifies on single environments, plus the vector API's own contract:
batched spaces, same-step autoreset with ``final_obs`` / ``final_info`` and
their masks, and gymnasium's vector wrappers reading those infos.
"""

from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env, data_equivalence
from gymnasium.utils.passive_env_checker import (
    check_action_space,
    check_obs,
    check_observation_space,
    data_shares_objects,
)
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space
from gymnasium.wrappers.vector import DictInfoToList, RecordEpisodeStatistics

import amaze  # noqa: F401  (registers AMaze-v0)

ROBOTS = ["DD", "H15", "CC11"]
MAZE = "M4_10x10_C1_l.25_L.25_t.5_T.5"
VECTOR_MAZES = ["M1_5x5_U", "M2_7x6_C1_l.25_L.25_t.5_T.5", "M3_4x9_NE_C1"]


@pytest.fixture(autouse=True)
def gymnasium_warnings_are_errors():
    """The checkers report many problems as warnings: make each one fail the test."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


# -----------------------------------------------------------------------------
# Single environment


@pytest.mark.parametrize("robot", ROBOTS)
def test_gymnasium_check_env(robot):
    env = gymnasium.make("AMaze-v0", maze=MAZE, robot=robot, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)


@pytest.mark.parametrize("robot", ROBOTS)
def test_stable_baselines3_check_env(robot):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gymnasium.make("AMaze-v0", maze=MAZE, robot=robot)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(env, warn=True)
        sb3_checker.check_env(env.unwrapped, warn=True)
    messages = [str(w.message) for w in caught]
    # Images of the reference's size (v x v, v = 11 or 15) are smaller than the
    # 36 x 36 that SB3's default CnnPolicy needs: a note on the policy, not the env.
    unexpected = [m for m in messages if "minimal resolution for an image" not in m]
    assert unexpected == []
    if robot == "DD":
        assert messages == []


# -----------------------------------------------------------------------------
# Native vector environment


def make_vec(robot: str, num_envs: int = 7):
    return gymnasium.make_vec(
        "AMaze-v0",
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        maze=VECTOR_MAZES,
        robot=robot,
        deadline_factor=1.0,  # short episodes: many autoresets
    )


def start_observations(robot: str, num_envs: int) -> list[np.ndarray]:
    """The first observation of each agent's maze, from single environments."""
    return [
        gymnasium.make("AMaze-v0", maze=VECTOR_MAZES[k % len(VECTOR_MAZES)], robot=robot).reset()[0]
        for k in range(num_envs)
    ]


@pytest.mark.parametrize("robot", ROBOTS)
def test_vector_spaces(robot):
    env = make_vec(robot)
    for space in (env.single_observation_space, env.observation_space):
        check_observation_space(space)
    for space in (env.single_action_space, env.action_space):
        check_action_space(space)
    assert env.observation_space == batch_space(env.single_observation_space, env.num_envs)
    assert env.action_space == batch_space(env.single_action_space, env.num_envs)
    assert env.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP


@pytest.mark.parametrize("robot", ROBOTS)
def test_vector_reset(robot):
    env = make_vec(robot)
    obs, info = env.reset(seed=3)
    check_obs(obs, env.observation_space, "reset")
    assert isinstance(info, dict)
    assert obs.dtype == env.observation_space.dtype and obs in env.observation_space
    again, _ = env.reset(seed=3)
    assert data_equivalence(obs, again, exact=True)  # seeded resets are reproducible
    assert not data_shares_objects(obs, again)
    env.step(env.action_space.sample())
    assert data_equivalence(env.reset(seed=3)[0], obs, exact=True)
    assert data_equivalence(env.reset()[0], obs, exact=True)  # nothing random in a start
    np.testing.assert_array_equal(obs, np.stack(start_observations(robot, env.num_envs)))


@pytest.mark.parametrize("robot", ROBOTS)
def test_vector_step_types_and_determinism(robot):
    """Two environments given the same seed and actions return the same data."""
    first, second = make_vec(robot), make_vec(robot)
    first.action_space.seed(11)
    first.reset(seed=5)
    second.reset(seed=5)
    n = first.num_envs
    previous = None
    for _ in range(60):
        actions = first.action_space.sample()
        data = first.step(actions)
        assert data_equivalence(data, second.step(actions.copy()), exact=True)
        obs, rewards, terminated, truncated, infos = data
        check_obs(obs, first.observation_space, "step")
        assert obs in first.observation_space
        assert rewards.shape == (n,) and np.issubdtype(rewards.dtype, np.floating)
        for flags in (terminated, truncated):
            assert flags.shape == (n,) and flags.dtype == np.bool_
        assert isinstance(infos, dict)
        if previous is not None:  # nothing handed out is reused by the next step
            assert not data_shares_objects(previous, data)
        previous = data


@pytest.mark.parametrize("robot", ROBOTS)
def test_vector_same_step_autoreset(robot):
    env = make_vec(robot)
    starts = start_observations(robot, env.num_envs)
    env.reset(seed=0)
    env.action_space.seed(2)
    ended = 0
    for _ in range(200):
        obs, _, terminated, truncated, infos = env.step(env.action_space.sample())
        done = terminated | truncated
        if not done.any():
            assert infos == {}
            continue
        ended += int(done.sum())
        np.testing.assert_array_equal(infos["_final_obs"], done)
        np.testing.assert_array_equal(infos["_final_info"], done)
        final_info = infos["final_info"]
        for key in ("success", "steps", "pretty_reward", "normalized_reward", "cumulative_reward"):
            np.testing.assert_array_equal(final_info[f"_{key}"], done)
            assert final_info[key].shape == (env.num_envs,)
        np.testing.assert_array_equal(final_info["success"][done], terminated[done])
        for k in range(env.num_envs):
            if done[k]:  # the next episode has started, its first observation is returned
                final = infos["final_obs"][k]
                check_obs(final, env.single_observation_space, "step (final_obs)")
                assert final in env.single_observation_space
                assert not np.shares_memory(final, obs)
                np.testing.assert_array_equal(obs[k], starts[k])
            else:
                assert infos["final_obs"][k] is None
    assert ended > env.num_envs


@pytest.mark.parametrize("robot", ["DD", "H11"])
def test_vector_final_obs_is_the_last_of_the_episode(robot):
    """The last observation of an episode is the one a single environment shows there."""
    env = make_vec(robot, num_envs=3)
    singles = [
        gymnasium.make("AMaze-v0", maze=maze, robot=robot, deadline_factor=1.0)
        for maze in VECTOR_MAZES
    ]
    env.reset(seed=0)
    for single in singles:
        single.reset()
    env.action_space.seed(4)
    for _ in range(120):
        actions = env.action_space.sample()
        _, _, terminated, truncated, infos = env.step(actions)
        for k, single in enumerate(singles):
            last, *_ = single.step(int(actions[k]))
            if terminated[k] or truncated[k]:
                np.testing.assert_array_equal(infos["final_obs"][k], last)
                single.reset()


@pytest.mark.parametrize("robot", ROBOTS)
def test_vector_actions_are_validated(robot):
    env = make_vec(robot, num_envs=3)
    env.reset(seed=0)
    if robot.startswith("C"):
        bad_actions = [np.zeros(3), np.zeros((2, 2)), np.zeros((3, 3))]
    else:
        bad_actions = [
            np.array([0, 1, 4]),
            np.array([-1, 0, 0]),
            np.array([0.0, 1.0, 2.0]),
            np.array([0, 1]),
        ]
    for actions in bad_actions:
        with pytest.raises(ValueError):
            env.step(actions)
    engine = env.unwrapped.engine
    assert engine.timesteps.tolist() == [0, 0, 0]  # refused steps moved no agent
    env.step(env.action_space.sample())
    assert engine.timesteps.tolist() == [1, 1, 1]


@pytest.mark.parametrize("robot", ["DD", "CC11"])
def test_vector_wrappers_read_the_infos(robot):
    """gymnasium's vector wrappers understand the infos, episode ends included."""
    env = RecordEpisodeStatistics(make_vec(robot))
    listed = DictInfoToList(make_vec(robot))
    env.reset(seed=0)
    listed.reset(seed=0)
    env.action_space.seed(8)
    recorded = 0
    for _ in range(150):
        actions = env.action_space.sample()
        *_, infos = env.step(actions)
        *_, info_list = listed.step(actions)
        assert isinstance(info_list, list) and len(info_list) == env.num_envs
        if "episode" in infos:
            done = infos["_episode"]
            recorded += int(done.sum())
            final = infos["final_info"]
            np.testing.assert_allclose(
                infos["episode"]["r"][done], final["cumulative_reward"][done], atol=1e-9
            )
            np.testing.assert_array_equal(infos["episode"]["l"][done], final["steps"][done])
            for k in np.flatnonzero(done):
                assert info_list[k]["final_info"]["steps"] == final["steps"][k]
    assert recorded > 0
