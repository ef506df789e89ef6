"""What every figure of a report shares: the paper style, one colour per treatment, three formats.

* :func:`paper_style`: matplotlib settings for figures read at a column's
  width (8.5 cm, :data:`COLUMN_WIDTH` inches): 7-8 pt text, thin lines;
* :class:`Palette`: one colour per trainer/algorithm cell, the same in every
  figure of every report (:func:`cell_colour`, a fixed mapping from the
  cell's name, whatever else a study holds; for an algorithm variant, from its
  name and the study's ``[variants]``), written once per report as
  ``figures/colours.json``;
* :func:`save_figure`: a figure as PNG (300 dpi), PDF and SVG side by side,
  each written atomically.

matplotlib is imported inside the functions (``Agg``): importing the report
costs nothing until it draws.
"""

from __future__ import annotations

import hashlib
import io
import json
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from amaze.runs.folder import write_bytes

__all__ = [
    "COLUMN_WIDTH",
    "FORMATS",
    "Palette",
    "cell_colour",
    "paper_style",
    "pyplot",
    "save_figure",
    "variant_shifts",
]

#: A journal column, 8.5 cm, in inches.
COLUMN_WIDTH = 8.5 / 2.54
#: Two columns (17.8 cm), in inches, for figures of many treatments.
PAGE_WIDTH = 17.8 / 2.54
#: The formats each figure is written in, the first one shown in ``report.md``.
FORMATS = ("png", "pdf", "svg")
#: Dots per inch of the PNG.
DPI = 300
#: Text sizes in points.
FONT_SIZE = 7
TITLE_SIZE = 8

STYLE = {
    "font.family": "DejaVu Sans",  # has the combining macron of R̄
    "font.size": FONT_SIZE,
    "axes.titlesize": TITLE_SIZE,
    "axes.labelsize": FONT_SIZE,
    "xtick.labelsize": FONT_SIZE,
    "ytick.labelsize": FONT_SIZE,
    "legend.fontsize": FONT_SIZE,
    "legend.frameon": False,
    "axes.linewidth": 0.6,
    "xtick.major.width": 0.6,
    "ytick.major.width": 0.6,
    "xtick.minor.width": 0.4,
    "ytick.minor.width": 0.4,
    "lines.linewidth": 1.2,
    "grid.linewidth": 0.4,
    "grid.alpha": 0.4,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "pdf.fonttype": 42,  # TrueType in the PDF: text stays text
    "svg.fonttype": "none",
    "savefig.dpi": DPI,
}


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the ``Agg`` backend (no window)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


@contextmanager
def paper_style() -> Iterator[Any]:
    """A block whose figures take the paper style; yields ``pyplot``."""
    plt = pyplot()
    with plt.rc_context(STYLE):
        yield plt


#: tab10's colours in an order where neighbours and every other one differ in hue: blue,
#: orange, green, purple, red, cyan, brown, olive, pink, grey.
TAB10_ORDER = (0, 1, 2, 4, 3, 9, 5, 8, 6, 7)
#: Twelve colours that stay apart on white: tab10's in :data:`TAB10_ORDER`, then Dark2's
#: ochre and tab20b's dark olive (each at least as far from the others, in CIELAB, as
#: tab10's closest two are from each other).
COLOURS = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#9467bd",
    "#d62728",
    "#17becf",
    "#8c564b",
    "#bcbd22",
    "#e377c2",
    "#7f7f7f",
    "#a6761d",
    "#637939",
)
#: Each trainer's place in :data:`COLOURS` (its colour with ``cmaes``), fixed once and for all:
#: a trainer added to :data:`experiments.trainers.TRAINERS` takes a free place here.
TRAINER_SLOTS = {
    "direct": 0,
    "interpolation": 1,
    "edhucat-careful": 2,
    "edhucat-random": 3,
    "domain-randomisation": 4,
    "edhucat-follow-edens": 5,
    "edens": 6,
    "edhucat-risky": 7,
    "edens-populations": 8,
    "edhucat-edens": 9,
    "coevolution": 10,
    "edhucat-moderate": 11,
}
#: How far each algorithm moves its trainer's colour along :data:`COLOURS` (a multiple of 3:
#: the four algorithms of one trainer get four colours, the twelve trainers of one algorithm
#: twelve).
ALGORITHM_SHIFTS = {"cmaes": 0, "a2c": 3, "ppo": 6, "neat": 9}
#: What a study's algorithm variants are: each variant's name and its base algorithm.
Variants = Mapping[str, str]


