"""How the evaluation protocol plays its mazes: the ``rotations`` keyword, and every report says."""

from __future__ import annotations

import json

import numpy as np
import pytest

from amaze.errors import OptionError
from amaze.evaluation.controllers import OracleController, RandomController
from amaze.evaluation.protocol import Evaluator, check_rotations, evaluate
from amaze.evaluation.suite import standard_suite
from amaze.maze import rotations
from amaze.maze.spec import MazeSpec

MAZES = ["M1_5x5_U", "M2_6x6_C1"]


def east(observations: np.ndarray) -> np.ndarray:
    return np.zeros(len(observations), dtype=np.int64)


def test_a_maze_list_is_played_as_given_by_default_and_says_so():
    report = evaluate(east, "DD", MAZES, inputs=False)
    assert [e.maze for e in report.episodes] == MAZES
    assert report.rotations == 1
    assert report.summary()["rotations"] == 1
    assert "2 mazes, each as given (1 rotation)" in report.format()


def test_four_rotations_play_every_corner_grouped_by_the_maze_given():
    report = evaluate(OracleController("DD"), "DD", MAZES, rotations=4)
    assert [e.maze for e in report.episodes] == rotations(MAZES)
    assert report.rotations == 4 and report.summary()["rotations"] == 4
    assert sorted({e.start for e in report.episodes}) == ["NE", "NW", "SE", "SW"]
    assert {e.column for e in report.episodes} == set(MAZES)
    per_maze = report.per_maze()
    assert list(per_maze) == [(maze, "") for maze in MAZES]
    assert [scores["episodes"] for scores in per_maze.values()] == [4, 4]
    assert "2 mazes, each in its 4 rotations" in report.format()


def test_four_rotations_equal_the_rotations_given_one_by_one():
    policy = RandomController("DD", seed=1)
    rotated = evaluate(policy, "DD", MAZES, rotations=4, inputs=False)
    by_hand = evaluate(policy, "DD", rotations(MAZES), inputs=False)
    assert [e.steps for e in rotated.episodes] == [e.steps for e in by_hand.episodes]
    assert rotated.normalized_reward == by_hand.normalized_reward
    assert (rotated.rotations, by_hand.rotations) == (4, 1)


def test_the_suite_is_played_in_four_rotations_unless_one_is_asked():
    suite = standard_suite()
    full = Evaluator("DD", inputs=False)
    assert full.rotations == 4 and len(full.maze_strings) == 72
    base = Evaluator("DD", rotations=1, inputs=False)
    given = [MazeSpec.from_string(m).to_string() for m in suite.maze_strings(rotations=False)]
    assert base.rotations == 1 and base.maze_strings == given
    report = base.evaluate(OracleController("DD"))
    assert len(report.episodes) == 18 and report.summary()["rotations"] == 1
    assert list(report.per_maze()) == [(m.column, m.row) for m in suite.mazes]


def test_the_suite_summary_records_four_rotations():
    report = evaluate(OracleController("DD"), "DD")
    summary = json.loads(json.dumps(report.summary()))
    assert summary["episodes"] == 72 and summary["rotations"] == 4
    assert "18 mazes, each in its 4 rotations" in report.format()


def test_a_seedless_maze_has_one_seed_in_its_four_rotations():
    evaluator = Evaluator("DD", ["5x5_U"], rotations=4, inputs=False)
    seeds = {text.split("_")[0] for text in evaluator.maze_strings}
    assert len(seeds) == 1 and len(evaluator.maze_strings) == 4


def test_mean_steps_per_report_and_per_maze():
    report = evaluate(OracleController("DD"), "DD", MAZES, rotations=4)
    assert report.mean_steps == np.mean([e.steps for e in report.episodes])
    for (maze, _), scores in report.per_maze().items():
        steps = [e.steps for e in report.episodes if e.column == maze]
        assert scores["mean_steps"] == np.mean(steps)


@pytest.mark.parametrize("value", [0, 2, 3, 5, -4, 4.0, "4", True])
def test_rotations_are_one_or_four(value):
    with pytest.raises(OptionError, match="rotations"):
        check_rotations(value, suite=False)
    with pytest.raises(OptionError, match="rotations"):
        Evaluator("DD", MAZES, rotations=value)
    with pytest.raises(OptionError, match="rotations"):
        evaluate(east, "DD", MAZES, rotations=value)


def test_default_rotations_depend_on_the_maze_set():
    assert check_rotations(None, suite=True) == 4
    assert check_rotations(None, suite=False) == 1
    assert check_rotations(4, suite=False) == 4 and check_rotations(1, suite=True) == 1


def test_an_empty_maze_list_is_refused():
    with pytest.raises(OptionError, match="at least one maze"):
        Evaluator("DD", [], rotations=4)
