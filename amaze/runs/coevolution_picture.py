"""``coevolution.png``: a co-evolution run's progress at a glance, from its ``progress.csv``.

The picture of :class:`~amaze.runs.coevolution.CoevolutionRun`: three panels
over env steps, the trainer's figures on the batches (its :class:`Curve`
columns), the validation success of the validated rounds and of the
champion, and the difficulty of the batches and of the population against
the target's.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from amaze.curriculum.difficulty import difficulty
from amaze.maze.render import save_picture
from amaze.runs.folder import ProgressLog

__all__ = ["Curve", "save_coevolution_plot"]


class Curve(NamedTuple):
    """A ``progress.csv`` column drawn in ``coevolution.png``'s top panel."""

    column: str
    label: str
    style: str = "-"
    width: float = 1.0


def save_coevolution_plot(
    progress: ProgressLog,
    png_path: Path,
    target: str,
    batch_plot: tuple[str, Sequence[Curve]],
    title: str = "",
) -> Path:
    """``coevolution.png``: the batches, validation success and maze difficulty over env steps.

    Top: the trainer's figures on each batch (``batch_plot``: the panel's
    label and its curves). Middle: the validation success of each validated
    round's best and of the champion. Bottom: the mean difficulty of each
    batch and of the population, and the target's as a dashed line.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = progress.rows()
    steps = np.array([float(r["steps"]) for r in rows])

    def column(name: str) -> np.ndarray:
        return np.array([float(r[name]) for r in rows])

    figure, (top, valid, hard) = plt.subplots(3, 1, figsize=(7, 8), dpi=110, sharex=True)
    label, curves = batch_plot
    for curve in curves:
        top.plot(steps, column(curve.column), curve.style, lw=curve.width, label=curve.label)
    top.set_ylabel(label)
    checked = column("validation_success_rate")
    validated = ~np.isnan(checked)  # only every validation_every-th round is validated
    valid.plot(steps[validated], checked[validated], "-", lw=0.6, alpha=0.6, label="round's best")
    valid.plot(steps, column("champion_success_rate"), "-", lw=1.6, label="champion")
    valid.set_ylabel("validation success")
    valid.set_ylim(-0.02, 1.02)
    hard.plot(steps, column("batch_difficulty"), "-", lw=0.6, alpha=0.6, label="batch")
    hard.plot(steps, column("population_difficulty"), "-", lw=1.6, label="population")
    hard.axhline(difficulty(target), ls="--", color="grey", label="target")
    hard.set_ylabel("difficulty")
    hard.set_xlabel("environment steps")
    for axes in (top, valid, hard):
        axes.grid(alpha=0.3)
        if axes.get_legend_handles_labels()[0]:
            axes.legend(loc="lower right", fontsize=8)
    if title:
        top.set_title(title)
    figure.tight_layout()
    try:
        return save_picture(figure, png_path)
    finally:
        plt.close(figure)
