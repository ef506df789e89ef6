"""The figures of a study's report (matplotlib, written under ``DIR/figures/``).

* ``distributions.png``: R̄ and success of every run per treatment (boxes and
  the runs as points), the paper's figures of the same;
* ``inputs.png``: input recognition per input class (empty corridor, lure,
  clue, trap) per treatment;
* ``curves.png``: learning curves, the median over seeds of what each run
  logged in ``progress.csv`` against env steps and against wall-clock
  training seconds (see :func:`learning_curve` for which column each trainer
  logs);
* ``best-trajectories.png``: the best run's agent (by suite success, then
  R̄) in the 4 rotations of its target or evaluation maze.

A run's file that cannot be read (a ``progress.csv`` that is not a progress
log, a picture that is not one) leaves its part out of the figures and is
reported through ``unreadable`` (see :func:`save_figures`); the others are
drawn.
"""

from __future__ import annotations

import csv
import io
import math
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from amaze.errors import one_line
from amaze.maze.render import load_font, save_picture
from amaze.runs.config import read_json_object
from amaze.runs.folder import write_bytes
from experiments.runner import StudyFolder
from experiments.study import Study, StudyError

__all__ = ["learning_curve", "save_figures"]

#: Points of a learning curve's common grid.
GRID = 60
INPUT_KINDS = ("empty", "lure", "clue", "trap")
ALGORITHM_COLORS = {"a2c": "#d95f02", "ppo": "#1b9e77", "cmaes": "#7570b3", "neat": "#e7298a"}


def learning_curve(folder: Path) -> dict[str, np.ndarray] | None:
    """``steps``, ``seconds`` and, when logged, ``success`` and ``rbar`` of a run's progress.

    What each trainer logs: the direct RL run, its evaluation on the paper's
    evaluation maze (``eval_success_rate``, ``eval_normalized_reward``); a curriculum, each
    branch on its own maze (``success``, ``rbar``; its seconds are per
    branch, summed here); coevolution, the champion on validation mazes
    (``champion_success_rate``); direct evolution, the champion's fitness (as R̄
    when the fitness measure is R̄; no success). ``None`` without a log;
    :class:`~experiments.study.StudyError` naming the file for a log that
    cannot be read (not UTF-8 text, not CSV, a missing column, a value that
    is not a number).
    """
    path = folder / "progress.csv"
    try:
        rows = list(csv.DictReader(io.StringIO(path.read_text(encoding="utf-8"))))
        return _curve(rows, folder) if rows else None
    except FileNotFoundError:
        return None
    except (OSError, UnicodeError, csv.Error) as problem:
        raise StudyError(
            f"progress log {str(path)!r} cannot be read: {one_line(problem)}"
        ) from None
    except KeyError as problem:
        raise StudyError(f"progress log {str(path)!r} has no column {problem}") from None
    except (ValueError, TypeError) as problem:
        raise StudyError(f"progress log {str(path)!r}: {one_line(problem)}") from None


def _curve(rows: list[dict[str, Any]], folder: Path) -> dict[str, np.ndarray]:
    """The curve of :func:`learning_curve` from the rows of a progress log."""

    def column(name: str) -> np.ndarray:
        return np.array(
            [float(row[name]) if row[name] not in ("", None) else np.nan for row in rows]
        )

    fields = rows[0].keys()
    curve = {"steps": column("steps")}
    if "branches" in fields:
        curve["seconds"] = np.cumsum(column("seconds"))
        curve["success"], curve["rbar"] = column("success"), column("rbar")
    else:
        curve["seconds"] = column("seconds")
        if "eval_success_rate" in fields:
            curve["success"], curve["rbar"] = (
                column("eval_success_rate"),
                column("eval_normalized_reward"),
            )
        elif "champion_success_rate" in fields:
            curve["success"] = column("champion_success_rate")
        elif "champion" in fields:
            try:
                config = read_json_object(folder / "config.json", StudyError, "run config")
            except StudyError:  # without its config, the fitness is not known to be R̄
                config = {}
            if config.get("fitness") == "normalized_reward":
                curve["rbar"] = column("champion")
    return curve


