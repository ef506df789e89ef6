"""Robust aggregate statistics with stratified bootstrap intervals, every draw from a seed.

The statistics of Agarwal et al., "Deep Reinforcement Learning at the Edge of
the Statistical Precipice" (NeurIPS 2021), as their ``rliable`` package
computes them: the interquartile mean (IQM), the probability of improvement,
performance profiles (run-score distributions) and percentile confidence
intervals from a *stratified* bootstrap, one that resamples runs with
replacement within each task and never moves a score from one task to another.

Scores are arrays shaped ``(runs, tasks)``: a run is one seed of a training
method, a task one thing it is scored on (a maze group, a point of a learning
curve). A 1-D array is one task. Every random draw comes from a
:class:`numpy.random.Generator` made from the ``seed`` argument, so an interval
is a function of its inputs: the same call gives the same figures on any
machine, whatever else the process draws.

We do not use ``rliable`` itself: its bootstrap (rliable 1.2.0, ``library.py``,
``StratifiedBootstrap.update_indices``) draws its indices with the global
``np.random.choice``, ignoring the ``random_state`` it is given, and it pins
``arch``, which breaks with pandas 3. ``tools/check_intervals_against_rliable.py``
compares the two on seeded data.

The resampling is vectorised: the indices of many resamples are drawn at once
as a ``(reps, runs, tasks)`` array, in chunks of at most
:data:`_CHUNK_ELEMENTS` elements so that memory stays bounded whatever
``reps``; the figures do not depend on the chunk size (the generator's stream
is the same drawn in one piece or several). The known statistics (:func:`iqm`,
:func:`numpy.mean`, :func:`numpy.median`) are computed on a whole chunk at
once; any other callable is called once per resample.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

__all__ = [
    "Bands",
    "Interval",
    "curve_intervals",
    "iqm",
    "performance_profile",
    "performance_profile_ci",
    "probability_of_improvement",
    "probability_of_improvement_ci",
    "stratified_bootstrap_ci",
    "stratified_resamples",
]

#: The most elements (indices, resampled scores, comparisons) one chunk of
#: resamples holds: 2**22 float64 values are 32 MiB.
_CHUNK_ELEMENTS = 1 << 22

Statistic = Callable[[np.ndarray], float]


@dataclass(frozen=True)
class Interval:
    """A point estimate and its bootstrap confidence interval.

    ``n`` is the number of runs the estimate rests on (for two samples, the
    smaller of their run counts), to be shown beside it: an interval from 3
    runs is not one from 30. The percentile interval of a skewed statistic
    need not contain the point.
    """

    point: float
    low: float
    high: float
    n: int


class Bands(NamedTuple):
    """Point estimates and the bounds of their confidence intervals, one per tau or point."""

    point: np.ndarray
    low: np.ndarray
    high: np.ndarray


# ---------------------------------------------------------------- validation


def _scores(scores: ArrayLike, name: str = "scores") -> np.ndarray:
    """``scores`` as a finite float array shaped (runs, tasks); a 1-D array is one task."""
    try:
        array = np.asarray(scores, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be an array of numbers: {error}") from None
    if array.ndim == 1:
        array = array[:, np.newaxis]
    if array.ndim != 2:
        raise ValueError(f"{name} must be shaped (runs, tasks) or (runs,), got shape {array.shape}")
    if array.size == 0:
        raise ValueError(
            f"{name} is empty (shape {array.shape}): it needs at least one run and one task"
        )
    bad = ~np.isfinite(array)
    if bad.any():
        run, task = (int(i) for i in np.argwhere(bad)[0])
        raise ValueError(
            f"{name} must be finite, but {name}[{run}, {task}] (run {run}, task {task}) "
            f"is {array[run, task]}"
        )
    return array


def _check_reps(reps: int) -> int:
    if isinstance(reps, bool) or not isinstance(reps, numbers.Integral):
        raise ValueError(f"reps must be an integer, got {reps!r}")
    if reps < 1:
        raise ValueError(f"reps must be at least 1, got {reps}")
    return int(reps)


def _check_confidence(confidence: float) -> float:
    if (
        isinstance(confidence, bool)
        or not isinstance(confidence, numbers.Real)
        or not 0.0 < confidence < 1.0
    ):
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    return float(confidence)


def _check_same_tasks(x: np.ndarray, y: np.ndarray) -> None:
    if x.shape[1] != y.shape[1]:
        raise ValueError(
            f"x and y must have the same number of tasks, got {x.shape[1]} (x, shape "
            f"{x.shape}) and {y.shape[1]} (y, shape {y.shape})"
        )


def _taus(taus: ArrayLike) -> np.ndarray:
    try:
        array = np.atleast_1d(np.asarray(taus, dtype=float))
    except (TypeError, ValueError) as error:
        raise ValueError(f"taus must be an array of numbers: {error}") from None
    if array.ndim != 1:
        raise ValueError(f"taus must be 1-D, got shape {array.shape}")
    if array.size == 0:
        raise ValueError("taus is empty: give at least one threshold")
    nan = np.flatnonzero(np.isnan(array))
    if nan.size:
        raise ValueError(f"taus must not be NaN, but taus[{nan[0]}] is nan")
    return array


# ---------------------------------------------------------------- statistics


def iqm(scores: ArrayLike) -> float:
    """The interquartile mean of all the scores, runs and tasks pooled.

    The mean of the middle half of the values (``scipy.stats.trim_mean`` with
    a quarter cut at each end, as rliable's ``aggregate_iqm``): robust to the
    few outlying runs that move a mean, yet using more of the data than a
    median, so its interval is narrower than the median's.
    """
    return float(stats.trim_mean(_scores(scores).ravel(), 0.25))


def _iqm_batched(samples: np.ndarray) -> np.ndarray:
    return stats.trim_mean(samples.reshape(len(samples), -1), 0.25, axis=1)


def _mean_batched(samples: np.ndarray) -> np.ndarray:
    return samples.reshape(len(samples), -1).mean(axis=1)


def _median_batched(samples: np.ndarray) -> np.ndarray:
    return np.median(samples.reshape(len(samples), -1), axis=1)


#: Statistics computed on a chunk of resamples ``(k, runs, tasks)`` at once, giving ``(k,)``.
_BATCHED: dict[Callable[..., object], Callable[[np.ndarray], np.ndarray]] = {
    iqm: _iqm_batched,
    np.mean: _mean_batched,
    np.median: _median_batched,
}


def _statistic_of(statistic: Statistic, samples: np.ndarray) -> np.ndarray:
    """``statistic`` of each resample in ``samples`` (k, runs, tasks), as a (k,) array."""
    batched = _BATCHED.get(statistic)
    if batched is not None:
        return np.asarray(batched(samples), dtype=float)
    return np.fromiter((float(statistic(sample)) for sample in samples), float, len(samples))


def _per_task_improvement(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """P(X > Y) + P(X = Y) / 2 per task, for stacks x (k, n, tasks), y (k, m, tasks): (k, tasks)."""
    left, right = x[:, :, np.newaxis, :], y[:, np.newaxis, :, :]
    wins = np.count_nonzero(left > right, axis=(1, 2))
    ties = np.count_nonzero(left == right, axis=(1, 2))
    # the Mann-Whitney U of x (wins, ties counting a half) over the n m pairs
    return (wins + 0.5 * ties) / (x.shape[1] * y.shape[1])


def probability_of_improvement(x: ArrayLike, y: ArrayLike) -> float:
    """The probability that a run of X beats a run of Y on a task, averaged over the tasks.

    Per task, ``P(X > Y) + P(X = Y) / 2`` over all the pairs of a run of ``x``
    and a run of ``y`` (the Mann-Whitney U of ``x`` divided by ``n m``), then
    the mean over tasks, as rliable's ``metrics.probability_of_improvement``.
    0.5 means neither method tends to beat the other; it says how often, not
    by how much. ``x`` is (runs_x, tasks), ``y`` (runs_y, tasks): the run
    counts may differ, the tasks must match.
    """
    xs, ys = _scores(x, "x"), _scores(y, "y")
    _check_same_tasks(xs, ys)
    return float(np.mean(_per_task_improvement(xs[np.newaxis], ys[np.newaxis])[0]))


def performance_profile(scores: ArrayLike, taus: ArrayLike) -> np.ndarray:
    """The fraction of scores (runs and tasks pooled) strictly above each tau.

    rliable's run-score distribution (``create_performance_profile`` with its
    default ``use_score_distribution=True``): a whole distribution instead of
    one aggregate, from which one reads, e.g., the share of runs that solve
    more than 90 % of their mazes.
    """
    array, thresholds = _scores(scores), _taus(taus)
    return _profile_batched(array[np.newaxis], thresholds)[0]


def _profile_batched(samples: np.ndarray, taus: np.ndarray) -> np.ndarray:
    flat = samples.reshape(len(samples), -1)
    return np.count_nonzero(flat[:, :, np.newaxis] > taus, axis=1) / flat.shape[1]


# ---------------------------------------------------------------- bootstrap


def _resample_chunks(
    scores: np.ndarray, reps: int, rng: np.random.Generator, per_rep: int
) -> Iterator[np.ndarray]:
    """Stratified resamples of ``scores`` (runs, tasks), chunk by chunk: (k, runs, tasks).

    ``per_rep`` is how many elements the caller's work holds per resample,
    which sets the chunk's size.
    """
    runs, tasks = scores.shape
    columns = np.arange(tasks)
    step = max(1, _CHUNK_ELEMENTS // max(per_rep, 1))
    done = 0
    while done < reps:
        k = min(step, reps - done)
        # each task's column gets its own runs, drawn with replacement among its own
        rows = rng.integers(0, runs, size=(k, runs, tasks))
        yield scores[rows, columns]
        done += k


def stratified_resamples(scores: ArrayLike, *, reps: int, seed: int = 0) -> Iterator[np.ndarray]:
    """The bootstrap resamples that :func:`stratified_bootstrap_ci` draws for the same seed.

    Yields chunks shaped ``(k, runs, tasks)`` (the ``k`` add up to ``reps``):
    in each resample, column ``t`` holds ``runs`` scores drawn with
    replacement from column ``t`` of ``scores``, so every task keeps its run
    count and its own scores. Exposed to check the stratification, and to
    compute a statistic the module does not know on the same resamples.
    """
    array = _scores(scores)
    yield from _resample_chunks(array, _check_reps(reps), np.random.default_rng(seed), array.size)


def _percentiles(values: np.ndarray, confidence: float) -> tuple[np.ndarray, np.ndarray]:
    """The percentile interval's bounds over axis 0 (linear interpolation, as ``arch``)."""
    alpha = (1.0 - confidence) / 2.0
    low, high = np.percentile(values, [100 * alpha, 100 * (1.0 - alpha)], axis=0)
    return low, high


