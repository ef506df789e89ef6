"""The figures of a study's report from its standard-suite results (written under ``DIR/figures/``).

* ``distributions.png``: R̄ and success on the standard evaluation suite of
  every run per treatment (boxes, and the runs as points in the treatment's
  colour), the paper's figures of the same;
* ``inputs.png``: input recognition per input class (empty corridor, lure,
  clue, trap) per treatment;
* ``best-trajectories.png``: the best run's agent (by suite success, then
  R̄) in the 4 rotations of its target or evaluation maze.

Each is written as PNG (300 dpi), PDF and SVG
(:func:`~experiments.plotting.save_figure`), in the report's one
:class:`~experiments.plotting.Palette`. The learning curves and performance
profiles of the study's comparisons are :mod:`experiments.curves`'.

A run's file that cannot be read (a trajectory picture that is not one)
leaves its part out and is reported through ``unreadable`` (see
:func:`save_figures`); the others are drawn.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from amaze.errors import one_line
from experiments.plotting import COLUMN_WIDTH, PAGE_WIDTH, Palette, label, paper_style, save_figure
from experiments.study import StudyError

__all__ = ["best_run", "draw_boxes", "save_figures"]

INPUT_KINDS = ("empty", "lure", "clue", "trap")
#: The panels of ``distributions.png``: a column of ``runs.csv`` and its label.
SUITE_METRICS = (
    ("normalized_reward", "normalized reward R\u0304\n(evaluation suite)"),
    ("success_rate", "success rate\n(evaluation suite)"),
)
#: The panels of ``inputs.png``.
INPUT_METRICS = tuple((f"input_{kind}", f"input recognition:\n{kind}") for kind in INPUT_KINDS)

#: Hears of a run's file that cannot be read: the run's id, what is left out, why.
Unreadable = Callable[[str, str, str], None]


def _treatments(rows: Sequence[dict[str, Any]], order: Sequence[str]) -> list[str]:
    """The treatments of ``order`` that have rows."""
    present = {row["treatment"] for row in rows}
    return [t for t in order if t in present]


def _box(
    ax: Any, rows: Sequence[dict[str, Any]], mine: Sequence[str], metric: str, palette: Palette
) -> None:
    """One box per treatment of ``mine``, its runs as points in the treatment's colour."""
    rng = np.random.default_rng(0)  # jitter of the points only
    data = [
        [r[metric] for r in rows if r["treatment"] == t and not math.isnan(r[metric])] for t in mine
    ]
    positions = np.arange(len(mine))
    ax.boxplot(
        data,
        positions=positions,
        widths=0.55,
        showfliers=False,
        medianprops={"color": "black", "linewidth": 0.8},
        boxprops={"linewidth": 0.6},
        whiskerprops={"linewidth": 0.6},
        capprops={"linewidth": 0.6},
    )
    for x, values, treatment in zip(positions, data, mine, strict=True):
        jitter = rng.uniform(-0.15, 0.15, len(values))
        ax.scatter(x + jitter, values, s=6, color=palette(treatment), zorder=3, linewidths=0)
    ax.grid(True, axis="y")


def draw_boxes(
    rows: Sequence[dict[str, Any]],
    order: Sequence[str],
    metrics: Sequence[tuple[str, str]],
    palette: Palette,
    plt: Any,
) -> Any:
    """A row of panels per condition and metric, a box per treatment (n under its name)."""
    treatments = _treatments(rows, order)
    conditions = list(dict.fromkeys(t.split("/")[2] for t in treatments))
    widest = max(sum(t.split("/")[2] == c for t in treatments) for c in conditions)
    width = COLUMN_WIDTH if widest <= 6 else PAGE_WIDTH
    panels = [(c, m) for c in conditions for m in metrics]
    figure, axes = plt.subplots(
        len(panels), 1, figsize=(width, 1.25 * len(panels) + 1.0 * len(conditions)),
        layout="constrained", squeeze=False,
    )  # fmt: skip
    for ax, (condition, (metric, name)) in zip(axes[:, 0], panels, strict=True):
        mine = [t for t in treatments if t.split("/")[2] == condition]
        _box(ax, rows, mine, metric, palette)
        ax.set_ylabel(name)
        if len(conditions) > 1:
            ax.set_title(condition, loc="left")
        if metric == metrics[-1][0]:  # the names under each condition's last panel
            counts = [sum(r["treatment"] == t for r in rows) for t in mine]
            names = [f"{label(t)} (n={n})" for t, n in zip(mine, counts, strict=True)]
            ax.set_xticks(range(len(mine)), names, rotation=40, ha="right")
        else:
            ax.set_xticks(range(len(mine)), [""] * len(mine))
    return figure


