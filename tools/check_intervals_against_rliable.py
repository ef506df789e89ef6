"""Compare :mod:`experiments.intervals` with the ``rliable`` package on seeded score matrices.

A check run by hand, not a test: the project does not depend on rliable
(its bootstrap draws from numpy's global generator, and it pins ``arch``,
which breaks with pandas 3). Run it from a scratch environment that has
rliable, with the project on the path (from the project's root)::

    python3.11 -m venv /tmp/rlcheck
    /tmp/rlcheck/bin/pip install rliable "pandas<3" scipy numpy
    PYTHONPATH=. /tmp/rlcheck/bin/python tools/check_intervals_against_rliable.py

What must agree, and how closely:

* the point estimates, which involve no randomness: the IQM with rliable's
  ``metrics.aggregate_iqm`` to 1e-12, the probability of improvement with
  ``metrics.probability_of_improvement`` exactly, the performance profile with
  ``library.create_performance_profile``'s profile exactly;
* the confidence intervals (percentile, 95 %), which come from different
  random draws (ours from a seeded ``numpy.random.Generator``, rliable's from
  ``np.random.seed`` then the global ``np.random.choice``), so they agree only
  up to the bootstrap's Monte Carlo error. Tolerance on each bound:
  ``TOLERANCE`` (5 %) of rliable's interval width, or one step of the
  statistic's lattice where that is larger (a profile moves by 1 / (runs x
  tasks); the probability of improvement, bootstrapped with at most 2000
  resamples because rliable's is slow, gets two steps of 1 / (n m tasks)).
  With ``--reps`` 10000 the standard error of the difference of two
  independent estimates of a 2.5 % quantile is about 1 % of the width.
  The whole check takes about two minutes, nearly all of it rliable's.

It also shows that rliable ignores the ``random_state`` it is given: two calls
with equal ``RandomState`` objects but different global seeds give different
intervals. It prints a table and exits with status 1 if anything is outside
its tolerance.
"""

from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np

from experiments import intervals as ours

try:
    from rliable import library as rly
    from rliable import metrics
except ImportError:  # pragma: no cover - depends on the environment
    sys.exit(
        "rliable is not importable: run this with an environment that has it "
        "(see the docstring of tools/check_intervals_against_rliable.py)"
    )

#: The tolerance on each CI bound, as a fraction of rliable's interval width.
TOLERANCE = 0.05
CONFIDENCE = 0.95

#: (name, runs, tasks, how the scores are drawn): seeded score matrices.
CASES = [
    ("uniform 5x3", 5, 3, lambda rng, shape: rng.uniform(size=shape)),
    ("normal 10x8", 10, 8, lambda rng, shape: rng.normal(0.5, 0.2, size=shape)),
    ("beta 3x12", 3, 12, lambda rng, shape: rng.beta(0.5, 0.5, size=shape)),
    ("success 20x4", 20, 4, lambda rng, shape: rng.binomial(10, 0.6, size=shape) / 10),
    ("lognormal 30x1", 30, 1, lambda rng, shape: rng.lognormal(0.0, 1.0, size=shape)),
]

ROWS: list[tuple[str, str, str, str, str, str]] = []
FAILURES: list[str] = []


def row(case: str, what: str, mine: object, theirs: object, diff: float, tol: float) -> None:
    ok = diff <= tol + 1e-12  # (a lattice step computed two ways may differ in the last bit)
    if not ok:
        FAILURES.append(f"{case}: {what}")
    ROWS.append(
        (
            case,
            what,
            _show(mine),
            _show(theirs),
            f"{diff:.2e}",
            f"{tol:.1e}" + ("" if ok else " FAIL"),
        )
    )


def _show(value: object) -> str:
    if isinstance(value, tuple):
        return "[" + ", ".join(f"{v:.4f}" for v in value) + "]"
    return f"{value:.6f}" if isinstance(value, float) else str(value)