def stratified_bootstrap_ci(
    scores: ArrayLike,
    statistic: Statistic = iqm,
    *,
    reps: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> Interval:
    """``statistic(scores)`` and its percentile confidence interval from a stratified bootstrap.

    Each of ``reps`` resamples draws, within each task, as many runs as it
    has, with replacement (see :func:`stratified_resamples`); the interval is
    the ``(1 - confidence) / 2`` and ``(1 + confidence) / 2`` percentiles of
    the statistic over the resamples. It is the uncertainty of running the
    same tasks again with new seeds (rliable's default, ``task_bootstrap=False``).

    ``statistic`` maps a (runs, tasks) array to a number: :func:`iqm`,
    ``np.mean`` and ``np.median`` (pooled) are computed for many resamples at
    once; any other callable is called once per resample.

    With one run there is nothing to resample: every resample is the data
    itself, so ``low == high == point``. That zero width says the bootstrap
    cannot measure the uncertainty, not that there is none.
    """
    array = _scores(scores)
    reps, confidence = _check_reps(reps), _check_confidence(confidence)
    point = float(statistic(array))
    runs = array.shape[0]
    if runs == 1:
        return Interval(point, point, point, 1)
    rng = np.random.default_rng(seed)
    values = np.concatenate(
        [
            _statistic_of(statistic, chunk)
            for chunk in _resample_chunks(array, reps, rng, array.size)
        ]
    )
    low, high = _percentiles(values, confidence)
    return Interval(point, float(low), float(high), runs)


def probability_of_improvement_ci(
    x: ArrayLike,
    y: ArrayLike,
    *,
    reps: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> Interval:
    """:func:`probability_of_improvement` of X over Y and its percentile bootstrap interval.

    ``x`` and ``y`` are resampled independently of each other, each stratified
    by task (rliable's ``StratifiedIndependentBootstrap``), from two generators
    spawned from ``seed``. ``n`` is the smaller run count. With one run in
    each, ``low == high == point`` (nothing to resample).
    """
    xs, ys = _scores(x, "x"), _scores(y, "y")
    _check_same_tasks(xs, ys)
    reps, confidence = _check_reps(reps), _check_confidence(confidence)
    point = probability_of_improvement(xs, ys)
    n = min(xs.shape[0], ys.shape[0])
    if xs.shape[0] == 1 and ys.shape[0] == 1:
        return Interval(point, point, point, n)
    rng_x, rng_y = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))
    # a resample's work: the (runs_x, runs_y, tasks) comparisons, twice
    per_rep = 2 * xs.shape[0] * ys.shape[0] * xs.shape[1]
    chunks = zip(
        _resample_chunks(xs, reps, rng_x, per_rep),
        _resample_chunks(ys, reps, rng_y, per_rep),
        strict=True,
    )
    values = np.concatenate([_per_task_improvement(cx, cy).mean(axis=1) for cx, cy in chunks])
    low, high = _percentiles(values, confidence)
    return Interval(point, float(low), float(high), n)


