"""Anytime evaluations: when points are due, the evaluation set, the file and its resume."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from amaze.curriculum.validation import reserved_seeds, unseen_mazes, validation_mazes
from amaze.errors import AmazeError
from amaze.evaluation.controllers import OracleController, RandomController
from amaze.maze.spec import MazeSpec
from amaze.runs.anytime import EVALUATION_FIELDS, AnytimeEvaluations, EvaluationSet, Spent

TRAINING = "M3_6x6_C1"


class ToyError(AmazeError):
    pass


@dataclass
class ToyConfig:
    """What the anytime evaluations read of a run config."""

    budget_steps: int | None = 1000
    budget_seconds: float | None = None
    max_generations: int | None = None
    evaluation_points: int = 20
    evaluation_family: int = 3
    regime: str = "direct"
    mazes: tuple[str, ...] = (TRAINING,)
    target: str = TRAINING
    evaluation_maze: str | None = None
    robot: str = "DD"
    error: type[ValueError] = ToyError


def _anytime(tmp_path: Path, **changes: object) -> AnytimeEvaluations:
    return AnytimeEvaluations(tmp_path, ToyConfig(**changes))  # type: ignore[arg-type]


def test_points_are_due_at_even_fractions_of_the_steps_budget(tmp_path: Path) -> None:
    anytime = _anytime(tmp_path)
    assert anytime.due(Spent(1, 49, 0.0)) == []
    assert anytime.due(Spent(1, 50, 0.0)) == [1]
    assert anytime.due(Spent(1, 160, 0.0)) == [1, 2, 3]
    # the last point is the final agent's, taken by finish(), never inside the loop
    assert anytime.due(Spent(9, 5000, 0.0)) == list(range(1, 20))


def test_seconds_then_generations_when_there_is_no_steps_budget(tmp_path: Path) -> None:
    seconds = _anytime(tmp_path, budget_steps=None, budget_seconds=10.0, evaluation_points=4)
    assert seconds.basis == ("seconds", 10.0)
    assert seconds.due(Spent(3, 10**9, 4.9)) == [1]
    generations = _anytime(tmp_path, budget_steps=None, max_generations=8, evaluation_points=4)
    assert generations.due(Spent(4, 10**9, 99.0, generations=4)) == [1, 2]


def test_a_run_without_points_evaluates_nothing(tmp_path: Path) -> None:
    anytime = _anytime(tmp_path, evaluation_points=0)
    assert anytime.take(Spent(1, 10**6, 0.0), lambda: pytest.fail("played")) == 0.0
    assert anytime.finish(Spent(1, 10**6, 0.0), RandomController("DD")) == 0.0
    assert not anytime.log.path.exists() and anytime.figures() == {"points": 0}


def test_the_evaluation_set_is_the_family_with_its_own_seeds() -> None:
    chosen = EvaluationSet.of(["M4_10x10_C1_l.25_L.25"], "DD", 24)
    assert chosen.training == ("M4_10x10_C1_l0.25_L.25",)
    seeds = [MazeSpec.from_string(m).seed for m in chosen.family]
    assert len(set(seeds)) == 24 and not set(seeds) & reserved_seeds()
    for maze in chosen.family:  # the target's fields, another seed
        assert MazeSpec.from_string(maze).where(seed=4) == MazeSpec.from_string(chosen.training[0])
    # none of a run's validation or unseen mazes, whatever its seed
    for seed in (0, 1, 7, 2**32 - 1):
        assert not set(chosen.family) & set(validation_mazes(chosen.training[0], 24, seed))
        assert not set(chosen.family) & set(unseen_mazes(chosen.training[0], seed))
    # the same for every run: its digest depends on the set only
    assert EvaluationSet.of(["M4_10x10_C1_l.25_L.25"], "DD", 24).digest == chosen.digest
    assert EvaluationSet.of(["M4_10x10_C1_l.25_L.25"], "H15", 24).digest != chosen.digest
    assert EvaluationSet.of(["M4_10x10_C1_l.25_L.25"], "DD", 23).digest != chosen.digest


def test_a_curriculum_is_evaluated_on_its_target_family() -> None:
    direct = EvaluationSet.for_config(ToyConfig())
    curriculum = EvaluationSet.for_config(ToyConfig(regime="edhucat", mazes=("M9_5x5",)))
    assert direct == curriculum  # the direct regime's mazes are the curricula's target


def test_a_direct_run_on_family_mazes_can_take_the_curricula_s_set() -> None:
    # domain randomisation: other mazes of the target's family, of other sizes
    family = ("M31_8x8_C1", "M32_10x10_C1")
    own = EvaluationSet.for_config(ToyConfig(mazes=family))
    assert own.training == family and all("_8x8_" in m for m in own.family)
    chosen = EvaluationSet.for_config(ToyConfig(mazes=family, evaluation_maze=TRAINING))
    curriculum = EvaluationSet.for_config(ToyConfig(regime="coevolution"))
    assert chosen == curriculum and chosen.digest != own.digest


def test_rows_split_the_family_from_the_training_mazes(tmp_path: Path) -> None:
    anytime = _anytime(tmp_path)
    oracle = OracleController("DD")
    anytime.take(Spent(2, 120, 1.5), lambda: oracle)
    rows = anytime.log.rows()
    assert [row["point"] for row in rows] == ["1", "2"]  # one evaluation, two points
    assert float(rows[0]["evaluation_seconds"]) > 0 and float(rows[1]["evaluation_seconds"]) == 0
    assert tuple(rows[0]) == EVALUATION_FIELDS
    row = rows[-1]
    assert row["position"] == "2" and row["env_steps"] == "120"
    assert float(row["training_seconds"]) == 1.5
    assert float(row["elapsed_seconds"]) == pytest.approx(
        1.5 + float(rows[0]["evaluation_seconds"]), abs=1e-3
    )
    # the oracle solves every maze optimally: success 1, R̄ 1 on both parts
    for name in ("success_rate", "family_success_rate", "training_success_rate"):
        assert float(row[name]) == 1.0
    assert float(row["normalized_reward"]) == pytest.approx(1.0)
    assert row["evaluation_set"] == anytime.evaluation_set.digest


def test_the_final_point_is_taken_once(tmp_path: Path) -> None:
    anytime = _anytime(tmp_path, evaluation_points=2)
    agent = RandomController("DD", seed=3)
    assert anytime.finish(Spent(5, 700, 2.0), agent) > 0
    assert anytime.finish(Spent(5, 700, 2.0), agent) == 0.0
    rows = anytime.log.rows()
    assert [(r["point"], r["fraction"]) for r in rows] == [("2", "0.7")]  # stopped at 70 %
    assert anytime.figures()["points"] == 2


def test_resume_keeps_the_rows_up_to_the_checkpoint(tmp_path: Path) -> None:
    first = _anytime(tmp_path, evaluation_points=4)
    agent = RandomController("DD", seed=1)
    first.take(Spent(1, 250, 1.0), lambda: agent)
    first.take(Spent(2, 500, 2.0), lambda: agent)
    first.take(Spent(3, 750, 3.0), lambda: agent)

    resumed = _anytime(tmp_path, evaluation_points=4)
    resumed.restore(2, resumed.check())  # the checkpoint was at position 2
    assert [row["point"] for row in resumed.log.rows()] == ["1", "2"]
    assert resumed.taken == 2
    assert resumed.due(Spent(3, 750, 3.0)) == [3]

    nothing = _anytime(tmp_path, evaluation_points=4)
    nothing.restore(None, nothing.check())  # killed before its first checkpoint
    assert nothing.log.rows() == [] and nothing.taken == 0


def test_resume_refuses_rows_of_another_evaluation_set(tmp_path: Path) -> None:
    _anytime(tmp_path).take(Spent(1, 100, 1.0), lambda: RandomController("DD"))
    other = _anytime(tmp_path, evaluation_family=4)
    with pytest.raises(ToyError, match="played the evaluation set"):
        other.check()
    (tmp_path / "evaluations.csv").write_text("point,nonsense\n1,2\n")
    with pytest.raises(ToyError, match="does not start with the header"):
        _anytime(tmp_path).check()
