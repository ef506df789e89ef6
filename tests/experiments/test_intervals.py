"""IQM, probability of improvement, performance profiles and seeded stratified bootstrap CIs.

The expected figures are worked out by hand in the comments, not by the code
under test.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from experiments import intervals
from experiments.intervals import (
    Interval,
    curve_intervals,
    iqm,
    performance_profile,
    performance_profile_ci,
    probability_of_improvement,
    probability_of_improvement_ci,
    stratified_bootstrap_ci,
    stratified_resamples,
)

# ---------------------------------------------------------------- IQM


def test_iqm_of_four_values_is_the_mean_of_the_middle_two() -> None:
    # a quarter of 4 is 1 cut at each end: mean(2, 3)
    assert iqm([1.0, 2.0, 3.0, 4.0]) == 2.5


def test_iqm_trims_a_quarter_at_each_end_whatever_the_order() -> None:
    # 8 values: 2 cut at each end (0, 1 and 6, 100): mean(2, 3, 4, 5) = 3.5,
    # where the plain mean is 121 / 8 = 15.125
    assert iqm([100.0, 3.0, 0.0, 5.0, 1.0, 6.0, 4.0, 2.0]) == 3.5
    # 5 values: int(5 / 4) = 1 cut at each end: mean(2, 3, 4)
    assert iqm([5.0, 1.0, 4.0, 2.0, 3.0]) == 3.0


def test_iqm_pools_runs_and_tasks() -> None:
    scores = [[1.0, 10.0], [2.0, 20.0], [3.0, 30.0], [4.0, 40.0]]  # (4 runs, 2 tasks)
    # pooled and sorted: 1 2 3 4 10 20 30 40; the middle half 3 4 10 20 -> 37 / 4
    # (the mean of the per-task IQMs would be (2.5 + 25) / 2 = 13.75)
    assert iqm(scores) == 9.25


# ---------------------------------------------------------------- probability of improvement


def test_probability_of_improvement_counts_pairs_and_halves_ties() -> None:
    # x = 1 beats 0; x = 2 beats 0 and ties 2 twice (1 + 0.5 + 0.5); x = 3 beats all three:
    # (1 + 2 + 3) / 9 pairs
    assert probability_of_improvement([1.0, 2.0, 3.0], [0.0, 2.0, 2.0]) == pytest.approx(6 / 9)
    # the other way: y = 0 beats none; each y = 2 beats 1 and ties 2: 2 * 1.5 / 9
    assert probability_of_improvement([0.0, 2.0, 2.0], [1.0, 2.0, 3.0]) == pytest.approx(3 / 9)
    # x = [1, 2, 3], y = [0, 2, 5]: 1 beats 0 (1); 2 beats 0, ties 2 (1.5); 3 beats 0, 2 (2)
    assert probability_of_improvement([1.0, 2.0, 3.0], [0.0, 2.0, 5.0]) == pytest.approx(4.5 / 9)


def test_probability_of_improvement_averages_over_tasks() -> None:
    x = [[1.0, 5.0], [2.0, 6.0], [3.0, 7.0]]
    y = [[0.0, 8.0], [2.0, 9.0], [5.0, 10.0]]
    # task 0: 4.5 / 9 (above); task 1: every y beats every x, 0; mean 0.25
    assert probability_of_improvement(x, y) == pytest.approx(0.25)


def test_probability_of_improvement_takes_unequal_run_counts_and_equal_samples() -> None:
    # x = 4 beats 1, 2, 3 (3); x = 1 ties 1 (0.5): 3.5 / (2 * 3)
    assert probability_of_improvement([[4.0], [1.0]], [[1.0], [2.0], [3.0]]) == pytest.approx(
        7 / 12
    )
    assert probability_of_improvement([1.0, 2.0], [1.0, 2.0]) == 0.5


# ---------------------------------------------------------------- performance profile


def test_performance_profile_counts_scores_strictly_above_each_tau() -> None:
    scores = [[0.1, 0.5], [0.9, 0.5]]  # 4 scores, runs and tasks pooled
    # > 0: all 4; > 0.3: 0.5, 0.5, 0.9; > 0.5: only 0.9 (0.5 is not above 0.5);
    # > 0.8: 0.9; > 1: none
    profile = performance_profile(scores, [0.0, 0.3, 0.5, 0.8, 1.0])
    np.testing.assert_array_equal(profile, [1.0, 0.75, 0.25, 0.25, 0.0])


def test_performance_profile_ci_brackets_the_profile_and_is_exact_where_no_resample_moves() -> None:
    scores = np.array([[0.2, 0.6], [0.4, 0.8], [0.3, 0.9], [0.5, 0.7]])
    point, low, high = performance_profile_ci(scores, [0.0, 0.45, 1.0], reps=500, seed=3)
    # 5 of the 8 scores are above 0.45: 0.5, 0.6, 0.7, 0.8, 0.9
    np.testing.assert_array_equal(point, [1.0, 5 / 8, 0.0])
    # every score is above 0 and none above 1, in every resample: no width there
    assert (low[0], high[0], low[2], high[2]) == (1.0, 1.0, 0.0, 0.0)
    # task 1 (0.6..0.9) always gives its 4 runs above 0.45, task 0 as many as it draws
    # of its 0.5 (none with chance (3/4)^4 = 0.32): from 4/8 to 8/8, the low at 4/8
    assert low[1] == 0.5 and point[1] < high[1] <= 1.0


# ---------------------------------------------------------------- the bootstrap


def test_bootstrap_of_two_runs_follows_the_resample_distribution() -> None:
    # runs 0 and 1: a resample's mean is 0 (1/4), 0.5 (1/2) or 1 (1/4)
    interval = stratified_bootstrap_ci([0.0, 1.0], np.mean, reps=2000, seed=1)
    assert (interval.point, interval.low, interval.high, interval.n) == (0.5, 0.0, 1.0, 2)
    # a 40 % interval runs from the 30th to the 70th percentile, both inside the half at 0.5
    narrow = stratified_bootstrap_ci([0.0, 1.0], np.mean, reps=2000, confidence=0.4, seed=1)
    assert (narrow.low, narrow.high) == (0.5, 0.5)


def test_bootstrap_ci_covers_the_true_mean_about_as_often_as_it_should() -> None:
    """1000 samples of 10 runs from Normal(0.5, 0.1), the 95 % CI of the mean of each.

    The percentile bootstrap undercovers at n = 10 (it uses the plug-in
    variance and normal-like quantiles, not Student's t): about 90 % of the
    intervals cover 0.5, which the bounds leave room for (1000 intervals: a
    standard error of about 1 %). An interval that resampled tasks instead of
    runs (zero width here) covers almost never; one twice too wide almost
    always. The width must follow each sample's spread: about
    2 * 1.96 * sqrt(9 / 10) / sqrt(10) = 1.18 sample standard deviations, so
    an interval of fixed width fails too.
    """
    samples = np.random.default_rng(0).normal(0.5, 0.1, size=(1000, 10))
    found = [
        stratified_bootstrap_ci(sample, np.mean, reps=1000, seed=i)
        for i, sample in enumerate(samples)
    ]
    low = np.array([interval.low for interval in found])
    high = np.array([interval.high for interval in found])
    coverage = np.mean((low <= 0.5) & (0.5 <= high))
    assert 0.86 <= coverage <= 0.96, coverage
    ratio = (high - low) / samples.std(axis=1, ddof=1)
    assert 0.95 <= ratio.min() and ratio.max() <= 1.45, (ratio.min(), ratio.max())


def test_the_same_seed_gives_the_same_interval_and_another_seed_another() -> None:
    scores = np.random.default_rng(7).uniform(size=(10, 3))
    first = stratified_bootstrap_ci(scores, seed=11)
    assert stratified_bootstrap_ci(scores, seed=11) == first
    other = stratified_bootstrap_ci(scores, seed=12)
    assert other.point == first.point
    assert (other.low, other.high) != (first.low, first.high)
    assert first.low < first.point < first.high
    assert first.n == 10


def test_the_global_numpy_generator_plays_no_part() -> None:
    scores = np.random.default_rng(8).uniform(size=(6, 2))
    np.random.seed(1)  # noqa: NPY002 - the global state the module must ignore
    first = stratified_bootstrap_ci(scores, seed=4)
    np.random.seed(2)  # noqa: NPY002
    assert stratified_bootstrap_ci(scores, seed=4) == first


def test_each_resample_keeps_every_task_to_its_own_runs() -> None:
    scores = np.array([[0.0, 100.0], [1.0, 101.0], [2.0, 102.0], [3.0, 103.0]])
    chunks = list(stratified_resamples(scores, reps=300, seed=0))
    resamples = np.concatenate(chunks)
    assert resamples.shape == (300, 4, 2)  # 4 runs per task in each resample
    assert set(np.unique(resamples[:, :, 0])) <= {0.0, 1.0, 2.0, 3.0}
    assert set(np.unique(resamples[:, :, 1])) <= {100.0, 101.0, 102.0, 103.0}
    # drawn with replacement: some resample repeats a run, and the runs drawn differ per task
    assert any(len(set(sample[:, 0])) < 4 for sample in resamples)
    assert any(not np.array_equal(sample[:, 0], sample[:, 1] - 100.0) for sample in resamples)


def test_stratification_keeps_the_interval_to_what_the_tasks_allow() -> None:
    # task 0: ten runs of 0 or 1; task 1: ten runs of 100 or 101. A stratified
    # resample's mean is 50 + (ones in task 0 + ones in task 1) / 20, within
    # [50, 51]. A bootstrap that pooled the 20 scores would mix the tasks'
    # shares (about +-11 around 50.5), and one that resampled tasks would
    # give means of 0.5 or 100.5.
    scores = np.array([[0.0, 100.0], [1.0, 101.0]] * 5)
    interval = stratified_bootstrap_ci(scores, np.mean, reps=2000, seed=0)
    assert interval.point == 50.5
    assert 50.0 <= interval.low < interval.point < interval.high <= 51.0


def test_one_run_gives_a_zero_width_interval() -> None:
    interval = stratified_bootstrap_ci([[0.3, 0.7]], reps=50, seed=0)
    # iqm of the pooled 0.3, 0.7: nothing to trim from 2 values
    assert interval == Interval(point=0.5, low=0.5, high=0.5, n=1)


def test_a_statistic_computed_one_resample_at_a_time_sees_the_same_resamples() -> None:
    scores = np.random.default_rng(9).uniform(size=(8, 3))
    batched = stratified_bootstrap_ci(scores, np.mean, reps=300, seed=5)
    looped = stratified_bootstrap_ci(scores, lambda a: float(np.mean(a)), reps=300, seed=5)
    assert looped.point == pytest.approx(batched.point, abs=1e-12)
    assert looped.low == pytest.approx(batched.low, abs=1e-12)
    assert looped.high == pytest.approx(batched.high, abs=1e-12)


def test_chunking_changes_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    scores = np.random.default_rng(10).uniform(size=(9, 4))
    whole = stratified_bootstrap_ci(scores, reps=700, seed=2)
    monkeypatch.setattr(intervals, "_CHUNK_ELEMENTS", 50)  # one resample (36 values) a chunk
    assert stratified_bootstrap_ci(scores, reps=700, seed=2) == whole


def test_interval_is_frozen() -> None:
    interval = Interval(point=1.0, low=0.0, high=2.0, n=3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        interval.low = -1.0  # type: ignore[misc]


# ---------------------------------------------------------------- other intervals


def test_probability_of_improvement_ci_is_seeded_and_exact_for_dominance() -> None:
    # every x beats every y on both tasks, in any resample: 1, with no width
    x, y = [[5.0, 6.0], [7.0, 8.0], [9.0, 9.5]], [[0.0, 1.0], [2.0, 3.0]]
    assert probability_of_improvement_ci(x, y, reps=200, seed=0) == Interval(1.0, 1.0, 1.0, 2)
    rng = np.random.default_rng(4)
    a, b = rng.normal(0.6, 0.2, size=(10, 3)), rng.normal(0.5, 0.2, size=(8, 3))
    first = probability_of_improvement_ci(a, b, reps=500, seed=6)
    assert first == probability_of_improvement_ci(a, b, reps=500, seed=6)
    assert first != probability_of_improvement_ci(a, b, reps=500, seed=7)
    assert first.low < first.point < first.high
    assert first.n == 8
    assert 0.0 <= first.low and first.high <= 1.0


def test_curve_intervals_give_each_point_its_own_bootstrap() -> None:
    rng = np.random.default_rng(12)
    curves = np.cumsum(rng.uniform(size=(7, 5)), axis=1)  # 7 runs, 5 points
    curves[:, 0] = 2.0  # every run starts at 2
    point, low, high = curve_intervals(curves, reps=400, seed=3)
    assert (point[0], low[0], high[0]) == (2.0, 2.0, 2.0)
    for p in range(5):
        alone = stratified_bootstrap_ci(curves[:, p], reps=400, seed=3)
        assert point[p] == pytest.approx(alone.point, abs=1e-12)
        assert low[p] == pytest.approx(alone.low, abs=1e-12)
        assert high[p] == pytest.approx(alone.high, abs=1e-12)
    assert np.all(low <= point) and np.all(point <= high)


def test_curve_of_one_run_has_no_width() -> None:
    point, low, high = curve_intervals([[0.1, 0.4, 0.9]], reps=10)
    np.testing.assert_array_equal(point, [0.1, 0.4, 0.9])
    np.testing.assert_array_equal(low, point)
    np.testing.assert_array_equal(high, point)


# ---------------------------------------------------------------- errors


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: iqm([]), r"scores is empty \(shape \(0, 1\)\)"),
        (lambda: iqm(np.zeros((3, 0))), r"scores is empty \(shape \(3, 0\)\)"),
        (lambda: iqm([[1.0, 2.0], [math.nan, 3.0]]), r"scores\[1, 0\].* is nan"),
        (lambda: iqm([1.0, math.inf]), r"scores\[1, 0\].* is inf"),
        (lambda: iqm(np.zeros((2, 2, 2))), r"shape \(2, 2, 2\)"),
        (lambda: iqm(["a"]), "scores must be an array of numbers"),
        (
            lambda: probability_of_improvement(np.zeros((3, 2)), np.zeros((3, 4))),
            r"same number of tasks, got 2 \(x.*and 4 \(y",
        ),
        (
            lambda: probability_of_improvement_ci(np.zeros((3, 2)), np.zeros((3, 1))),
            "got 2 .* and 1",
        ),
        (lambda: probability_of_improvement([math.nan], [1.0]), r"x\[0, 0\].* is nan"),
        (lambda: stratified_bootstrap_ci([1.0, 2.0], reps=0), "reps must be at least 1, got 0"),
        (lambda: stratified_bootstrap_ci([1.0, 2.0], reps=2.5), "reps must be an integer, got 2.5"),
        (
            lambda: stratified_bootstrap_ci([1.0, 2.0], confidence=1.0),
            r"confidence must be in \(0, 1\), got 1.0",
        ),
        (
            lambda: probability_of_improvement_ci([1.0], [2.0], confidence=0.0),
            r"confidence must be in \(0, 1\), got 0.0",
        ),
        (lambda: performance_profile_ci([1.0, 2.0], [0.5], reps=-3), "got -3"),
        (lambda: performance_profile([1.0], [0.5, math.nan]), r"taus\[1\] is nan"),
        (lambda: performance_profile([1.0], []), "taus is empty"),
        (lambda: curve_intervals([[1.0, math.nan]]), r"scores_at_points\[0, 1\].* is nan"),
        (lambda: curve_intervals([[1.0], [2.0]], confidence=95), r"got 95"),
    ],
)
def test_bad_input_is_refused_with_the_bad_value_named(call, message) -> None:
    with pytest.raises(ValueError, match=message):
        call()
