"""PNG pictures of mazes for humans (Pillow only, no GUI toolkit).

:func:`render_maze` draws one maze: walls as crisp lines, the cells that the
agent can never reach (every cell off the solution of an intersection-free
maze) as a filled block, the start and goal cells as coloured squares, the
signs in their cells and directions, and optionally the solution path and a
thin outline giving each sign's kind (clue, lure or trap).
:func:`render_mazes_grid` tiles several mazes with their maze strings as
captions, and :func:`save_maze_png` writes a picture to disk.

Picture conventions:

* north is up: cell ``(i, j)`` is drawn at column ``i`` and row
  ``height - 1 - j`` of the grid, so the south-west cell ``(0, 0)`` is the
  bottom-left one;
* signs are drawn, in both themes, on a black tile with the gray level an
  agent perceives (a sign of lightness ``v`` is ``round(255 v)`` gray), so that
  lightness, which is what tells clues, lures and traps apart for an agent,
  reads the same way for the human eye. The tile is inset from the walls so a
  wall next to a sign stays visible in the light theme;
* everything axis-aligned (walls, path, markers) sits on whole pixels, so lines
  are sharp at any cell size; sign images are drawn at a higher resolution and
  area-averaged down, which antialiases their edges.

The geometry of a picture (where each cell and wall lands) is described by
:class:`MazeLayout`, which callers can use to draw on top of a rendering.

Options are checked before anything is drawn: a bad theme, a non-boolean
switch, a cell size outside [:data:`MIN_CELL_SIZE`, :data:`MAX_CELL_SIZE`] px,
a wall width or margin that does not fit, or a picture larger than
:data:`MAX_SIDE` px a side raise :class:`RenderError` (an
:class:`~amaze.errors.AmazeError`, so a ``ValueError``) naming the value, and
the ``amaze`` command prints it as one ``error:`` line.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import itertools
import os
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from amaze.errors import AmazeError
from amaze.maze.maze import Maze, as_maze
from amaze.maze.signs import Sign, SignKind, custom_sign_path
from amaze.validation import check_integer

Color = tuple[int, int, int]


class RenderError(AmazeError):
    """A picture option is invalid (a theme, a cell size, a wall width...)."""


THEMES: tuple[str, ...] = ("light", "dark")
MIN_CELL_SIZE = 4
MAX_CELL_SIZE = 512
#: Largest picture side (px), to refuse accidental gigapixel renderings.
MAX_SIDE = 16384
#: Automatic cell sizes aim at pictures of about this many pixels on their long side.
TARGET_SIDE = 720
#: Automatic cell sizes stay in this range (px).
AUTO_CELL_RANGE = (6, 64)
#: Signs lie on black tiles in every theme, so a pixel's gray level is what an agent sees.
SIGN_TILE: Color = (0, 0, 0)
#: Sign images are drawn this many times larger, then area-averaged down.
_SIGN_SUPERSAMPLING = 4


def _hex(code: str) -> Color:
    code = code.lstrip("#")
    return (int(code[0:2], 16), int(code[2:4], 16), int(code[4:6], 16))


@dataclass(frozen=True)
class Palette:
    """The colours of one theme (RGB triples)."""

    background: Color
    wall: Color
    unreachable: Color
    text: Color
    path: Color
    start: Color
    goal: Color
    clue: Color
    lure: Color
    trap: Color

    def kind_color(self, kind: SignKind) -> Color:
        """The outline colour of a sign of this kind."""
        return {SignKind.CLUE: self.clue, SignKind.LURE: self.lure, SignKind.TRAP: self.trap}[kind]


_THEME_BASE = {
    "light": {
        "background": _hex("#ffffff"),
        "wall": _hex("#111111"),
        "unreachable": _hex("#c4c4c4"),
        "text": _hex("#222222"),
    },
    "dark": {
        "background": _hex("#1d1f21"),
        "wall": _hex("#e8e8e8"),
        "unreachable": _hex("#4a4c4f"),
        "text": _hex("#dddddd"),
    },
}

# Marker colours. The standard set follows the reference viewer (blue path, red
# start, green goal); the colour-blind-safe set uses the seaborn "colorblind"
# (Okabe-Ito based) colours the reference switches to: teal path, orange start,
# blue goal, and sky blue / yellow / pink for clue / lure / trap outlines. It is
# the same on both themes.
_COLORBLIND_ACCENTS = {
    "path": "#029e73",
    "start": "#de8f05",
    "goal": "#0173b2",
    "clue": "#56b4e9",
    "lure": "#ece133",
    "trap": "#cc78bc",
}

_MARKERS = {
    ("light", False): {
        "path": "#1f6fd1",
        "start": "#d62728",
        "goal": "#2ca02c",
        "clue": "#2ca02c",
        "lure": "#ff9f1c",
        "trap": "#d62728",
    },
    ("dark", False): {
        "path": "#4f9cf0",
        "start": "#e5484d",
        "goal": "#3fb950",
        "clue": "#3fb950",
        "lure": "#ffb340",
        "trap": "#e5484d",
    },
    ("light", True): _COLORBLIND_ACCENTS,
    ("dark", True): _COLORBLIND_ACCENTS,
}


def palette(theme: str = "light", colorblind: bool = False) -> Palette:
    """The colours used for ``theme`` (``"light"`` or ``"dark"``)."""
    if theme not in THEMES:
        raise RenderError(f"unknown theme {theme!r} (expected one of {', '.join(THEMES)})")
    markers = {name: _hex(code) for name, code in _MARKERS[(theme, bool(colorblind))].items()}
    return Palette(**_THEME_BASE[theme], **markers)


@dataclass(frozen=True)
class RenderOptions:
    """How to draw a maze. Every field has a sensible default.

    ``None`` sizes are chosen from the maze size: ``cell_size`` so the picture is
    about :data:`TARGET_SIDE` pixels on its long side (6 to 64 px per cell),
    ``wall_width`` about a tenth of a cell, ``margin`` about a quarter of one.
    """

    #: ``"light"`` (black on white) or ``"dark"`` (light on near-black).
    theme: str = "light"
    #: Use colour-blind-safe marker colours (teal path, orange start, blue goal).
    colorblind: bool = False
    #: Draw the solution path from start to goal.
    solution: bool = False
    #: Draw the signs (clues, lures, traps) in their cells.
    signs: bool = True
    #: Outline each sign with a colour telling its kind (clue, lure or trap).
    sign_kinds: bool = False
    #: Fill the cells the agent can never reach (off the path of an intersection-free maze).
    unreachable: bool = True
    #: Colour the start and goal cells.
    markers: bool = True
    #: Pixels per cell (at least 4), or ``None`` for automatic.
    cell_size: int | None = None
    #: Wall thickness in pixels (at least 1, less than half a cell), or ``None`` for automatic.
    wall_width: int | None = None
    #: Empty border around the maze in pixels (at least the wall width), or ``None``.
    margin: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.theme, str) or self.theme not in THEMES:
            raise RenderError(f"unknown theme {self.theme!r} (expected one of {', '.join(THEMES)})")
        for name in ("colorblind", "solution", "signs", "sign_kinds", "unreachable", "markers"):
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise RenderError(f"option {name}={value!r} must be a bool")
        cell = self.cell_size
        if cell is not None:
            check_integer(
                "cell_size", cell, minimum=MIN_CELL_SIZE, maximum=MAX_CELL_SIZE, error=RenderError
            )
        wall = self.wall_width
        if wall is not None:
            check_integer("wall_width", wall, minimum=1, error=RenderError)
        if wall is not None and cell is not None and 2 * wall >= cell:
            raise RenderError(f"wall_width={wall!r} must be less than half of cell_size={cell!r}")
        if self.margin is not None:
            check_integer("margin", self.margin, minimum=0, error=RenderError)

    def with_overrides(self, **overrides: Any) -> RenderOptions:
        """A copy with some fields changed; an unknown field name raises ValueError."""
        names = {field.name for field in dataclasses.fields(self)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise RenderError(
                f"unknown render option(s) {', '.join(map(repr, unknown))}"
                f" (known: {', '.join(sorted(names))})"
            )
        return dataclasses.replace(self, **overrides) if overrides else self

    @property
    def colors(self) -> Palette:
        """The palette of these options."""
        return palette(self.theme, self.colorblind)


def _resolve_options(options: RenderOptions | None, overrides: dict[str, Any]) -> RenderOptions:
    if options is None:
        options = RenderOptions()
    elif not isinstance(options, RenderOptions):
        raise RenderError(f"options must be a RenderOptions, not {options!r}")
    return options.with_overrides(**overrides)


def auto_cell_size(width: int, height: int, target: int = TARGET_SIDE) -> int:
    """The default cell size for a ``width`` x ``height`` maze (see :class:`RenderOptions`)."""
    low, high = AUTO_CELL_RANGE
    return max(low, min(high, target // max(width, height)))


@dataclass(frozen=True)
class MazeLayout:
    """Where things land in a picture: cell ``(i, j)`` spans grid lines ``i..i+1``.

    Vertical grid line ``k`` is at ``x = margin + k * cell_size`` and horizontal
    line ``k`` (counted from the top) at ``y = margin + k * cell_size``; a wall
    is a ``wall_width`` thick band centred (rounding down) on its line.
    """

    width: int
    height: int
    cell_size: int
    wall_width: int
    margin: int

    @classmethod
    def of(cls, maze: Maze, options: RenderOptions | None = None) -> MazeLayout:
        """The layout that :func:`render_maze` uses for ``maze`` and ``options``."""
        options = options or RenderOptions()
        cell = options.cell_size or auto_cell_size(maze.width, maze.height)
        wall = options.wall_width or max(1, round(cell / 10))
        if 2 * wall >= cell:
            raise RenderError(f"wall_width={wall} must be less than half of cell_size={cell}")
        margin = options.margin if options.margin is not None else max(2 * wall, round(cell / 4))
        if margin < wall:
            raise RenderError(f"margin={margin} must be at least the wall width {wall}")
        layout = cls(maze.width, maze.height, cell, wall, margin)
        if max(layout.size) > MAX_SIDE:
            raise RenderError(
                f"cell_size={cell} makes a {layout.size[0]}x{layout.size[1]} px picture"
                f" (at most {MAX_SIDE} px a side)"
            )
        return layout

    @property
    def size(self) -> tuple[int, int]:
        """The picture's ``(width, height)`` in pixels."""
        return (
            self.width * self.cell_size + 2 * self.margin,
            self.height * self.cell_size + 2 * self.margin,
        )

    def line_x(self, k: int) -> int:
        """The x of vertical grid line ``k`` (0 = west border)."""
        return self.margin + k * self.cell_size

    def line_y(self, k: int) -> int:
        """The y of horizontal grid line ``k`` counted from the top (0 = north border)."""
        return self.margin + k * self.cell_size

    def cell_box(self, i: int, j: int) -> tuple[int, int, int, int]:
        """``(x0, y0, x1, y1)`` of cell ``(i, j)`` between its grid lines (x1, y1 excluded)."""
        row = self.height - 1 - j
        return self.line_x(i), self.line_y(row), self.line_x(i + 1), self.line_y(row + 1)

    def cell_interior(self, i: int, j: int) -> tuple[int, int, int, int]:
        """Inclusive ``(x0, y0, x1, y1)`` of the pixels of cell ``(i, j)`` inside its walls."""
        x0, y0, x1, y1 = self.cell_box(i, j)
        half = self.wall_width // 2
        inner = self.wall_width - half
        return x0 + inner, y0 + inner, x1 - half - 1, y1 - half - 1

    def cell_center(self, i: int, j: int) -> tuple[int, int]:
        """The pixel at the centre of cell ``(i, j)``."""
        x0, y0, _, _ = self.cell_box(i, j)
        return x0 + self.cell_size // 2, y0 + self.cell_size // 2

    def wall_box(self, i: int, j: int, side: int) -> tuple[int, int, int, int]:
        """Inclusive ``(x0, y0, x1, y1)`` of the wall on ``side`` (0=E, 1=N, 2=W, 3=S) of a cell."""
        x0, y0, x1, y1 = self.cell_box(i, j)
        half, w = self.wall_width // 2, self.wall_width
        if side in (0, 2):
            x = x1 if side == 0 else x0
            return x - half, y0 - half, x - half + w - 1, y1 - half + w - 1
        y = y0 if side == 1 else y1
        return x0 - half, y - half, x1 - half + w - 1, y - half + w - 1

    def edge_midpoint(self, i: int, j: int, side: int) -> tuple[int, int]:
        """A pixel in the middle of the wall band on ``side`` of cell ``(i, j)``."""
        x0, y0, x1, y1 = self.wall_box(i, j, side)
        return (x0 + x1) // 2, (y0 + y1) // 2

    def tile_box(self, i: int, j: int) -> tuple[int, int, int, int]:
        """Inclusive box of the sign tile of cell ``(i, j)``: the interior less a small gap."""
        x0, y0, x1, y1 = self.cell_interior(i, j)
        gap = self.tile_gap
        return x0 + gap, y0 + gap, x1 - gap, y1 - gap

    @property
    def tile_gap(self) -> int:
        """Space left between the walls and a sign tile (it holds the kind outline)."""
        inner = self.cell_size - self.wall_width
        return max(1, round(inner / 12)) if inner >= 6 else 0

    @property
    def path_width(self) -> int:
        """Thickness of the solution path."""
        return max(2, round(self.cell_size / 6))


