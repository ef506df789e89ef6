"""The readable Simulation against the reference runs (DD, hybrid, continuous)."""

from __future__ import annotations

import numpy as np
import pytest

from amaze.agents.robot import Robot, RobotStringError
from amaze.agents.simulation import EpisodeEndedError, Simulation
from tests.amaze.conftest import load_reference

REFERENCE = load_reference()
PRIMARY = REFERENCE["mazes"]
VECTOR_TO_ACTION = {(1, 0): 0, (0, 1): 1, (-1, 0): 2, (0, -1): 3}
INFO_KEYS = ("time", "success", "failure", "done", "pretty_reward", "len", "steps")
INFO_KEYS += ("collisions", "backsteps")


def discrete_actions(vectors) -> list[int]:
    return [VECTOR_TO_ACTION[(int(x), int(y))] for x, y in vectors]


def play(sim: Simulation, actions) -> tuple[list[float], list[np.ndarray]]:
    observations, rewards = [sim.observe()], []
    for action in actions:
        rewards.append(sim.step(action))
        observations.append(sim.observe())
    return rewards, observations


@pytest.mark.parametrize("fixture", PRIMARY, ids=[m["input"] for m in PRIMARY])
def test_optimal_discrete_run(fixture):
    run = fixture["optimal_run_DD"]
    sim = Simulation(fixture["input"], "DD")
    assert sim.rewards.deadline == fixture["rewards_constants_DD"]["deadline"]
    assert sim.rewards.minimal_reward == pytest.approx(
        fixture["rewards_constants_DD"]["minimal_reward"]
    )
    rewards, observations = play(sim, discrete_actions(run["actions"]))
    assert rewards == pytest.approx(run["rewards"])
    np.testing.assert_array_equal(np.array(observations), np.array(run["observations"], np.float32))
    infos = sim.infos()
    assert {k: infos[k] for k in INFO_KEYS} == {k: run["infos"][k] for k in INFO_KEYS}
    assert sim.cumulative_reward == pytest.approx(fixture["path_length"])
    assert sim.normalized_reward() == pytest.approx(1.0)
    assert infos["errors"]["clue"] == run["infos"]["errors"]["clue"]


@pytest.mark.parametrize("name", sorted(REFERENCE["random_runs_DD_seed0"]))
def test_random_runs_until_the_deadline(name):
    run = REFERENCE["random_runs_DD_seed0"][name]
    sim = Simulation(name, "DD")
    rewards, _ = play(sim, discrete_actions(run["actions"]))
    assert rewards == pytest.approx(run["rewards"])
    assert sim.cumulative_reward == pytest.approx(run["cumulative_reward"])
    assert sim.pretty_reward() == run["normalized_reward"]
    infos = sim.infos()
    assert {k: infos[k] for k in INFO_KEYS} == {k: run["infos"][k] for k in INFO_KEYS}
    assert infos["errors"] == pytest.approx(run["infos"]["errors"])
    with pytest.raises(EpisodeEndedError):  # the reference added the finish bonus again
        sim.step(0)


def test_deadline_run():
    run = REFERENCE["deadline_run_M4_10x10_U"]
    sim = Simulation("M4_10x10_U", "DD")
    bump = next(d for d in range(4) if sim.maze.walls[sim.maze.start][d])
    steps = 0
    while not sim.done():
        sim.step(bump)
        steps += 1
    assert steps == run["steps"] == run["deadline"]
    assert sim.failure() and not sim.success()
    assert sim.stats.collisions == steps


@pytest.mark.parametrize("key", sorted(REFERENCE["image_runs"]))
def test_hybrid_image_runs(key):
    run = REFERENCE["image_runs"][key]
    maze, robot = key.split("|")
    sim = Simulation(maze, robot)
    rewards, observations = play(sim, discrete_actions(run["actions"]))
    assert rewards == pytest.approx(run["rewards"])
    as_u8 = np.round(np.array(observations) * 255).astype(np.uint8)
    np.testing.assert_array_equal(as_u8, np.array(run["observations_u8"], dtype=np.uint8))
    assert observations[0].dtype == np.float32