def _stable_index(name: str, size: int) -> int:
    """A place in ``range(size)`` for a name of no table: the same in every process and run
    (not Python's ``hash``, which changes with each interpreter)."""
    return int.from_bytes(hashlib.sha256(name.encode("utf-8")).digest()[:8], "big") % size


def variant_shifts(variants: Variants) -> dict[str, int]:
    """Each algorithm variant's shift along :data:`COLOURS`: a place between the algorithms'.

    The algorithms' shifts are multiples of 3, which leaves 8 places between them; the
    variants, in the order of their names, take each the free place nearest after its
    base's shift (``ppo-fast`` of ``ppo`` at 6: 7), so that up to 8 variants and the 4
    algorithms all differ on one trainer; the 9th starts over. A study's variant names are
    its own, so their colours follow from its ``[variants]`` (the same in each of its
    reports), not from the name alone.
    """
    shifts: dict[str, int] = {}
    taken: set[int] = set()
    for name, base in sorted(variants.items()):
        start = ALGORITHM_SHIFTS.get(base, 0)
        places = [(start + step) % len(COLOURS) for step in range(1, len(COLOURS)) if step % 3]
        free = [place for place in places if place not in taken]
        if not free:
            taken.clear()
            free = places
        shifts[name] = free[0]
        taken.add(free[0])
    return shifts


def cell_colour(cell: str, variants: Variants | None = None) -> str:
    """The colour of a trainer/algorithm cell (``"direct/ppo"``), the same in every report.

    ``COLOURS[(TRAINER_SLOTS[trainer] + ALGORITHM_SHIFTS[algorithm]) % 12]``: it depends on
    the cell's name alone, not on the other cells of a study, so a treatment keeps its
    colour from one report to the next. The cells of one trainer, and those of one
    algorithm, all differ (the default comparisons of a study). An algorithm variant of
    ``variants`` (a study's ``[variants]``: name and base) shifts by
    :func:`variant_shifts`'s place instead, so that it differs from its base and the other
    algorithms on the same trainer. A trainer or an algorithm of none of these (a
    plug-in's) takes a place from a stable hash of its name.
    """
    trainer, algorithm = cell.split("/")[:2]
    slot = TRAINER_SLOTS.get(trainer)
    if slot is None:
        slot = _stable_index(f"trainer:{trainer}", len(COLOURS))
    shift = ALGORITHM_SHIFTS.get(algorithm)
    if shift is None and variants and algorithm in variants:
        shift = variant_shifts(variants)[algorithm]
    if shift is None:
        shift = 3 * _stable_index(f"algorithm:{algorithm}", 4)
    return COLOURS[(slot + shift) % len(COLOURS)]


class Palette:
    """The colours of a study's trainer/algorithm cells (``"direct/ppo"``), for its figures.

    Each cell's colour is :func:`cell_colour`'s: fixed by the cell's name (and for an
    algorithm variant, by the study's ``variants``: name and base), so that a treatment
    has one colour in every figure of every report. With more than 12 cells, some share
    a colour (the figures also name them).
    """

    def __init__(self, cells: Sequence[str], variants: Variants | None = None) -> None:
        self.variants = dict(variants or {})
        self.colours = {cell: cell_colour(cell, self.variants) for cell in sorted(set(cells))}

    def __call__(self, treatment: str) -> str:
        """The colour of a cell or of a treatment (``trainer/algorithm[/condition]``)."""
        return cell_colour(treatment, self.variants)

    def save(self, path: Path) -> Path:
        """Write the mapping as JSON (cell: colour), for figures made elsewhere."""
        text = json.dumps(self.colours, indent=2, sort_keys=True) + "\n"
        write_bytes(path, text.encode("utf-8"))
        return path


def label(treatment: str) -> str:
    """A treatment's name in a legend: ``direct PPO``."""
    trainer, algorithm = treatment.split("/")[:2]
    return f"{trainer} {algorithm.upper()}"


def save_figure(figure: Any, path: Path) -> Path:
    """``figure`` as ``path`` (a ``.png``, 300 dpi) and beside it as ``.pdf`` and ``.svg``.

    Returns the PNG's path; the figure is closed.
    """
    plt = pyplot()
    try:
        for suffix in FORMATS:
            buffer = io.BytesIO()
            metadata = {"Date": None} if suffix == "svg" else {}
            if suffix == "pdf":
                metadata = {"CreationDate": None}
            figure.savefig(buffer, format=suffix, dpi=DPI, metadata=metadata)
            write_bytes(path.with_suffix(f".{suffix}"), buffer.getvalue())
    finally:
        plt.close(figure)
    return path.with_suffix(".png")