def unreachable_cells(maze: Maze) -> np.ndarray:
    """Bool ``(width, height)``: cells off the solution of an intersection-free maze.

    In such a maze (all unicursive ones) every side branch of the path is walled
    off, so no agent ever enters these cells; the reference viewer fills them in.
    """
    mask = np.zeros((maze.width, maze.height), dtype=bool)
    if maze.unicursive:
        mask[:] = True
        for cell in maze.solution:
            mask[cell] = False
    return mask


def render_maze(
    maze: Maze | str, options: RenderOptions | None = None, **overrides: Any
) -> Image.Image:
    """Draw ``maze`` (a :class:`~amaze.maze.maze.Maze` or a maze string) as an RGB image.

    Keyword arguments override fields of ``options`` (``render_maze(m, theme="dark")``).
    Bad options raise :class:`RenderError` (a ``ValueError``) naming the value.
    """
    maze = as_maze(maze)
    options = _resolve_options(options, overrides)
    layout = MazeLayout.of(maze, options)
    colors = options.colors
    image = Image.new("RGB", layout.size, colors.background)
    draw = ImageDraw.Draw(image)
    blocked = unreachable_cells(maze) if options.unreachable else None

    if blocked is not None:
        for i, j in np.argwhere(blocked):
            x0, y0, x1, y1 = layout.cell_box(int(i), int(j))
            draw.rectangle((x0, y0, x1 - 1, y1 - 1), fill=colors.unreachable)

    if options.markers:
        for cell, color in ((maze.start, colors.start), (maze.end, colors.goal)):
            draw.rectangle(layout.cell_interior(*cell), fill=color)

    if options.solution:
        _draw_path(draw, layout, maze.solution, colors.path)

    if options.signs or options.sign_kinds:
        _draw_signs(image, draw, layout, maze, options, colors)

    _draw_walls(draw, layout, maze, blocked, colors.wall)
    return image


