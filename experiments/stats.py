"""Pairwise comparisons of treatments, corrected for multiple testing, as the paper reports them.

The paper compares its treatments with an independent t-test and a
Benjamini-Hochberg correction of the p-values, and marks them with stars
(``*`` p < 0.05, ``**`` < 1e-2, ``***`` < 1e-3, ``****`` < 1e-4). Here each
pair also gets a Mann-Whitney U test (no normality assumed: success rates
are bounded, and replicates are few), corrected the same way, and an effect
size for each: Cohen's d (pooled standard deviation) and the rank-biserial
correlation (``2 U / (n1 n2) - 1``: the probability that a value of the first
group beats one of the second, minus the reverse). The correction is
:func:`scipy.stats.false_discovery_control` over all the pairs tested for
one metric (the family); a pair that cannot be tested (fewer than 2 values
in a group, or no variance at all; for the t-test, no variance within the
groups, where its statistic is infinite) gets no p-value and stays out of
the family.

Stars are shown only where a test can reach them: a pair with a group of
fewer than :data:`MIN_SEEDS` seeds gets none (:func:`stars_withheld` says
why; with 3 against 3 seeds, an exact two-sided Mann-Whitney U test cannot
go below p = 0.1). Its p-values are still computed and kept.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from scipy import stats

__all__ = [
    "MIN_SEEDS",
    "Comparison",
    "cohens_d",
    "compare_pairs",
    "rank_biserial",
    "smallest_u_p",
    "stars",
    "stars_withheld",
]

#: The paper's star thresholds (p below each: one more star).
STAR_THRESHOLDS = (0.05, 1e-2, 1e-3, 1e-4)
#: Fewest seeds in each group of a pair for its stars to be shown.
MIN_SEEDS = 5


def stars(p: float | None) -> str:
    """``*`` to ``****`` for a (corrected) p-value, ``ns`` above 0.05, ``n/a`` without one."""
    if p is None or not math.isfinite(p):
        return "n/a"
    count = sum(p < threshold for threshold in STAR_THRESHOLDS)
    return "*" * count if count else "ns"


def smallest_u_p(n1: int, n2: int) -> float:
    """The smallest p an exact two-sided Mann-Whitney U test of ``n1`` against ``n2`` values gives.

    Every value of one group above every value of the other is the most
    extreme of the ``C(n1 + n2, n1)`` equally likely orders, at each end:
    ``p = 2 / C(n1 + n2, n1)`` (1 at most).
    """
    if n1 < 1 or n2 < 1:
        return 1.0
    return min(1.0, 2.0 / math.comb(n1 + n2, n1))


def stars_withheld(n1: int, n2: int) -> str | None:
    """Why a pair of ``n1`` and ``n2`` seeds gets no stars; ``None`` when it may have them."""
    if min(n1, n2) >= MIN_SEEDS:
        return None
    return (
        f"{n1} vs {n2} seeds, fewer than {MIN_SEEDS} in a group: no stars (a two-sided"
        f" Mann-Whitney U test of {n1} against {n2} values cannot reach"
        f" p < {smallest_u_p(n1, n2):.2g})"
    )


def cohens_d(a: Sequence[float], b: Sequence[float]) -> float:
    """``(mean(a) - mean(b)) / pooled standard deviation`` (NaN without variance)."""
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    n1, n2 = len(x), len(y)
    if n1 < 2 or n2 < 2:
        return float("nan")
    if np.ptp(x) == 0 and np.ptp(y) == 0:  # (a float variance of equal values may not be 0)
        return float("nan")
    pooled = ((n1 - 1) * x.var(ddof=1) + (n2 - 1) * y.var(ddof=1)) / (n1 + n2 - 2)
    if pooled <= 0:
        return float("nan")
    return float((x.mean() - y.mean()) / math.sqrt(pooled))


def rank_biserial(u: float, n1: int, n2: int) -> float:
    """The rank-biserial correlation of a Mann-Whitney U of the first group: in [-1, 1]."""
    return 2.0 * u / (n1 * n2) - 1.0


@dataclass(frozen=True)
class Comparison:
    """Two treatments compared on one metric."""

    metric: str
    first: str
    second: str
    n_first: int
    n_second: int
    mean_first: float
    mean_second: float
    t_p: float | None
    t_p_corrected: float | None
    cohens_d: float
    u_p: float | None
    u_p_corrected: float | None
    rank_biserial: float

    @property
    def withheld(self) -> str | None:
        """Why this pair shows no stars (:func:`stars_withheld`), or ``None``."""
        return stars_withheld(self.n_first, self.n_second)

    @property
    def t_stars(self) -> str:
        """The stars of the corrected t-test's p; ``""`` where they are withheld."""
        return "" if self.withheld else stars(self.t_p_corrected)

    @property
    def u_stars(self) -> str:
        """The stars of the corrected U test's p; ``""`` where they are withheld."""
        return "" if self.withheld else stars(self.u_p_corrected)


