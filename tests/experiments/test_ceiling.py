"""The report's "first reaching" table: when each run's agent first reaches the ceiling."""

from __future__ import annotations

import numpy as np

from experiments.ceiling import ceiling_table, first_reaching
from experiments.comparisons import StudyComparison
from experiments.evaluations import ComparisonData, TreatmentCurves


def _curves(name: str, success: list[list[float]]) -> TreatmentCurves:
    rates = np.array(success)
    points = rates.shape[1]
    steps = np.tile(np.arange(1, points + 1) * 1e6, (len(success), 1))
    return TreatmentCurves(
        name,
        tuple(f"{name}-{i}" for i in range(len(success))),
        {"success_rate": rates, "env_steps": steps, "training_seconds": steps / 1e5},
    )


def test_each_run_is_counted_at_its_first_point_at_the_ceiling() -> None:
    curves = _curves("a", [[0.5, 0.97, 1.0, 0.9], [0.1, 0.2, 0.3, 0.96], [1.0, 1.0, 1.0, 1.0]])
    steps, seconds = first_reaching(curves)
    np.testing.assert_array_equal(steps, [2e6, np.nan, 1e6])  # a later dip does not count
    np.testing.assert_array_equal(seconds, [20.0, np.nan, 10.0])


def test_the_table_gives_runs_reaching_and_medians_per_treatment() -> None:
    comparison = StudyComparison("c", "C", "steps", ("a", "b"), ())
    data = ComparisonData(
        comparison,
        (
            _curves("a", [[0.5, 1.0, 1.0], [0.99, 1.0, 1.0], [0.2, 0.3, 0.97]]),
            _curves("b", [[0.1, 0.2, 0.3], [0.0, 0.0, 0.5]]),
        ),
        "digest",
        (),
        (),
    )
    lines = ceiling_table(data).splitlines()
    assert lines[2] == "| a | 3 | 3 | 2.00 M (1.00 M - 3.00 M) | 20.0 s (10.0 s - 30.0 s) |"
    assert lines[3] == "| b | 2 | 0 | - | - |"
