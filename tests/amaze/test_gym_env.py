"""The gymnasium environment AMaze-v0: spaces, checker, episode ends, maze switching, rendering."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import amaze  # noqa: F401  (registers AMaze-v0)
from amaze.gym_env import MazeEnv

from .conftest import load_reference

REFERENCE = load_reference()
VECTOR_TO_ACTION = {(1, 0): 0, (0, 1): 1, (-1, 0): 2, (0, -1): 3}
COMPLEX = "M4_10x10_C1_l.25_L.25_t.5_T.5"


@pytest.mark.parametrize(
    ("robot", "obs_shape", "obs_dtype", "action"),
    [
        ("DD", (8,), np.float32, gymnasium.spaces.Discrete(4)),
        ("H15", (1, 15, 15), np.uint8, gymnasium.spaces.Discrete(4)),
        ("CC11", (1, 11, 11), np.uint8, gymnasium.spaces.Box(-1, 1, (2,), np.float32)),
    ],
)
def test_spaces_and_gymnasium_checker(robot, obs_shape, obs_dtype, action):
    env = gymnasium.make("AMaze-v0", maze=COMPLEX, robot=robot, render_mode="rgb_array")
    assert env.observation_space.shape == obs_shape
    assert env.observation_space.dtype == obs_dtype
    assert env.action_space == action
    check_env(env.unwrapped, skip_render_check=False)
    obs, _ = env.reset(seed=1)
    assert env.observation_space.contains(obs)


def test_optimal_run_terminates_with_both_normalised_rewards():
    fixture = REFERENCE["mazes"][0]
    env = gymnasium.make("AMaze-v0", maze=fixture["input"], robot="DD")
    obs, info = env.reset(seed=0)
    np.testing.assert_array_equal(obs, np.array(fixture["optimal_run_DD"]["observations"][0]))
    assert "pretty_reward" not in info
    actions = [
        VECTOR_TO_ACTION[tuple(int(v) for v in a)] for a in fixture["optimal_run_DD"]["actions"]
    ]
    total = 0.0
    for k, action in enumerate(actions):
        obs, reward, terminated, truncated, info = env.step(action)
        total += reward
        assert terminated == (k == len(actions) - 1) and not truncated
    assert total == pytest.approx(fixture["path_length"])
    assert info["pretty_reward"] == 1.0 and info["paper_reward"] == pytest.approx(1.0)
    with pytest.raises(ValueError):  # no second finish bonus
        env.step(0)


def test_deadline_truncates():
    run = REFERENCE["random_runs_DD_seed0"]["M4_10x10_C1"]
    env = gymnasium.make("AMaze-v0", maze="M4_10x10_C1", robot="DD")
    env.reset()
    for k, vector in enumerate(run["actions"]):
        _, _, terminated, truncated, info = env.step(
            VECTOR_TO_ACTION[tuple(int(v) for v in vector)]
        )
        assert not terminated and truncated == (k == len(run["actions"]) - 1)
    assert info["pretty_reward"] == run["normalized_reward"]


def test_reset_option_switches_maze():
    env = gymnasium.make("AMaze-v0", maze="M4_10x10_C1", robot="DD")
    _, info = env.reset(options={"maze": "M16_5x10_U"})
    assert info["maze"] == "M16_5x10_U" and info["len"] == 20
    _, info = env.reset()
    assert info["maze"] == "M16_5x10_U"  # kept for the next episodes
    with pytest.raises(ValueError, match="q"):
        env.reset(options={"maze": "M4_q"})


def test_observations_are_not_aliased():
    env = gymnasium.make("AMaze-v0", maze="M4_10x10_C1", robot="DD")
    first, _ = env.reset()
    second, *_ = env.step(0)
    assert first is not second and not np.shares_memory(first, second)


def test_rgb_array_render():
    env = gymnasium.make("AMaze-v0", maze="M4_5x5_U", robot="DD", render_mode="rgb_array")
    env.reset()
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    env.step(0 if not env.unwrapped.maze.walls[0, 0, 0] else 1)
    assert not np.array_equal(frame, env.render())  # the agent moved


def test_human_render_shows_frames(monkeypatch):
    shown = []
    monkeypatch.setattr(MazeEnv, "_show", lambda self, frame: shown.append(frame.shape))
    env = gymnasium.make("AMaze-v0", maze="M4_5x5_U", robot="DD", render_mode="human")
    env.reset()
    env.step(1)
    assert env.render() is None and len(shown) == 3


def test_bad_arguments():
    with pytest.raises(ValueError, match="H10"):
        gymnasium.make("AMaze-v0", maze="M4_5x5", robot="H10")
    with pytest.raises(ValueError, match="render_mode"):
        MazeEnv(maze="M4_5x5", render_mode="video")