def rliable_ci(scores, func, reps: int, global_seed: int) -> tuple[float, float]:
    """rliable's percentile interval of ``func``, its global generator seeded first."""
    np.random.seed(global_seed)  # noqa: NPY002 - rliable draws from the global generator
    _, cis = rly.get_interval_estimates(
        {"a": scores}, func, reps=reps, confidence_interval_size=CONFIDENCE
    )
    return float(cis["a"][0, 0]), float(cis["a"][1, 0])


def compare_bounds(case, what, mine: ours.Interval, theirs: tuple[float, float], step=0.0):
    width = theirs[1] - theirs[0]
    tol = max(TOLERANCE * width, step)
    diff = max(abs(mine.low - theirs[0]), abs(mine.high - theirs[1]))
    row(case, what, (mine.low, mine.high), theirs, diff, tol)


def check_case(index: int, name: str, runs: int, tasks: int, draw, reps: int) -> None:
    rng = np.random.default_rng(1000 + index)
    x = draw(rng, (runs, tasks))
    y = draw(rng, (runs + 2, tasks))  # another method, other run count
    taus = np.linspace(float(x.min()) - 0.01, float(x.max()), 7)

    # point estimates
    a, b = ours.iqm(x), float(metrics.aggregate_iqm(x))
    row(name, "IQM point", a, b, abs(a - b), 1e-12)
    a, b = ours.probability_of_improvement(x, y), float(metrics.probability_of_improvement(x, y))
    row(name, "P(X>Y) point", a, b, abs(a - b), 0.0)
    # create_performance_profile bootstraps too; few reps, only its point is compared here
    np.random.seed(index)  # noqa: NPY002
    profiles, profile_cis = rly.create_performance_profile({"a": x}, taus, reps=reps)
    a_profile = ours.performance_profile(x, taus)
    diff = float(np.max(np.abs(a_profile - profiles["a"])))
    row(
        name,
        "profile point (7 taus; tau 3 shown)",
        a_profile[3],
        float(profiles["a"][3]),
        diff,
        0.0,
    )

    # intervals
    mine = ours.stratified_bootstrap_ci(x, ours.iqm, reps=reps, confidence=CONFIDENCE, seed=index)
    theirs = rliable_ci(x, lambda s: np.array([metrics.aggregate_iqm(s)]), reps, index)
    compare_bounds(name, "IQM 95% CI", mine, theirs)

    mine = ours.stratified_bootstrap_ci(x, np.mean, reps=reps, confidence=CONFIDENCE, seed=index)
    theirs = rliable_ci(x, lambda s: np.array([np.mean(s)]), reps, index)
    compare_bounds(name, "mean 95% CI", mine, theirs)

    poi_reps = min(reps, 2000)  # rliable's P(X>Y) runs mannwhitneyu per task per resample
    mine = ours.probability_of_improvement_ci(
        x, y, reps=poi_reps, confidence=CONFIDENCE, seed=index
    )
    np.random.seed(index)  # noqa: NPY002
    _, cis = rly.get_interval_estimates(
        {"xy": [x, y]},
        lambda s, t: np.array([metrics.probability_of_improvement(s, t)]),
        reps=poi_reps,
        confidence_interval_size=CONFIDENCE,
    )
    theirs = (float(cis["xy"][0, 0]), float(cis["xy"][1, 0]))
    # fewer reps, so a larger Monte Carlo error: two steps of its lattice, 1 / (n m tasks)
    compare_bounds(
        name, f"P(X>Y) 95% CI ({poi_reps} reps)", mine, theirs, 2 / (runs * (runs + 2) * tasks)
    )

    _, low, high = ours.performance_profile_ci(
        x, taus, reps=reps, confidence=CONFIDENCE, seed=index
    )
    their_low, their_high = profile_cis["a"]
    diff = np.maximum(np.abs(low - their_low), np.abs(high - their_high))
    tol = np.maximum(TOLERANCE * (their_high - their_low), 1 / x.size)
    worst = int(np.argmax(diff / tol))
    row(
        name,
        f"profile 95% CI (worst tau, {worst})",
        (float(low[worst]), float(high[worst])),
        (float(their_low[worst]), float(their_high[worst])),
        float(diff[worst]),
        float(tol[worst]),
    )


