"""The evaluation protocol: scores of known controllers, aggregation, determinism."""

from __future__ import annotations

import json

import numpy as np
import pytest

from amaze.evaluation.controllers import OracleController, RandomController
from amaze.evaluation.inputs import evaluate_inputs, inputs_for_maze
from amaze.evaluation.protocol import EvaluationReport, Evaluator, evaluate
from amaze.evaluation.suite import COLUMNS, ROWS, standard_suite


@pytest.fixture(scope="module")
def evaluator() -> Evaluator:
    return Evaluator("DD")


def test_oracle_is_optimal_on_the_whole_suite(evaluator):
    report = evaluator.evaluate(OracleController("DD"))
    assert len(report.episodes) == 72
    assert report.success_rate == 1.0
    assert report.normalized_reward == pytest.approx(1.0)
    assert report.pretty_reward == pytest.approx(1.0)
    for episode in report.episodes:
        assert episode.steps == episode.path_length - 1
        assert episode.collisions == episode.backsteps == 0
    # The oracle reads the maze, so its input recognition has no meaning.
    assert report.input_recognition is None


def test_random_controller_scores_match_a_direct_computation(evaluator):
    report = evaluator.evaluate(RandomController("DD", seed=3))
    again = evaluator.evaluate(RandomController("DD", seed=3))
    assert report == again  # seeded: reproducible
    assert report != evaluator.evaluate(RandomController("DD", seed=4))
    assert report.success_rate == np.mean([e.success for e in report.episodes])
    assert report.normalized_reward == pytest.approx(
        np.mean([e.normalized_reward for e in report.episodes])
    )
    # 20x20 mazes and 4 l steps: random walks mostly fail, with negative R̄.
    assert report.success_rate < 0.2
    assert report.normalized_reward < 0
    # Input recognition is the inputs test of the same (reset) controller.
    direct = evaluate_inputs(RandomController("DD", seed=3), inputs_for_maze(
        "M0_20x20_C1_l.25_L.25_t.5_T.5", "DD"
    ))  # fmt: skip
    assert report.input_recognition == pytest.approx(direct.overall)
    assert report.input_rates == pytest.approx(dict(direct.rates))
    assert 0 < report.input_recognition < 1


def test_episodes_cover_the_suite_in_its_four_rotations(evaluator):
    report = evaluator.evaluate(OracleController("DD"))
    assert [e.maze for e in report.episodes] == standard_suite().maze_strings()
    per_maze = report.per_maze()
    assert list(per_maze) == [(c.name, r) for c in COLUMNS for r in ROWS]
    assert all(scores["episodes"] == 4 for scores in per_maze.values())
    assert sorted({e.start for e in report.episodes}) == ["NE", "NW", "SE", "SW"]
    assert list(report.per_column()) == [c.name for c in COLUMNS]


def test_a_policy_that_always_goes_east_is_scored_per_maze():
    mazes = ["M1_5x5_U", "M2_8x8_C1"]
    report = evaluate(lambda obs: np.zeros(len(obs), dtype=np.int64), "DD", mazes, inputs=False)
    assert [e.maze for e in report.episodes] == ["M1_5x5_U", "M2_8x8_C1"]
    assert set(report.per_column()) == set(mazes)
    assert report.input_recognition is None
    for episode in report.episodes:
        assert not episode.success
        assert episode.steps == 4 * episode.path_length  # the deadline


def test_summary_is_json_ready_with_the_run_folder_keys(evaluator, tmp_path):
    report = evaluator.evaluate(RandomController("DD", seed=0))
    summary = json.loads(json.dumps(report.summary()))
    assert {"success_rate", "normalized_reward", "input_recognition"} <= set(summary)
    assert summary["normalized_reward"] == pytest.approx(report.normalized_reward)
    report.write_csv(tmp_path / "episodes.csv")
    lines = (tmp_path / "episodes.csv").read_text().splitlines()
    assert len(lines) == 73
    assert lines[0].startswith("maze,column,row,start,success")
    assert "16 traps" in report.format()


def test_hybrid_robots_are_evaluated_on_images():
    evaluator = Evaluator("H7")
    seen = []

    def policy(observations):
        seen.append(observations.shape)
        return np.zeros(len(observations), dtype=np.int64)

    report = evaluator.evaluate(policy)
    assert isinstance(report, EvaluationReport)
    assert seen[0] == (72, 1, 7, 7)
    assert (140, 1, 7, 7) in seen  # the input-recognition batch
    assert report.input_recognition is not None


def test_continuous_robots_have_no_input_recognition():
    report = evaluate(RandomController("CC7", seed=0), "CC7", ["M1_4x4_U"])
    assert report.input_recognition is None
    assert len(report.episodes) == 1


def test_bad_policies_are_reported(evaluator):
    with pytest.raises(ValueError, match="actions"):
        evaluator.evaluate(lambda obs: np.zeros(3, dtype=np.int64))
    with pytest.raises(ValueError, match="integers"):
        evaluator.evaluate(lambda obs: np.zeros(len(obs)))
    with pytest.raises(ValueError, match="maze"):
        Evaluator("DD", [])