def best_run(rows: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    """The run of the best agent: by suite success, then R̄."""
    scored = [r for r in rows if not math.isnan(r["success_rate"])]
    if not scored:
        return None
    return max(scored, key=lambda r: (r["success_rate"], r["normalized_reward"]))


def _picture(path: Path) -> Image.Image:
    """The picture in ``path`` as RGB; StudyError naming it when it is not a picture."""
    try:
        with Image.open(path) as image:
            return image.convert("RGB")
    except (OSError, ValueError, Image.DecompressionBombError) as problem:
        raise StudyError(f"picture {str(path)!r} cannot be read: {one_line(problem)}") from None


def trajectory_strip(run_folder: Path) -> Image.Image | None:
    """The run's trajectory pictures side by side (``None`` without any)."""
    pictures = sorted((run_folder / "trajectories").glob("*.png"))
    if not pictures:
        return None
    images = [_picture(p) for p in pictures]
    height = 400
    scaled = [im.resize((max(1, im.width * height // im.height), height)) for im in images]
    strip = Image.new(
        "RGB", (sum(im.width for im in scaled) + 10 * (len(scaled) + 1), height + 20), "white"
    )
    ImageDraw.Draw(strip)  # (a blank canvas; the caption is the figure's)
    x = 10
    for image in scaled:
        strip.paste(image, (x, 10))
        x += image.width + 10
    return strip


def draw_strip(strip: Image.Image, row: dict[str, Any], plt: Any) -> Any:
    """The strip of :func:`trajectory_strip` as a figure a page wide, captioned."""
    height = PAGE_WIDTH * strip.height / strip.width
    figure, ax = plt.subplots(figsize=(PAGE_WIDTH, height + 0.3), layout="constrained")
    ax.imshow(np.asarray(strip), interpolation="lanczos")
    ax.set_axis_off()
    ax.set_title(
        f"{row['treatment']}, seed {row['seed']}: suite success {row['success_rate']:.3f},"
        f" R\u0304 {row['normalized_reward']:.3f}",
        loc="left",
    )
    return figure


def save_figures(
    out: Path,
    study_folder: Path,
    rows: Sequence[dict[str, Any]],
    order: Sequence[str],
    palette: Palette,
    unreadable: Unreadable | None = None,
) -> list[tuple[str, Path]]:
    """Write the figures of the module docstring under ``out``; return their titles and paths.

    ``order`` is the study's treatments; ``study_folder`` holds the runs'
    folders (``rows``' ``folder`` is relative to it). A run's picture that
    cannot be read is left out and ``unreadable`` hears of it.
    """
    heard: Unreadable = unreadable or (lambda run_id, what, reason: None)
    if not _treatments(rows, order):
        return []
    written = []
    with paper_style() as plt:
        figure = draw_boxes(rows, order, SUITE_METRICS, palette, plt)
        written.append(
            ("R̄ and success per treatment", save_figure(figure, out / "distributions.png"))
        )
        figure = draw_boxes(rows, order, INPUT_METRICS, palette, plt)
        written.append(
            ("Input recognition per input class", save_figure(figure, out / "inputs.png"))
        )
        best = best_run(rows)
        try:
            strip = None if best is None else trajectory_strip(study_folder / best["folder"])
        except StudyError as problem:
            heard(Path(best["folder"]).name, "its trajectories", one_line(problem))
            strip = None
        if strip is not None:
            path = save_figure(draw_strip(strip, best, plt), out / "best-trajectories.png")
            written.append(("The best agent's trajectories", path))
    return written