def test_continuous_run():
    run = REFERENCE["continuous_run_M4_5x5_U_CC"]
    sim = Simulation("M4_5x5_U", "CC15")
    positions = [sim.position]
    observations = [sim.observe()]
    rewards = []
    for action in run["actions"]:
        rewards.append(sim.step(action))
        positions.append(sim.position)
        observations.append(sim.observe())
    np.testing.assert_allclose(positions, run["positions"], rtol=0, atol=1e-12)
    assert rewards == pytest.approx(run["rewards"])
    assert sim.success() and sim.stats.steps == run["steps"]
    assert sim.pretty_reward() == run["normalized_reward"]
    stored = np.array(run["observations_u8"], dtype=np.uint8)
    ours = np.round(np.array(observations[: len(stored)]) * 255).astype(np.uint8)
    np.testing.assert_array_equal(ours, stored)


def test_continuous_window_follows_the_robot():
    sim = Simulation("M4_5x5_C1", "CC11")
    first = sim.observe()
    for _ in range(15):
        sim.step((1.0, 0.0) if not sim.maze.walls[sim.maze.start][0] else (0.0, 1.0))
    assert not np.array_equal(first, sim.observe())


def test_observations_are_fresh_arrays():
    sim = Simulation("M4_10x10_C1", "DD")
    first = sim.observe()
    first[:] = 9
    assert sim.observe().max() <= 1
    assert sim.observe() is not sim.observe()


def test_reset_keeps_the_deadline_factor_and_restarts():
    sim = Simulation("M4_10x10_C1", "DD", deadline_factor=10)
    sim.step(1)
    sim.reset()
    assert sim.rewards.deadline == 10 * 29 and sim.timestep == 0
    assert sim.position == (0.5, 0.5) and sim.cumulative_reward == 0


def test_trajectory_recording():
    sim = Simulation("M4_5x5_U", "DD", record_trajectory=True)
    sim.step(0)
    sim.step(1)
    arrays = sim.trajectory.as_arrays()
    assert arrays["positions"].shape == (2, 2) and arrays["rewards"].shape == (2,)
    assert tuple(arrays["positions"][0]) == (0.5, 0.5)


@pytest.mark.parametrize("action", [4, -1, "E", 1.5, None])
def test_bad_discrete_actions(action):
    with pytest.raises(ValueError):
        Simulation("M4_5x5_U", "DD").step(action)


@pytest.mark.parametrize(
    ("text", "canonical"),
    [
        ("DD", "DD"),
        ("D", "DD"),
        ("H", "CD15"),
        ("H11", "CD11"),
        ("CD15", "CD15"),
        ("C", "CC15"),
        ("CC11", "CC11"),
    ],
)
def test_robot_strings(text, canonical):
    robot = Robot.from_string(text)
    assert robot.to_string() == canonical
    assert Robot.from_string(canonical) == robot


@pytest.mark.parametrize("text", ["A", "AD", "DA", "AA", "A11", "AAA", "CDA", "DC", "H10", ""])
def test_bad_robot_strings(text):
    with pytest.raises(RobotStringError):
        Robot.from_string(text)


@pytest.mark.parametrize("robot", ["CC7", "CC15"])
def test_a_robot_exactly_on_a_wall_end_is_pushed_towards_its_cell(robot):
    """The reference divides by the distance to the wall end, zero on the end itself.

    Evolution's saturated accelerations put robots exactly on integer points;
    a CC15 co-evolution run ended with ``ZeroDivisionError`` in the engine.
    Both the simulation and the engine push the robot a radius from the end,
    towards its cell's centre, and agree to the last bit.
    """
    from amaze.agents.engine import BatchEngine
    from amaze.agents.robot import RADIUS

    maze = "M4_5x5_U"
    sim = Simulation(maze, robot)
    walls = sim.maze.walls
    assert walls[0, 1, 3] or walls[1, 0, 2]  # the end of a wall at the point (1, 1)
    sim.position, sim.velocity = (1.0, 1.0), (0.0, 0.0)
    sim.step((0.0, 0.0))
    x, y = sim.position
    assert np.isfinite([x, y]).all() and x > 1.0 and y > 1.0  # into cell (1, 1)
    assert np.hypot(x - 1.0, y - 1.0) >= RADIUS
    engine = BatchEngine([maze], robot, 1)
    engine._fst[0, 0], engine._fst[0, 1] = 1.0, 1.0
    engine.step(np.zeros((1, 2)))
    assert engine.positions[0].tolist() == [x, y]
