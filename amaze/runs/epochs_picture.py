"""``epochs.png``: what the EDEnS selector of an ``edens-populations`` run chose, epoch by epoch.

Three panels over the decided epochs, from the run's ``epochs.jsonl`` records
(:mod:`amaze.runs.edens_populations`): every alternative's validation success
(the chosen one circled, extinct ones crossed), then the controller the
chosen alternative ran with: its probabilities and temperature, and the sides
of new mazes and the edits of mutants.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from amaze.maze.render import save_picture
from amaze.maze.spec import MazeSpec

__all__ = ["save_epochs_plot"]

#: The controller's fields drawn on [0, 1], and those drawn as integers.
_FRACTIONS = ("replay_probability", "staleness", "temperature", "mutation_probability")
_INTEGERS = ("min_size", "max_size", "edits")


def save_epochs_plot(
    decisions: Sequence[Mapping[str, Any]], png_path: Path, target: str, title: str = ""
) -> Path:
    """``epochs.png`` from ``decisions`` (one ``epochs.jsonl`` object per epoch, in order).

    ``target`` gives ``max_size`` where a controller leaves it unset (the
    target's larger side).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    spec = MazeSpec.from_string(target)
    longest = max(spec.width, spec.height)
    figure, (judged, fractions, sizes) = plt.subplots(3, 1, figsize=(9, 8), dpi=110, sharex=True)
    epochs = np.array([d["epoch"] for d in decisions], dtype=float)
    width = max(len(decisions[0]["alternatives"]) if decisions else 1, 1)
    for d in decisions:
        for a in d["alternatives"]:
            x = d["epoch"] + (a["index"] - (width - 1) / 2) * 0.6 / width
            marker = "x" if a["extinct"] else "o"
            judged.plot(x, a["validation_success_rate"], marker, ms=4, color=f"C{a['index'] % 10}")
            if a["index"] == d["chosen"]:
                judged.plot(x, a["validation_success_rate"], "o", ms=9, mfc="none", color="k")
    for i in range(width):
        judged.plot([], [], "o", ms=4, color=f"C{i % 10}", label=f"alternative {i}")
    judged.plot([], [], "o", ms=9, mfc="none", color="k", label="chosen")
    judged.set_ylabel("validation success")
    judged.set_ylim(-0.05, 1.05)
    # each chosen controller holds over the next epoch: the steps end one epoch after the last
    chosen = [d["alternatives"][d["chosen"]]["controller"] for d in decisions]
    chosen = chosen + chosen[-1:]
    spans = np.append(epochs, epochs[-1] + 1) if len(epochs) else epochs
    for name in _FRACTIONS:
        fractions.step(spans, [c[name] for c in chosen], where="post", label=name)
    regret = [float(c["score"] == "regret") for c in chosen]
    fractions.step(spans, regret, ":", where="post", color="k", label="score is regret")
    fractions.set_ylabel("chosen controller")
    fractions.set_ylim(-0.05, 1.05)
    for name in _INTEGERS:
        values = [longest if c[name] is None else c[name] for c in chosen]
        sizes.step(spans, values, where="post", label=name)
    sizes.set_ylabel("sides, edits")
    sizes.set_xlabel("epoch")
    sizes.xaxis.set_major_locator(MaxNLocator(integer=True))
    for axes in (judged, fractions, sizes):
        axes.grid(alpha=0.3)
        if axes.get_legend_handles_labels()[0]:
            axes.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    if title:
        judged.set_title(title)
    figure.tight_layout()
    try:
        return save_picture(figure, png_path)
    finally:
        plt.close(figure)