def _median_curve(curves: Sequence[dict[str, np.ndarray]], x_name: str, y_name: str):
    usable = [c for c in curves if y_name in c and len(c[x_name])]
    if not usable:
        return None
    end = max(float(np.nanmax(c[x_name])) for c in usable)
    if not math.isfinite(end) or end <= 0:
        return None
    grid = np.linspace(0, end, GRID)
    stacked = []
    for curve in usable:
        x, y = curve[x_name], curve[y_name]
        index = np.searchsorted(x, grid, side="right") - 1
        values = np.where(index >= 0, y[np.clip(index, 0, None)], np.nan)
        values = np.where(grid <= x[-1], values, y[-1])  # a finished run holds its last value
        stacked.append(values)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a grid point no seed has reached
        return grid, np.nanmedian(np.vstack(stacked), axis=0)


#: Hears of a run's file that cannot be read: the run's id, what is left out, why.
Unreadable = Callable[[str, str, str], None]


def save_figures(
    folder: StudyFolder,
    study: Study,
    rows: Sequence[dict[str, Any]],
    unreadable: Unreadable | None = None,
) -> list[tuple[str, Path]]:
    """Write the figures (see the module docstring); return their titles and paths.

    A run's file that cannot be read is left out and ``unreadable`` hears of it.
    """
    heard: Unreadable = unreadable or (lambda run_id, what, reason: None)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = folder.out / "figures"
    out.mkdir(parents=True, exist_ok=True)
    treatments = [t for t in study.treatments if any(r["treatment"] == t for r in rows)]
    written: list[tuple[str, Path]] = []
    if not treatments:
        return written
    conditions = list(dict.fromkeys(t.split("/")[2] for t in treatments))
    trainers = list(dict.fromkeys(t.split("/")[0] for t in treatments))
    rng = np.random.default_rng(0)  # jitter of the points only

    def boxes(ax: Any, condition: str, metric: str, title: str) -> None:
        """One box per treatment of ``condition``, its runs as points coloured by algorithm."""
        mine = [t for t in treatments if t.split("/")[2] == condition]
        data = [
            [r[metric] for r in rows if r["treatment"] == t and not math.isnan(r[metric])]
            for t in mine
        ]
        positions = np.arange(len(mine))
        ax.boxplot(data, positions=positions, widths=0.55, showfliers=False)
        for x, values, treatment in zip(positions, data, mine, strict=True):
            color = ALGORITHM_COLORS.get(treatment.split("/")[1], "#666666")
            jitter = rng.uniform(-0.15, 0.15, len(values))
            ax.scatter(x + jitter, values, s=14, color=color, zorder=3)
        names = [f"{t.split('/')[0]} {t.split('/')[1].upper()}" for t in mine]
        ax.set_xticks(positions, names, fontsize=7, rotation=50, ha="right")
        ax.set_title(title if len(conditions) == 1 else f"{title}, {condition}", fontsize=10)
        ax.grid(axis="y", alpha=0.3)

    def box_grid(metrics: Sequence[tuple[str, str]], path: Path, title: str) -> None:
        """A row per metric, a column per condition."""
        cells = max(sum(t.split("/")[2] == c for t in treatments) for c in conditions)
        width = max(5.0, 0.45 * cells + 1.5)
        figure, axes = plt.subplots(
            len(metrics),
            len(conditions),
            figsize=(width * len(conditions), 3.6 * len(metrics)),
            squeeze=False,
            sharey="row",
        )
        for row, (metric, label) in enumerate(metrics):
            for col, condition in enumerate(conditions):
                boxes(axes[row][col], condition, metric, label)
        figure.tight_layout()
        written.append((title, _save(figure, path)))

    box_grid(
        [
            ("normalized_reward", "Normalized reward R̄ (evaluation suite)"),
            ("success_rate", "Success rate (evaluation suite)"),
        ],
        out / "distributions.png",
        "R̄ and success per treatment",
    )
    box_grid(
        [(f"input_{kind}", f"Input recognition: {kind}") for kind in INPUT_KINDS],
        out / "inputs.png",
        "Input recognition per input class",
    )

    curves: dict[str, list[dict[str, np.ndarray]]] = {t: [] for t in treatments}
    for run in study.runs:
        if run.treatment in curves and (folder.run_folder(run) / "summary.json").is_file():
            try:
                curve = learning_curve(folder.run_folder(run))
            except StudyError as problem:
                heard(run.id, "its learning curve", one_line(problem))
                continue
            if curve is not None:
                curves[run.treatment].append(curve)
    signals = (("success", "success (as logged)"), ("rbar", "R̄ (as logged)"))
    figure, axes = plt.subplots(
        len(signals) * len(conditions), 2, figsize=(13, 3.6 * len(signals) * len(conditions))
    )
    axes = np.atleast_2d(axes)
    styles = ["-", "--", ":", "-."]
    for treatment in treatments:
        trainer, algorithm, condition = treatment.split("/")
        color = ALGORITHM_COLORS.get(algorithm, "#666666")
        style = styles[trainers.index(trainer) % len(styles)]
        for index, (y_name, _) in enumerate(signals):
            row = conditions.index(condition) * len(signals) + index
            for col, x_name in enumerate(("steps", "seconds")):
                median = _median_curve(curves[treatment], x_name, y_name)
                if median is not None:
                    label = f"{trainer} {algorithm.upper()}"
                    axes[row][col].plot(*median, style, color=color, label=label, lw=1.3)
    for condition_index, condition in enumerate(conditions):
        for index, (_, y_label) in enumerate(signals):
            row = condition_index * len(signals) + index
            for col, x_label in enumerate(("env steps", "training seconds")):
                ax = axes[row][col]
                ax.set_xlabel(x_label)
                ax.set_ylabel(y_label)
                if len(conditions) > 1:
                    ax.set_title(condition, fontsize=9)
                ax.grid(alpha=0.3)
    legend: dict[str, Any] = {}
    for ax in axes.flat:
        handles, names = ax.get_legend_handles_labels()
        legend.update(zip(names, handles, strict=True))
    figure.legend(legend.values(), legend.keys(), loc="lower center", ncol=5, fontsize=7)
    figure.suptitle("Learning curves: median over seeds of what each run logged", fontsize=11)
    legend_rows = math.ceil(len(legend) / 5)
    figure.tight_layout(rect=(0, 0.02 + 0.12 * legend_rows / (2 * len(conditions)), 1, 0.97))
    written.append(("Learning curves", _save(figure, out / "curves.png")))

    best = _best(rows)
    if best is not None:
        try:
            strip = _trajectory_strip(folder.out / best["folder"], best)
        except StudyError as problem:
            heard(Path(best["folder"]).name, "its trajectories", one_line(problem))
            strip = None
        if strip is not None:
            path = save_picture(strip, out / "best-trajectories.png")
            written.append(("The best agent's trajectories", path))
    plt.close("all")
    return written


def _save(figure: Any, path: Path) -> Path:
    """``figure`` as a PNG, written atomically."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110)
    write_bytes(path, buffer.getvalue())
    return path


def _best(rows: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
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


def _trajectory_strip(run_folder: Path, row: dict[str, Any]) -> Image.Image | None:
    pictures = sorted((run_folder / "trajectories").glob("*.png"))
    if not pictures:
        return None
    images = [_picture(p) for p in pictures]
    height = 260
    scaled = [im.resize((max(1, im.width * height // im.height), height)) for im in images]
    caption = 34
    strip = Image.new(
        "RGB",
        (sum(im.width for im in scaled) + 10 * (len(scaled) + 1), height + caption + 10),
        "white",
    )
    draw = ImageDraw.Draw(strip)
    draw.text(
        (10, 8),
        f"{row['treatment']}, seed {row['seed']}: suite success {row['success_rate']:.3f},"
        f" R̄ {row['normalized_reward']:.3f}",
        fill=(30, 30, 30),
        font=load_font(14),
    )
    x = 10
    for image in scaled:
        strip.paste(image, (x, caption))
        x += image.width + 10
    return strip