def _draw_path(
    draw: ImageDraw.ImageDraw, layout: MazeLayout, cells: Sequence[tuple[int, int]], color: Color
) -> None:
    """The solution as axis-aligned bands between cell centres (square joints, sharp edges)."""
    width = layout.path_width
    lo = width // 2
    hi = width - lo - 1
    points = [layout.cell_center(*cell) for cell in cells]
    if len(points) == 1:
        x, y = points[0]
        draw.rectangle((x - lo, y - lo, x + hi, y + hi), fill=color)
    for (xa, ya), (xb, yb) in itertools.pairwise(points):
        x0, x1 = sorted((xa, xb))
        y0, y1 = sorted((ya, yb))
        draw.rectangle((x0 - lo, y0 - lo, x1 + hi, y1 + hi), fill=color)


def _draw_walls(
    draw: ImageDraw.ImageDraw,
    layout: MazeLayout,
    maze: Maze,
    blocked: np.ndarray | None,
    color: Color,
) -> None:
    """Every wall, except those between two unreachable cells (inside a filled block)."""
    walls = maze.walls
    w, h = maze.width, maze.height
    for i in range(w):
        for j in range(h):
            for side in range(4):
                if not walls[i, j, side]:
                    continue
                if side in (0, 1):  # east and north walls are also the neighbour's
                    ni, nj = (i + 1, j) if side == 0 else (i, j + 1)
                    inside = ni < w and nj < h
                    if inside and blocked is not None and blocked[i, j] and blocked[ni, nj]:
                        continue
                    draw.rectangle(layout.wall_box(i, j, side), fill=color)
                elif (side == 2 and i == 0) or (side == 3 and j == 0):  # the outer border
                    draw.rectangle(layout.wall_box(i, j, side), fill=color)


