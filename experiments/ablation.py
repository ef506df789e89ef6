"""Ablations: how far one changed factor moves a study's medians, with intervals.

An ablation compares a *base* study with *variant* studies, each the base with
one factor changed (``paper-code`` and ``paper-code-lr``...), treatment by
treatment (the same ``trainer/algorithm/budget`` in both), from their
``runs.csv`` files (what ``amaze-experiment report`` writes, and what
``experiments/results/`` keeps). For each metric it gives both medians, their
difference (variant - base), a 95 % bootstrap interval of that difference
(``scipy.stats.bootstrap``, the seeds of each study resampled apart, 10,000
resamples, seeded) and the two-sided Mann-Whitney U test's p.

Two factors need no other study, as every run scores both ways
(:data:`WITHIN_RUN`): the suite (the standard suite against the paper's) and
the definition of input recognition (the pooled rate against the paper's mean
of class rates). For those the difference is paired, per run, and its
interval bootstraps the median of the paired differences.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy import stats

from amaze.errors import AmazeError

__all__ = [
    "METRICS",
    "WITHIN_RUN",
    "AblationError",
    "ablation_report",
    "between_studies",
    "read_runs_csv",
    "within_runs",
]

#: The metrics an ablation compares, and how the report names them.
METRICS = {
    "paper_suite_success_rate": "success (paper's suite)",
    "paper_suite_normalized_reward": "R̄ (paper's suite)",
    "success_rate": "success (standard suite)",
    "paper_input_recognition": "input recognition (paper's)",
}
#: The factors every run scores both ways: (name, base column, changed column).
WITHIN_RUN = (
    ("suite: standard -> paper's", "success_rate", "paper_suite_success_rate"),
    ("suite: standard -> paper's (R̄)", "normalized_reward", "paper_suite_normalized_reward"),
    ("input recognition: pooled -> paper's", "input_recognition", "paper_input_recognition"),
)
#: Largest ``runs.csv`` read (a 10,000-run study's is a few MB).
MAX_RUNS_CSV_BYTES = 64 * 2**20
#: Resamples of each bootstrap interval.
RESAMPLES = 10_000
#: The columns an ablation needs in a ``runs.csv``.
NEEDED = ("treatment", "seed", "success_rate", "normalized_reward", "input_recognition")
#: The columns it reads where a ``runs.csv`` has them (studies reported before the paper's
#: suite was scored lack them: their metrics are left out of the comparison).
OPTIONAL = tuple(c for c in (*METRICS, *(w[2] for w in WITHIN_RUN)) if c not in NEEDED)


class AblationError(AmazeError):
    """A ``runs.csv`` an ablation cannot read, or studies it cannot compare."""


def read_runs_csv(path: str | Path) -> list[dict[str, float | str]]:
    """The rows of a study's ``runs.csv``: ``treatment`` and ``seed`` as text, metrics as floats.

    A missing file, one over :data:`MAX_RUNS_CSV_BYTES`, a missing column or a
    metric that is not a number (empty cells are NaN) raises
    :class:`AblationError` naming it.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "runs.csv"
    try:
        size = path.stat().st_size
        if size > MAX_RUNS_CSV_BYTES:
            raise AblationError(f"{str(path)!r} is {size} bytes, over {MAX_RUNS_CSV_BYTES}")
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as problem:
        raise AblationError(f"cannot read {str(path)!r}: {problem}") from None
    reader = csv.DictReader(io.StringIO(text))
    missing = [c for c in NEEDED if c not in (reader.fieldnames or [])]
    if missing:
        raise AblationError(f"{str(path)!r} has no column {', '.join(missing)}")
    rows: list[dict[str, float | str]] = []
    for line, row in enumerate(reader, start=2):
        parsed: dict[str, float | str] = {"treatment": row["treatment"], "seed": row["seed"]}
        for column in (*NEEDED[2:], *OPTIONAL):
            text = (row.get(column) or "").strip()
            try:
                parsed[column] = float(text) if text else math.nan
            except ValueError:
                raise AblationError(
                    f"{str(path)!r} line {line}: {column} {text!r} is not a number"
                ) from None
        rows.append(parsed)
    return rows


def _values(rows: Sequence[dict], treatment: str, column: str) -> np.ndarray:
    values = np.array([r[column] for r in rows if r["treatment"] == treatment], dtype=float)
    return values[np.isfinite(values)]