def _testable(x: np.ndarray, y: np.ndarray) -> bool:
    """Both groups have 2 values or more, and the values are not all equal."""
    return len(x) >= 2 and len(y) >= 2 and bool(np.ptp(np.concatenate([x, y])) > 0)


def _t_testable(x: np.ndarray, y: np.ndarray) -> bool:
    """A t statistic exists: some variance within the groups (else it is infinite)."""
    return bool(np.ptp(x) > 0 or np.ptp(y) > 0)


def compare_pairs(
    metric: str,
    groups: Mapping[str, Sequence[float]],
    pairs: Sequence[tuple[str, str]] | None = None,
) -> list[Comparison]:
    """Every pair of ``groups`` (or the ``pairs`` given) compared on ``metric``, corrected.

    ``groups`` maps a treatment to its replicates' values (NaN values are
    left out). The t-test is scipy's ``ttest_ind`` (Student's, as the paper);
    the U test is two-sided.
    """
    values = {
        name: np.asarray([v for v in data if v is not None and math.isfinite(v)], dtype=float)
        for name, data in groups.items()
    }
    chosen = list(pairs) if pairs is not None else list(combinations(values, 2))
    raw: list[tuple[str, str, float | None, float, float | None, float]] = []
    for first, second in chosen:
        x, y = values[first], values[second]
        d = cohens_d(x, y)
        if not _testable(x, y):
            raw.append((first, second, None, d, None, float("nan")))
            continue
        t_p = None
        if _t_testable(x, y):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # one group without variance
                t_p = float(stats.ttest_ind(x, y).pvalue)
        u = stats.mannwhitneyu(x, y, alternative="two-sided")
        r = rank_biserial(float(u.statistic), len(x), len(y))
        if t_p is not None and not math.isfinite(t_p):
            t_p = None
        raw.append((first, second, t_p, d, float(u.pvalue), r))
    corrected_t = _corrected([row[2] for row in raw])
    corrected_u = _corrected([row[4] for row in raw])
    comparisons = []
    for (first, second, t_p, d, u_p, r), t_c, u_c in zip(
        raw, corrected_t, corrected_u, strict=True
    ):
        x, y = values[first], values[second]
        comparisons.append(
            Comparison(
                metric=metric,
                first=first,
                second=second,
                n_first=len(x),
                n_second=len(y),
                mean_first=float(x.mean()) if len(x) else float("nan"),
                mean_second=float(y.mean()) if len(y) else float("nan"),
                t_p=t_p,
                t_p_corrected=t_c,
                cohens_d=d,
                u_p=u_p,
                u_p_corrected=u_c,
                rank_biserial=r,
            )
        )
    return comparisons


def _corrected(p_values: Sequence[float | None]) -> list[float | None]:
    """Benjamini-Hochberg over the p-values present; ``None`` stays ``None``."""
    present = [i for i, p in enumerate(p_values) if p is not None]
    corrected: list[float | None] = [None] * len(p_values)
    if present:
        adjusted = stats.false_discovery_control([p_values[i] for i in present], method="bh")
        for index, value in zip(present, adjusted, strict=True):
            corrected[index] = float(value)
    return corrected
