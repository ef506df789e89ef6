"""The figures of a comparison: learning curves and the performance profile of final agents.

Both read the runs' anytime evaluations (:mod:`experiments.evaluations`), one
quantity for every trainer and algorithm: the agent each run would hand over,
played on the study's one evaluation set.

* ``curves-<comparison>.png``: success rate (top) and normalized reward R̄
  (bottom) against environment steps (left) and against training time
  (right), both on log scales (evolution plays about a thousand times more
  steps than RL in the same time, and takes far less time for the same
  steps), the budget dotted; each treatment a line, the interquartile mean
  over seeds at each evaluation point, placed at the seeds' median steps (or
  seconds), in a 95 % stratified bootstrap band;
* ``profile-<comparison>.png``: the fraction of runs whose final agent's
  success rate exceeds each threshold tau, with 95 % bootstrap bands
  (a performance profile).

Each is a column wide (:data:`~experiments.plotting.COLUMN_WIDTH`), in the
treatments' colours (:class:`~experiments.plotting.Palette`), with one legend
under the panels giving each treatment's number of runs.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from experiments.evaluations import AXES, QUANTITIES, ComparisonData, TreatmentCurves
from experiments.intervals import Bands, performance_profile_ci
from experiments.plotting import COLUMN_WIDTH, Palette, label, paper_style, save_figure

__all__ = ["TAUS", "draw_curves", "draw_profile", "write_comparison_figures"]

#: The thresholds of a performance profile.
TAUS = np.linspace(0.0, 1.0, 101)
#: Legend entries per row, and the longest entry (in characters) that fits two to a row
#: of a column-wide figure; longer names get a row each.
LEGEND_COLUMNS = 2
LEGEND_NAME_CHARACTERS = 26


def _legend_columns(data: ComparisonData) -> int:
    """Entries per legend row: two, or one where a treatment's name would not fit half a row."""
    longest = max(len(f"{label(c.treatment)} (n={c.n})") for c in data.treatments)
    return LEGEND_COLUMNS if longest <= LEGEND_NAME_CHARACTERS else 1


def _legend(figure: Any, axes: Any, columns: int) -> None:
    """One legend for the whole figure, under its panels."""
    handles, names = axes.flat[0].get_legend_handles_labels()
    figure.legend(handles, names, loc="outside lower center", ncol=columns, handlelength=1.5)


def _height(panels_high: float, treatments: int, columns: int) -> float:
    """A figure's height: its panels and the legend's rows."""
    return panels_high + 0.16 * math.ceil(treatments / columns) + 0.1


def draw_curve(ax: Any, curves: TreatmentCurves, bands: Bands, axis: str, colour: str) -> None:
    """One treatment's IQM line over seeds and its 95 % ``bands`` (of one quantity), on ``ax``."""
    x = curves.x(axis)
    name = f"{label(curves.treatment)} (n={curves.n})"
    ax.fill_between(x, bands.low, bands.high, color=colour, alpha=0.2, linewidth=0)
    ax.plot(x, bands.point, color=colour, label=name, marker="o", markersize=1.8)


def _log_axis(ax: Any, data: ComparisonData, axis: str) -> None:
    """A log x axis from decade to decade (labels at decades only), the budget dotted."""
    from matplotlib.ticker import NullFormatter

    ax.set_xscale("log", nonpositive="mask")
    ax.xaxis.set_minor_formatter(NullFormatter())
    values = np.concatenate([curves.x(axis) for curves in data.treatments])
    budget = data.budgets.get(axis)
    if budget:
        ax.axvline(budget, color="0.35", linestyle=":", linewidth=0.8)
        values = np.append(values, budget)
    values = values[values > 0]
    if values.size:
        low, high = np.log10(values.min()), np.log10(values.max())
        ax.set_xlim(10 ** math.floor(low), 10 ** max(math.ceil(high), math.floor(low) + 1))


def draw_curves(data: ComparisonData, palette: Palette, plt: Any) -> Any:
    """The learning-curve figure of one comparison (see the module docstring)."""
    figure, axes = plt.subplots(
        len(QUANTITIES),
        len(AXES),
        figsize=(COLUMN_WIDTH, _height(2.7, len(data.treatments), _legend_columns(data))),
        layout="constrained",
        sharex="col",
        sharey="row",
        squeeze=False,
    )
    for row, (quantity, y_label) in enumerate(QUANTITIES.items()):
        bands = [curves.bands(quantity) for curves in data.treatments]
        for col, (axis, x_label) in enumerate(AXES.items()):
            ax = axes[row][col]
            for curves, band in zip(data.treatments, bands, strict=True):
                draw_curve(ax, curves, band, axis, palette(curves.treatment))
            _log_axis(ax, data, axis)
            if quantity == "success_rate":
                ax.set_ylim(-0.03, 1.03)
            if row == len(QUANTITIES) - 1:
                ax.set_xlabel(x_label)
            if col == 0:
                ax.set_ylabel(y_label)
            ax.grid(True)
    _legend(figure, axes, _legend_columns(data))
    return figure


def draw_profile(data: ComparisonData, palette: Palette, plt: Any) -> Any:
    """The performance profile of the final agents' success rates, one line per treatment."""
    figure, ax = plt.subplots(
        figsize=(COLUMN_WIDTH, _height(1.9, len(data.treatments), _legend_columns(data))),
        layout="constrained",
    )
    for curves in data.treatments:
        colour = palette(curves.treatment)
        bands = performance_profile_ci(curves.final("success_rate"), TAUS, reps=2000, seed=0)
        ax.fill_between(
            TAUS, bands.low, bands.high, step="post", color=colour, alpha=0.2, linewidth=0
        )
        name = f"{label(curves.treatment)} (n={curves.n})"
        ax.step(TAUS, bands.point, where="post", color=colour, label=name)
    ax.set_xlim(0, 1)
    ax.set_ylim(-0.03, 1.03)
    ax.set_xlabel("success rate threshold \u03c4 (final agent, evaluation set)")
    ax.set_ylabel("fraction of runs > \u03c4")
    ax.grid(True)
    _legend(figure, np.array([ax]), _legend_columns(data))
    return figure


def write_comparison_figures(
    data: ComparisonData, palette: Palette, out: Path
) -> list[tuple[str, Path]]:
    """Write the comparison's curves and profile under ``out``; their titles and PNG paths.

    Nothing is drawn for a comparison without a run to draw.
    """
    if not data.treatments:
        return []
    name, title = data.comparison.name, data.comparison.title
    written = []
    with paper_style() as plt:
        path = save_figure(draw_curves(data, palette, plt), out / f"curves-{name}.png")
        written.append((f"Learning curves: {title}", path))
        path = save_figure(draw_profile(data, palette, plt), out / f"profile-{name}.png")
        written.append((f"Performance profile: {title}", path))
    return written
