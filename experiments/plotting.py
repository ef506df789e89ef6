"""What every figure of a report shares: the paper style, one colour per treatment, three formats.

* :func:`paper_style`: matplotlib settings for figures read at a column's
  width (8.5 cm, :data:`COLUMN_WIDTH` inches): 7-8 pt text, thin lines;
* :class:`Palette`: one colour per trainer/algorithm cell of a study, the
  same in every figure of its report (tab10 by sorted cell; then tab20b's
  dark shades beyond 10 cells; evenly spaced hues beyond 20), written once
  as ``figures/colours.json``;
* :func:`save_figure`: a figure as PNG (300 dpi), PDF and SVG side by side,
  each written atomically.

matplotlib is imported inside the functions (``Agg``): importing the report
costs nothing until it draws.
"""

from __future__ import annotations

import io
import json
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from amaze.runs.folder import write_bytes

__all__ = ["COLUMN_WIDTH", "FORMATS", "Palette", "paper_style", "pyplot", "save_figure"]

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
#: orange, green, purple, red, cyan, brown, olive, pink, grey (a comparison of trainers with
#: one algorithm takes every other cell of the sorted list).
TAB10_ORDER = (0, 1, 2, 4, 3, 9, 5, 8, 6, 7)


class Palette:
    """One colour per trainer/algorithm cell (``"direct/ppo"``), whatever the figure.

    Cells are sorted by name and take tab10's colours in turn
    (:data:`TAB10_ORDER`); with more than 10, then the two darkest shades of
    each of tab20b's hues (no pale colour: lines stay visible on white); with
    more than 20, evenly spaced colours of the ``turbo`` map.
    """

    def __init__(self, cells: Sequence[str]) -> None:
        import matplotlib
        from matplotlib.colors import to_hex

        ordered = sorted(set(cells))
        if len(ordered) <= 10:
            tab10 = matplotlib.colormaps["tab10"].colors
            colours = [tab10[i] for i in TAB10_ORDER]
        elif len(ordered) <= 20:  # tab10, then tab20b's darkest two shades of each hue
            tab10 = matplotlib.colormaps["tab10"].colors
            tab20b = matplotlib.colormaps["tab20b"].colors
            colours = [tab10[i] for i in TAB10_ORDER] + list(tab20b[0::4]) + list(tab20b[1::4])
        else:
            turbo = matplotlib.colormaps["turbo"]
            colours = [turbo(0.05 + 0.9 * i / (len(ordered) - 1)) for i in range(len(ordered))]
        self.colours = {cell: to_hex(colours[i]) for i, cell in enumerate(ordered)}

    def __call__(self, treatment: str) -> str:
        """The colour of a cell or of a treatment (``trainer/algorithm[/condition]``)."""
        trainer, algorithm = treatment.split("/")[:2]
        return self.colours.get(f"{trainer}/{algorithm}", "#666666")

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
