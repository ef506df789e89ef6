"""How soon each treatment's runs reach the ceiling: the report's "first reaching" table.

The learning curves show how a treatment's interquartile mean rises; a reader
comparing methods at equal budgets also asks *when* a run's agent first gets
there. For each treatment of a comparison, :func:`ceiling_table` counts the
runs whose agent (played on the study's evaluation set at the anytime points)
reaches a success rate of at least :data:`CEILING`, and gives the median and
range of the env steps and training seconds of the first point where it
does. The resolution is the points' (``evaluation_points``, 20 by default): a
run that gets there between two points is counted at the later one.
"""

from __future__ import annotations

import numpy as np

from experiments.evaluations import ComparisonData, TreatmentCurves

__all__ = ["CEILING", "ceiling_table", "first_reaching"]

#: The success rate on the evaluation set counted as the ceiling.
CEILING = 0.97


def first_reaching(curves: TreatmentCurves, tau: float = CEILING) -> tuple[np.ndarray, np.ndarray]:
    """The env steps and training seconds of each run's first point at success >= ``tau``.

    Two float arrays in the order of ``curves.runs``; NaN for a run that never gets there.
    """
    hits = curves.values["success_rate"] >= tau
    reached = hits.any(axis=1)
    first = hits.argmax(axis=1)
    rows = np.arange(curves.n)
    steps = np.where(reached, curves.values["env_steps"][rows, first], np.nan)
    seconds = np.where(reached, curves.values["training_seconds"][rows, first], np.nan)
    return steps.astype(float), seconds.astype(float)


def _spread(values: np.ndarray, unit: str) -> str:
    """``median (min - max)`` of the finite values, in ``unit`` ("steps" or "s")."""
    values = values[np.isfinite(values)]
    if not values.size:
        return "-"

    def shown(value: float) -> str:
        return f"{value / 1e6:.2f} M" if unit == "steps" else f"{value:.1f} s"

    median = shown(float(np.median(values)))
    if values.size == 1:
        return median
    return f"{median} ({shown(float(values.min()))} - {shown(float(values.max()))})"


def ceiling_table(data: ComparisonData, tau: float = CEILING) -> str:
    """The markdown table of :func:`first_reaching` per treatment (empty without treatments)."""
    if not data.treatments:
        return ""
    lines = [
        f"| treatment | n | runs reaching success >= {tau:g} | env steps to it, median (range)"
        " | training seconds to it, median (range) |",
        "|---|---|---|---|---|",
    ]
    for curves in data.treatments:
        steps, seconds = first_reaching(curves, tau)
        reached = int(np.isfinite(steps).sum())
        lines.append(
            f"| {curves.treatment} | {curves.n} | {reached} | {_spread(steps, 'steps')}"
            f" | {_spread(seconds, 's')} |"
        )
    return "\n".join(lines)
