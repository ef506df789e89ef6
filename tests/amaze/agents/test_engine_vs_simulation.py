"""The batch engine and the readable Simulation, driven by the same random actions, agree.

Each agent of one engine plays its own maze (mazes of different sizes and
classes in one batch); a Simulation per agent replays the same actions,
restarting when the engine auto-resets. Observations, rewards, terminations,
truncations and positions must be identical, in all three robot modes and with
both the serial and the parallel kernels.
"""

from __future__ import annotations

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.agents.simulation import Simulation
from amaze.maze.maze import Maze

MAZES = [
    "M1_5x5_U",
    "M2_7x4_C1",
    "M3_10x10_C1_l.25_L.25_t.5_T.5",
    "M4_6x9_NE_C1_Cpoint-.5_l.4_L.25_Lwarning-.3_t.5_T.5",
    "M5_12x8_SE_C1_l.3_L.5_t.5_T.25",
    "M6_8x8_NW_R_C1_t1_T.5",
    "M7_2x2",
    "M8_20x20_C1_l.25_L.25_t.5_T.5",
]


def engine_observation_of(sim: Simulation) -> np.ndarray:
    obs = sim.observe()
    return obs if sim.robot.discrete_inputs else np.rint(obs * 255).astype(np.uint8)


def random_actions(robot: str, rng: np.random.Generator, n: int) -> np.ndarray:
    if robot == "DD" or robot.startswith("H"):
        return rng.integers(0, 4, size=n)
    # Accelerations with a persistent random heading per agent, so that robots
    # travel between cells, hit walls and corners, and turn back.
    angles = rng.uniform(0, 2 * np.pi, size=n)
    return np.stack([np.cos(angles), np.sin(angles)], axis=1) * rng.uniform(0.3, 1.0, (n, 1))


@pytest.mark.parametrize("parallel", [False, True])
@pytest.mark.parametrize(("robot", "steps"), [("DD", 400), ("H11", 300), ("CC11", 1500)])
def test_engine_matches_simulation(robot, steps, parallel):
    mazes = [Maze.from_string(text) for text in MAZES]
    rng = np.random.default_rng(42)
    engine = BatchEngine(mazes, robot, len(mazes), deadline_factor=2, parallel=parallel)
    simulations = [Simulation(maze, robot, deadline_factor=2) for maze in mazes]
    observations = engine.reset()
    episodes_ended = 0
    heading = random_actions(robot, rng, len(mazes))
    for step in range(steps):
        for k, sim in enumerate(simulations):
            np.testing.assert_array_equal(
                observations[k], engine_observation_of(sim), f"{k} {step}"
            )
        if robot.startswith("C"):
            change = rng.random(len(mazes)) < 0.02
            heading[change] = random_actions(robot, rng, int(change.sum()))
            actions = heading.copy()
        else:
            actions = random_actions(robot, rng, len(mazes))
        result = engine.step(actions)
        for k, sim in enumerate(simulations):
            reward = sim.step(actions[k])
            assert result.rewards[k] == pytest.approx(reward, abs=1e-12)
            assert result.terminated[k] == sim.success()
            assert result.truncated[k] == sim.failure()
            if sim.done():
                episodes_ended += 1
                index = list(result.episodes.agents).index(k)
                np.testing.assert_array_equal(
                    result.final_observations[index], engine_observation_of(sim)
                )
                assert result.episodes.cumulative_reward[index] == pytest.approx(
                    sim.cumulative_reward, abs=1e-9
                )
                assert result.episodes.steps[index] == sim.stats.steps
                assert result.episodes.collisions[index] == sim.stats.collisions
                assert result.episodes.backsteps[index] == sim.stats.backsteps
                assert result.episodes.pretty_rewards()[index] == sim.pretty_reward()
                assert result.episodes.normalized_rewards()[index] == pytest.approx(
                    sim.normalized_reward()
                )
                sim.reset()
            else:
                np.testing.assert_allclose(engine.positions[k], sim.position, rtol=0, atol=1e-12)
        observations = result.observations
    assert episodes_ended >= len(mazes)  # resets were exercised