def _draw_signs(
    image: Image.Image,
    draw: ImageDraw.ImageDraw,
    layout: MazeLayout,
    maze: Maze,
    options: RenderOptions,
    colors: Palette,
) -> None:
    """Sign tiles, and their kind outlines in the gap between the walls and the tile.

    On the start cell (the only marked cell a sign can occupy) the outline is
    drawn one gap further in, so the start colour still frames the cell.
    """
    gap = layout.tile_gap
    marked = {maze.start, maze.end} if options.markers else set()
    for placed in maze.signs:
        i, j = placed.cell
        x0, y0, x1, y1 = layout.tile_box(i, j)
        if options.sign_kinds and gap > 0:
            if placed.cell in marked:
                x0, y0, x1, y1 = x0 + gap, y0 + gap, x1 - gap, y1 - gap
            draw.rectangle(
                (x0 - gap, y0 - gap, x1 + gap, y1 + gap), fill=colors.kind_color(placed.kind)
            )
        if not options.signs:
            continue
        size = min(x1 - x0, y1 - y0) + 1
        if size < 1:
            continue
        draw.rectangle((x0, y0, x1, y1), fill=SIGN_TILE)
        if size >= 3:
            tile = _sign_tile(placed.sign, int(placed.direction), size, _image_version(placed.sign))
            image.paste(tile.convert("RGB"), (x0, y0))