def check_curve(reps: int) -> None:
    """IQM at each point of 12 learning curves of 6 points, point by point.

    rliable takes the curves as (runs, 1 task, points) and draws the runs
    independently at each point; ours resamples whole curves. Each point's
    interval is the same bootstrap either way.
    """
    rng = np.random.default_rng(7)
    curves = np.cumsum(rng.uniform(0.0, 0.3, size=(12, 6)), axis=1)
    point, low, high = ours.curve_intervals(curves, reps=reps, confidence=CONFIDENCE, seed=7)
    np.random.seed(7)  # noqa: NPY002
    _, cis = rly.get_interval_estimates(
        {"a": curves[:, np.newaxis, :]},
        lambda s: np.array([metrics.aggregate_iqm(s[:, :, p]) for p in range(s.shape[2])]),
        reps=reps,
        confidence_interval_size=CONFIDENCE,
    )
    their_low, their_high = cis["a"]
    their_point = np.array([metrics.aggregate_iqm(curves[:, p]) for p in range(6)])
    row("curves 12x6", "IQM points (6)", "", "", float(np.max(np.abs(point - their_point))), 1e-12)
    diff = np.maximum(np.abs(low - their_low), np.abs(high - their_high))
    tol = TOLERANCE * (their_high - their_low)
    worst = int(np.argmax(diff / tol))
    row(
        "curves 12x6",
        f"IQM 95% CI (worst point, {worst})",
        (float(low[worst]), float(high[worst])),
        (float(their_low[worst]), float(their_high[worst])),
        float(diff[worst]),
        float(tol[worst]),
    )


def show_ignored_random_state(reps: int) -> None:
    """rliable given equal RandomStates but different global seeds: different intervals."""
    x = np.random.default_rng(3).uniform(size=(8, 3))
    found = []
    for global_seed in (1, 2):
        np.random.seed(global_seed)  # noqa: NPY002
        with warnings.catch_warnings():  # arch 7 deprecates random_state; it is the point here
            warnings.simplefilter("ignore", FutureWarning)
            _, cis = rly.get_interval_estimates(
                {"a": x},
                lambda s: np.array([metrics.aggregate_iqm(s)]),
                reps=reps,
                random_state=np.random.RandomState(0),
            )
        found.append((float(cis["a"][0, 0]), float(cis["a"][1, 0])))
    print(
        "rliable, random_state=RandomState(0) both times, global seed 1 then 2: "
        f"{_show(found[0])} vs {_show(found[1])} -> "
        + ("different: the random_state is ignored" if found[0] != found[1] else "equal")
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=10000, help="bootstrap resamples per interval")
    reps = parser.parse_args(argv).reps
    for index, (name, runs, tasks, draw) in enumerate(CASES):
        check_case(index, name, runs, tasks, draw, reps)
    check_curve(reps)
    headers = ("case", "quantity", "ours", "rliable", "|diff|", "tolerance")
    widths = [max(len(h), *(len(r[i]) for r in ROWS)) for i, h in enumerate(headers)]
    for line in (headers, tuple("-" * w for w in widths), *ROWS):
        print("  ".join(cell.ljust(w) for cell, w in zip(line, widths, strict=True)).rstrip())
    print()
    show_ignored_random_state(min(reps, 2000))
    if FAILURES:
        print(f"\n{len(FAILURES)} outside tolerance: " + "; ".join(FAILURES))
        return 1
    print(f"\nall {len(ROWS)} comparisons within tolerance ({reps} reps, 95 % intervals)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