def _median_difference_ci(variant: np.ndarray, base: np.ndarray) -> tuple[float, float]:
    def difference(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.median(x, axis=axis) - np.median(y, axis=axis)

    if len(variant) < 2 or len(base) < 2:
        return math.nan, math.nan
    result = stats.bootstrap(
        (variant, base),
        difference,
        n_resamples=RESAMPLES,
        method="percentile",
        random_state=np.random.default_rng(0),
        vectorized=True,
    )
    return float(result.confidence_interval.low), float(result.confidence_interval.high)


def _p(variant: np.ndarray, base: np.ndarray) -> float:
    if len(variant) < 2 or len(base) < 2 or np.ptp(np.concatenate([variant, base])) == 0:
        return math.nan
    return float(stats.mannwhitneyu(variant, base, alternative="two-sided").pvalue)


def between_studies(
    base: Sequence[dict], variant: Sequence[dict], factor: str
) -> list[dict[str, float | str | int]]:
    """One record per treatment both studies ran and metric (see the module docstring)."""
    records: list[dict[str, float | str | int]] = []
    shared = [t for t in dict.fromkeys(r["treatment"] for r in base) if t in {
        r["treatment"] for r in variant
    }]  # fmt: skip
    for treatment in shared:
        for column, label in METRICS.items():
            b, v = _values(base, treatment, column), _values(variant, treatment, column)
            if not len(b) or not len(v):
                continue
            low, high = _median_difference_ci(v, b)
            records.append(
                {
                    "factor": factor,
                    "treatment": treatment,
                    "metric": label,
                    "n": min(len(b), len(v)),
                    "base": float(np.median(b)),
                    "variant": float(np.median(v)),
                    "difference": float(np.median(v) - np.median(b)),
                    "low": low,
                    "high": high,
                    "p": _p(v, b),
                }
            )
    return records


def within_runs(rows: Sequence[dict]) -> list[dict[str, float | str | int]]:
    """The factors of :data:`WITHIN_RUN`, paired per run, for each treatment of ``rows``."""
    records: list[dict[str, float | str | int]] = []
    for treatment in dict.fromkeys(r["treatment"] for r in rows):
        mine = [r for r in rows if r["treatment"] == treatment]
        for factor, before, after in WITHIN_RUN:
            pairs = np.array([(r[before], r[after]) for r in mine], dtype=float)
            pairs = pairs[np.all(np.isfinite(pairs), axis=1)]
            if not len(pairs):
                continue
            differences = pairs[:, 1] - pairs[:, 0]
            low = high = math.nan
            if len(pairs) >= 2 and np.ptp(differences) > 0:
                interval = stats.bootstrap(
                    (differences,),
                    np.median,
                    n_resamples=RESAMPLES,
                    method="percentile",
                    random_state=np.random.default_rng(0),
                ).confidence_interval
                low, high = float(interval.low), float(interval.high)
            elif len(pairs) >= 2:
                low = high = float(differences[0])
            records.append(
                {
                    "factor": factor,
                    "treatment": treatment,
                    "metric": "paired",
                    "n": len(pairs),
                    "base": float(np.median(pairs[:, 0])),
                    "variant": float(np.median(pairs[:, 1])),
                    "difference": float(np.median(differences)),
                    "low": low,
                    "high": high,
                    "p": math.nan,
                }
            )
    return records


def _number(value: float | str | int) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, int):
        return str(value)
    return "n/a" if math.isnan(value) else f"{value:.3g}"


def ablation_report(base: str | Path, variants: Sequence[str | Path]) -> str:
    """The ablation of ``variants`` against ``base`` (study folders or ``runs.csv``), Markdown.

    Each variant is named by its folder (or its file's folder). Raises
    :class:`AblationError` for a file it cannot read or a variant that shares
    no treatment with the base.
    """
    base_rows = read_runs_csv(base)
    records = []
    for variant in variants:
        path = Path(variant)
        name = path.name if path.is_dir() else path.parent.name
        found = between_studies(base_rows, read_runs_csv(variant), name)
        if not found:
            raise AblationError(f"{str(variant)!r} shares no treatment with {str(base)!r}")
        records += found
    records += within_runs(base_rows)
    header = "| factor | treatment | metric | n | base | variant | difference [95 % CI] | p |"
    lines = [header, "|---|---|---|---|---|---|---|---|"]
    for r in records:
        shown = f"{_number(r['difference'])} [{_number(r['low'])}, {_number(r['high'])}]"
        lines.append(
            f"| {r['factor']} | {r['treatment']} | {r['metric']} | {r['n']} |"
            f" {_number(r['base'])} | {_number(r['variant'])} | {shown} | {_number(r['p'])} |"
        )
    return "\n".join(lines) + "\n"