def _image_version(sign: Sign) -> int:
    """The modification time of a custom sign's file (0 for built-ins), so edits show."""
    path = custom_sign_path(sign.shape)
    try:
        return path.stat().st_mtime_ns if path is not None else 0
    except OSError:
        return -1


@lru_cache(maxsize=256)
def _sign_tile(sign: Sign, direction: int, size: int, version: int) -> Image.Image:
    """The gray ``size`` x ``size`` picture of ``sign`` pointing ``direction`` (antialiased).

    ``version`` only keys the cache (see :func:`_image_version`).
    """
    from amaze.maze.sign_images import sign_frames

    factor = _SIGN_SUPERSAMPLING
    frames = np.asarray(sign_frames(sign, size * factor), dtype=np.float64)
    frame = np.clip(frames[direction], 0.0, 1.0)
    big = Image.fromarray(np.round(frame * 255.0).astype(np.uint8), mode="L")
    return big.reduce(factor)


def save_maze_png(
    maze: Maze | str,
    path: str | os.PathLike,
    options: RenderOptions | None = None,
    **overrides: Any,
) -> Path:
    """Render ``maze`` and write it as a PNG file at ``path`` (folders are created)."""
    image = render_maze(maze, options, **overrides)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path, format="PNG")
    return path


def save_picture(picture: Any, path: str | os.PathLike) -> Path:
    """Write a PIL image or a matplotlib figure to ``path`` as PNG, atomically.

    The picture goes to a temporary file beside ``path`` first, then replaces
    it, so a run killed while drawing never leaves a truncated picture.
    Folders are created.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    if hasattr(picture, "savefig"):
        picture.savefig(tmp, format="png")
    else:
        picture.save(tmp, format="PNG")
    os.replace(tmp, path)
    return path


# -- grids of mazes -------------------------------------------------------------------

#: Automatic cell sizes of grids aim at tiles of about this many pixels.
GRID_TARGET_SIDE = 300


def render_mazes_grid(
    mazes: Sequence[Maze | str],
    columns: int | None = None,
    labels: bool | Sequence[str] = True,
    options: RenderOptions | None = None,
    **overrides: Any,
) -> Image.Image:
    """Tile several mazes in rows of ``columns`` (default: a near-square grid).

    ``labels`` is True (each maze's canonical string as a small caption below it),
    False (no captions) or one caption per maze. Without an explicit
    ``cell_size`` every maze is drawn with the same one, chosen so the largest
    maze is about :data:`GRID_TARGET_SIDE` px, so sizes compare at a glance.
    """
    mazes = [as_maze(maze) for maze in mazes]
    if not mazes:
        raise RenderError("render_mazes_grid needs at least one maze")
    if columns is None:
        columns = int(np.ceil(np.sqrt(len(mazes))))
    columns = check_integer("columns", columns, minimum=1, error=RenderError)
    if labels is True:
        captions: list[str] | None = [maze.to_string() for maze in mazes]
    elif labels is False or labels is None:
        captions = None
    else:
        captions = [str(label) for label in labels]
        if len(captions) != len(mazes):
            raise RenderError(f"{len(captions)} labels for {len(mazes)} mazes")
    options = _resolve_options(options, overrides)
    if options.cell_size is None:
        side = max(max(maze.width, maze.height) for maze in mazes)
        options = options.with_overrides(
            cell_size=max(MIN_CELL_SIZE, min(32, GRID_TARGET_SIDE // side))
        )
    pictures = [render_maze(maze, options) for maze in mazes]
    colors = options.colors
    n_rows = -(-len(mazes) // columns)
    n_cols = min(columns, len(mazes))
    slots = [divmod(index, columns) for index in range(len(mazes))]
    col_w = [
        max(p.width for p, (_, c) in zip(pictures, slots, strict=True) if c == col)
        for col in range(n_cols)
    ]
    row_h = [
        max(p.height for p, (r, _) in zip(pictures, slots, strict=True) if r == row)
        for row in range(n_rows)
    ]
    pad = 8
    font = load_font(max(10, min(14, min(col_w) // 16)))
    line_h = _text_height(font) + 2
    lines = (
        [_wrap(text, font, col_w[col]) for text, (_, col) in zip(captions, slots, strict=True)]
        if captions
        else [[] for _ in mazes]
    )
    caption_h = [
        max(len(ls) for ls, (r, _) in zip(lines, slots, strict=True) if r == row) * line_h
        for row in range(n_rows)
    ]
    xs = list(itertools.accumulate((w + pad for w in col_w), initial=pad))
    ys = list(
        itertools.accumulate(
            (h + c + pad for h, c in zip(row_h, caption_h, strict=True)), initial=pad
        )
    )
    grid = Image.new("RGB", (xs[-1], ys[-1]), colors.background)
    draw = ImageDraw.Draw(grid)
    for picture, caption, (row, col) in zip(pictures, lines, slots, strict=True):
        left, top, width = xs[col], ys[row], col_w[col]
        # Bottom-aligned, so the captions of a row share a baseline.
        grid.paste(
            picture, (left + (width - picture.width) // 2, top + row_h[row] - picture.height)
        )
        y = top + row_h[row]
        for line in caption:
            text_w = draw.textlength(line, font=font)
            draw.text((left + (width - text_w) / 2, y), line, fill=colors.text, font=font)
            y += line_h
    return grid


def load_font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    """DejaVu Sans at ``size`` px: the one font of every picture the package draws.

    Mazes, trajectories, input recognition, curricula: captions look alike
    everywhere, and R̄ (an R and a combining macron, which Pillow's own font
    lacks) is drawn as R̄. The font file is the one matplotlib ships (a
    dependency; it is found without importing matplotlib); without it,
    Pillow's default font (its bitmap font where FreeType is missing).
    """
    path = _dejavu_sans()
    try:
        if path is not None:
            return ImageFont.truetype(str(path), size=size)
        return ImageFont.load_default(size=size)
    except (TypeError, ImportError, OSError):  # pragma: no cover - Pillow without FreeType
        return ImageFont.load_default()


@functools.cache
def _dejavu_sans() -> Path | None:
    """matplotlib's DejaVu Sans, if installed."""
    spec = importlib.util.find_spec("matplotlib")
    if spec is None or spec.origin is None:
        return None
    path = Path(spec.origin).parent / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf"
    return path if path.is_file() else None


def _text_height(font: Any) -> int:
    return int(font.getbbox("Mg_0")[3])


def _wrap(text: str, font: Any, width: int) -> list[str]:
    """Split ``text`` at underscores (kept at line ends) so each line fits in ``width`` px."""
    parts = text.split("_")
    lines: list[str] = []
    current = ""
    for k, part in enumerate(parts):
        piece = part + ("_" if k < len(parts) - 1 else "")
        if current and font.getlength(current + piece) > width:
            lines.append(current)
            current = piece
        else:
            current += piece
    lines.append(current)
    return lines
