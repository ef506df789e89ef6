"""Pairwise tests, effect sizes, the Benjamini-Hochberg correction and the stars, by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as scipy_stats

from experiments.stats import (
    MIN_SEEDS,
    cohens_d,
    compare_pairs,
    rank_biserial,
    smallest_u_p,
    stars,
    stars_withheld,
)


@pytest.mark.parametrize(
    ("p", "shown"),
    [
        (0.2, "ns"),
        (0.05, "ns"),
        (0.049, "*"),
        (0.009, "**"),
        (0.0009, "***"),
        (9e-5, "****"),
        (None, "n/a"),
        (math.nan, "n/a"),
    ],
)
def test_stars_follow_the_papers_thresholds(p, shown) -> None:
    assert stars(p) == shown


def test_cohens_d_uses_the_pooled_standard_deviation() -> None:
    a, b = [1.0, 2.0, 3.0], [4.0, 6.0, 8.0]
    # variances 1 and 4, pooled (2*1 + 2*4) / 4 = 2.5; means 2 and 6
    assert cohens_d(a, b) == pytest.approx(-4 / math.sqrt(2.5))
    assert math.isnan(cohens_d([1.0], b))
    assert math.isnan(cohens_d([1.0, 1.0], [1.0, 1.0]))


def test_rank_biserial_runs_from_minus_one_to_one() -> None:
    assert rank_biserial(0, 3, 3) == -1
    assert rank_biserial(9, 3, 3) == 1
    assert rank_biserial(4.5, 3, 3) == 0


def student_p(x: list[float], y: list[float]) -> float:
    """The two-sided p of Student's t-test, from its formula."""
    n1, n2 = len(x), len(y)
    pooled = ((n1 - 1) * np.var(x, ddof=1) + (n2 - 1) * np.var(y, ddof=1)) / (n1 + n2 - 2)
    t = (np.mean(x) - np.mean(y)) / math.sqrt(pooled * (1 / n1 + 1 / n2))
    return 2 * scipy_stats.t.sf(abs(t), n1 + n2 - 2)


def benjamini_hochberg(p: list[float]) -> list[float]:
    """The BH-adjusted p-values, from the step-up rule."""
    m = len(p)
    order = sorted(range(m), key=lambda i: p[i])
    adjusted = [0.0] * m
    running = 1.0
    for rank in range(m, 0, -1):
        index = order[rank - 1]
        running = min(running, p[index] * m / rank)
        adjusted[index] = running
    return adjusted


def test_pairs_are_tested_and_corrected_as_by_hand() -> None:
    groups = {
        "a": [0.10, 0.20, 0.15, 0.12, 0.14],
        "b": [0.50, 0.55, 0.61, 0.45, 0.52],
        "c": [0.11, 0.25, 0.18, 0.09, 0.16],
    }
    found = compare_pairs("success_rate", groups)
    assert [(c.first, c.second) for c in found] == [("a", "b"), ("a", "c"), ("b", "c")]
    raw = [student_p(groups[c.first], groups[c.second]) for c in found]
    assert [c.t_p for c in found] == pytest.approx(raw)
    assert [c.t_p_corrected for c in found] == pytest.approx(benjamini_hochberg(raw))
    u_raw = [c.u_p for c in found]
    assert [c.u_p_corrected for c in found] == pytest.approx(benjamini_hochberg(u_raw))
    ab = found[0]
    assert ab.rank_biserial == -1  # every value of a below every value of b
    assert ab.cohens_d == pytest.approx(cohens_d(groups["a"], groups["b"]))
    assert ab.t_stars == stars(ab.t_p_corrected) != "ns"
    assert found[1].t_stars == "ns"  # a and c overlap


def test_untestable_pairs_stay_out_of_the_family() -> None:
    groups = {"one": [0.5], "flat": [0.2, 0.2, 0.2], "flat2": [0.4, 0.4], "x": [0.1, 0.3, 0.2]}
    found = {(c.first, c.second): c for c in compare_pairs("r", groups)}
    assert found[("one", "x")].t_p is None and found[("one", "x")].u_p is None
    # no variance within either group: no t statistic, but the ranks still differ
    assert found[("flat", "flat2")].t_p is None
    assert found[("flat", "flat2")].u_p is not None
    tested = [c for c in found.values() if c.t_p is not None]
    assert [c.t_p_corrected for c in tested] == pytest.approx(
        benjamini_hochberg([c.t_p for c in tested])
    )


def test_the_smallest_u_p_is_two_orders_out_of_all() -> None:
    assert smallest_u_p(3, 3) == pytest.approx(0.1)  # 2 / C(6, 3)
    assert smallest_u_p(2, 2) == pytest.approx(1 / 3)
    assert smallest_u_p(5, 5) == pytest.approx(2 / 252)
    assert smallest_u_p(0, 4) == 1.0
    # scipy's exact test of two fully separated groups reaches it
    exact = scipy_stats.mannwhitneyu([1, 2, 3], [4, 5, 6], alternative="two-sided").pvalue
    assert exact == pytest.approx(smallest_u_p(3, 3))


def test_with_3_seeds_stars_are_withheld_and_the_reason_given() -> None:
    far = {"low": [0.10, 0.11, 0.12], "high": [0.90, 0.91, 0.92]}
    (pair,) = compare_pairs("success_rate", far)
    assert pair.t_p_corrected < 1e-4  # the t-test alone would say ****
    assert pair.t_stars == pair.u_stars == ""
    assert pair.withheld == stars_withheld(3, 3)
    assert "3 vs 3 seeds, fewer than 5 in a group" in pair.withheld
    assert "Mann-Whitney U test of 3 against 3 values cannot reach p < 0.1" in pair.withheld
    assert stars_withheld(4, 6) is not None and stars_withheld(5, 5) is None
    assert MIN_SEEDS == 5


def test_with_6_seeds_stars_are_shown() -> None:
    far = {"low": [0.10, 0.11, 0.12, 0.13, 0.10, 0.12], "high": [0.90, 0.91, 0.92, 0.9, 0.93, 0.9]}
    (pair,) = compare_pairs("success_rate", far)
    assert pair.withheld is None
    assert pair.t_stars == "****"
    assert pair.u_stars == stars(pair.u_p_corrected) == "**"  # exact p = 2 / C(12, 6)
