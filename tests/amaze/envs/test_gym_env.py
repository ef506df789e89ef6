"""The gymnasium environment AMaze-v0: spaces, checker, episode ends, maze switching, rendering."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import amaze  # noqa: F401  (registers AMaze-v0)
from amaze.agents.simulation import Simulation
from amaze.envs.gym_env import MazeEnv
from amaze.errors import AmazeError, EpisodeEndedError
from amaze.maze.directions import direction_between
from tests.amaze.conftest import load_reference

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
    assert info["pretty_reward"] == 1.0 and info["normalized_reward"] == pytest.approx(1.0)
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


# -----------------------------------------------------------------------------
# Discrete-action robots run on tables: same episodes as the readable Simulation

EQUIVALENCE_MAZES = [
    "M0_10x10_C1",
    "M8_20x20_C1_l.25_L.25_t.5_T.5",
    "M5_12x8_SE_C1_l.3_L.5_t.5_T.25",
    "M6_9x7_NW_C1_l.4_L.25_t.5_T.5",
    "M6_8x8_NW_R_C1_t1_T.5",
    "M3_6x9_NE_C1_Cpoint-.5_l.4_L.25_Lwarning-.3",
    "M4_10x10_U",
    "M16_5x10_U",
]


def simulation_info(sim: Simulation) -> dict:
    """What the environment's info must hold, read from a Simulation."""
    info = {
        "maze": sim.maze.to_string(),
        "time": sim.timestep,
        "len": sim.maze.path_length,
        "steps": sim.stats.steps,
        "collisions": sim.stats.collisions,
        "backsteps": sim.stats.backsteps,
        "success": sim.success(),
    }
    if sim.done():
        info["pretty_reward"] = sim.pretty_reward()
        info["normalized_reward"] = sim.normalized_reward()
    return info


def simulation_observation(sim: Simulation) -> np.ndarray:
    obs = sim.observe()
    return obs if sim.robot.discrete_inputs else np.rint(obs * 255).astype(np.uint8)[None]


def guided_action(sim: Simulation, rng: np.random.Generator, follow: float):
    """Towards the goal along the solution with probability ``follow``, else at random.

    The action is a Python int or a numpy integer, so that both are exercised.
    """
    solution = sim.maze.solution
    if sim.cell in solution[:-1] and rng.random() < follow:
        here = solution.index(sim.cell)
        action = int(direction_between(sim.cell, solution[here + 1]))
    else:
        action = int(rng.integers(0, 4))
    return action if rng.random() < 0.5 else np.int64(action)


def assert_same_info(info: dict, expected: dict) -> None:
    assert info == expected
    for key, value in expected.items():
        assert type(info[key]) is type(value), key


@pytest.mark.parametrize("robot", ["DD", "H11"])
def test_discrete_action_env_matches_simulation(robot):
    """Random and goal-directed episodes, maze switches by reset option, all identical."""
    env = gymnasium.make("AMaze-v0", maze=EQUIVALENCE_MAZES[0], robot=robot, deadline_factor=2)
    rng = np.random.default_rng(7)
    ends = {"terminated": 0, "truncated": 0}
    for maze in EQUIVALENCE_MAZES:
        sim = Simulation(maze, robot, deadline_factor=2)
        for episode, follow in enumerate([0.0, 0.8, 0.5, 0.95]):
            obs, info = env.reset(options={"maze": maze} if episode == 0 else None)
            sim.reset()
            np.testing.assert_array_equal(obs, simulation_observation(sim))
            assert obs.dtype == env.observation_space.dtype
            assert_same_info(info, simulation_info(sim))
            previous = obs
            while not sim.done():
                action = guided_action(sim, rng, follow)
                obs, reward, terminated, truncated, info = env.step(action)
                expected_reward = sim.step(action)
                assert type(reward) is float and reward == expected_reward
                assert type(terminated) is bool and terminated == sim.success()
                assert type(truncated) is bool and truncated == sim.failure()
                np.testing.assert_array_equal(obs, simulation_observation(sim))
                assert not np.shares_memory(obs, previous)
                assert_same_info(info, simulation_info(sim))
                previous = obs
            ends["terminated"] += terminated
            ends["truncated"] += truncated
            with pytest.raises(EpisodeEndedError):
                env.step(0)
    assert ends["terminated"] > 5 and ends["truncated"] > 5


@pytest.mark.parametrize("robot", ["DD", "H9"])
def test_discrete_action_validation_matches_simulation(robot):
    env = gymnasium.make("AMaze-v0", maze="M4_10x10_C1", robot=robot)
    sim = Simulation("M4_10x10_C1", robot)
    env.reset()
    for bad in [4, -1, True, 1.0, np.float64(2.0), "1", None, np.array([1]), np.True_]:
        with pytest.raises(AmazeError, match="discrete action"):
            env.step(bad)
        with pytest.raises(AmazeError, match="discrete action"):
            sim.step(bad)
    for good in [np.int8(1), np.uint64(0), np.array(2), 3]:  # refused actions changed nothing
        obs, reward, *_, info = env.step(good)
        assert reward == sim.step(good)
        np.testing.assert_array_equal(obs, simulation_observation(sim))
        assert_same_info(info, simulation_info(sim))


def test_observation_buffers_are_never_handed_out():
    """Writing into a returned observation does not change later ones."""
    env = gymnasium.make("AMaze-v0", maze="M4_5x5_U", robot="H7")
    first, _ = env.reset()
    first[...] = 7
    again, _ = env.reset()
    assert again.max() == 255 and again.min() == 0
    bump = int(np.flatnonzero(env.unwrapped.maze.walls[env.unwrapped.maze.start])[0])
    a, *_ = env.step(bump)
    b, *_ = env.step(bump)  # a collision: same state, same image, another array
    np.testing.assert_array_equal(a, b)
    assert not np.shares_memory(a, b)
