"""Numeric options of agents in mazes: bounded, validated, errors naming the value.

The deadline factor (Simulation, BatchEngine, RewardScheme), the number of
agents, the robot's vision and the animation options; each check happens
before anything is generated or allocated.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.agents.rewards import RewardScheme
from amaze.agents.robot import Robot, RobotStringError
from amaze.agents.simulation import Simulation
from amaze.agents.trajectories import TrajectoryError, save_episode_gif
from amaze.errors import OptionError

MAZE = "M4_5x5_C1"
BAD_FACTORS = [math.inf, -math.inf, math.nan, 0, 0.0, -1, 0.5, 1000.5, 1e308, "4", None, True]


@pytest.mark.parametrize("factor", BAD_FACTORS)
def test_deadline_factor_is_a_finite_number_from_1_to_1000(factor: object) -> None:
    for make in (
        lambda: Simulation(MAZE, "DD", deadline_factor=factor),
        lambda: BatchEngine([MAZE], "CC11", 2, deadline_factor=factor),
        lambda: RewardScheme(10, 1.0, factor),
    ):
        with pytest.raises(OptionError, match=re.escape(f"deadline_factor {factor!r}")):
            make()


def test_an_infinite_deadline_factor_no_longer_runs_forever() -> None:
    """Once ``inf`` was accepted: an agent that never reaches the goal never stopped."""
    with pytest.raises(OptionError, match="deadline_factor inf is not a finite number"):
        Simulation(MAZE, "DD", deadline_factor=float("inf"))


def test_n_agents_must_be_an_integer() -> None:
    for bad in (1.5, 2.0, "2", True, None, 0, -3):
        with pytest.raises(OptionError, match=f"n_agents {bad!r} is not a positive integer"):
            BatchEngine([MAZE], "DD", bad)
    assert BatchEngine([MAZE], "DD", np.int64(3)).n_agents == 3


def test_n_agents_is_bounded_by_the_engine_memory_before_allocating() -> None:
    with pytest.raises(OptionError, match=r"n_agents 1000000000000 is too many for robot CC15"):
        BatchEngine([MAZE], "CC15", 10**12)


@pytest.mark.parametrize("text", ["H10001", "CC67", "CD101", "C999999999999999999999"])
def test_vision_is_bounded(text: str) -> None:
    with pytest.raises(RobotStringError, match=r"vision \d+ must be odd and within \[5, 65\]"):
        Robot.from_string(text)


def test_vision_bound_applies_to_the_constructor_and_keeps_65() -> None:
    with pytest.raises(RobotStringError, match="vision 67"):
        Robot("C", "D", 67)
    assert Robot.from_string("H65").vision == 65
    with pytest.raises(RobotStringError, match=r"'D10001': DD .* takes no vision size"):
        Robot.from_string("D10001")  # discrete inputs take no vision


@pytest.mark.parametrize(
    ("options", "named"),
    [
        ({"final_pause": 700}, "final_pause 700"),
        ({"final_pause": 1e308}, "final_pause 1e+308"),
        ({"fps": 0.001}, "fps 0.001"),
    ],
)
def test_animation_timings_are_bounded(tmp_path, options: dict, named: str) -> None:
    """A GIF delay is 16 bits of hundredths of a second: longer ones overflowed."""
    simulation = Simulation("M4_5x5_U", "DD", record_trajectory=True)
    for action in (0, 1, 0):
        simulation.step(action)
    with pytest.raises(TrajectoryError, match=re.escape(named)):
        save_episode_gif(simulation.maze, simulation.trajectory, tmp_path / "x.gif", **options)
    assert not (tmp_path / "x.gif").exists()
    save_episode_gif(
        simulation.maze, simulation.trajectory, tmp_path / "y.gif", fps=0.01, final_pause=600
    )