def performance_profile_ci(
    scores: ArrayLike,
    taus: ArrayLike,
    *,
    reps: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> Bands:
    """:func:`performance_profile` at each tau and its pointwise percentile bootstrap interval.

    The resamples are those of :func:`stratified_bootstrap_ci` for the same
    seed, and every tau is read off the same resamples (as rliable does).
    With one run, ``low == high == point``.
    """
    array, thresholds = _scores(scores), _taus(taus)
    reps, confidence = _check_reps(reps), _check_confidence(confidence)
    point = _profile_batched(array[np.newaxis], thresholds)[0]
    if array.shape[0] == 1:
        return Bands(point, point.copy(), point.copy())
    rng = np.random.default_rng(seed)
    per_rep = array.size * thresholds.size
    values = np.concatenate(
        [
            _profile_batched(chunk, thresholds)
            for chunk in _resample_chunks(array, reps, rng, per_rep)
        ]
    )
    low, high = _percentiles(values, confidence)
    return Bands(point, low, high)


def curve_intervals(
    scores_at_points: ArrayLike,
    statistic: Statistic = iqm,
    *,
    reps: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> Bands:
    """For a learning curve: ``statistic`` over the runs at each point, with its interval.

    ``scores_at_points`` is (runs, points): run ``r``'s score at each point of
    the curve (an env-step count, a time). Each point is taken alone, as a
    one-task score array, and gets the interval that
    ``stratified_bootstrap_ci(scores_at_points[:, p], statistic, seed=seed)``
    gives it (the same resamples; equal to rounding). All points are computed
    together, on the same resampled runs (a resample keeps each run's curve
    whole). The bounds are pointwise, not a band that holds for the whole
    curve at once. With one run, ``low == high == point``.
    """
    array = _scores(scores_at_points, "scores_at_points")
    reps, confidence = _check_reps(reps), _check_confidence(confidence)
    runs, points = array.shape
    # each point alone, as a (runs, 1) array: (points, runs, 1)
    per_point = array.T[:, :, np.newaxis]
    point = np.array([float(statistic(column)) for column in per_point])
    if runs == 1:
        return Bands(point, point.copy(), point.copy())
    rng = np.random.default_rng(seed)
    values = []
    step = max(1, _CHUNK_ELEMENTS // array.size)
    done = 0
    while done < reps:
        k = min(step, reps - done)
        # the same draws as stratified_bootstrap_ci's for one task, applied to every point
        rows = rng.integers(0, runs, size=(k, runs, 1))[:, :, 0]
        samples = array[rows]  # (k, runs, points)
        stacked = samples.transpose(0, 2, 1).reshape(k * points, runs, 1)
        values.append(_statistic_of(statistic, stacked).reshape(k, points))
        done += k
    low, high = _percentiles(np.concatenate(values), confidence)
    return Bands(point, low, high)
