"""PNG rendering: geometry, colours, signs and option checking of amaze.maze.render.

Pixel positions are computed here from the documented layout (grid line ``k``
at ``margin + k * cell_size``, north up) rather than taken from the module, so
a wrong orientation or offset in the renderer makes these tests fail.
"""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from amaze.maze.maze import Maze
from amaze.maze.render import (
    MazeLayout,
    RenderOptions,
    palette,
    render_maze,
    render_mazes_grid,
    save_maze_png,
    unreachable_cells,
)
from amaze.maze.signs import SignKind

CELL, WALL, MARGIN = 20, 3, 5
FIXED = {"cell_size": CELL, "wall_width": WALL, "margin": MARGIN}

WHITE, BLACK = (255, 255, 255), (0, 0, 0)
CB_PATH, CB_START, CB_GOAL = (0x02, 0x9E, 0x73), (0xDE, 0x8F, 0x05), (0x01, 0x73, 0xB2)


def pixels(image: Image.Image) -> np.ndarray:
    """The picture as an ``(height, width, 3)`` uint8 array (row 0 = top)."""
    assert image.mode == "RGB"
    return np.asarray(image)


def centre(maze: Maze, cell: tuple[int, int], size: int = CELL) -> tuple[int, int]:
    """``(x, y)`` of the centre of a cell of ``size`` pixels, north up."""
    i, j = cell
    return MARGIN + i * size + size // 2, MARGIN + (maze.height - 1 - j) * size + size // 2


def edge_pixel(maze: Maze, cell: tuple[int, int], side: int) -> tuple[int, int]:
    """``(x, y)`` of the middle of the grid line on ``side`` (E, N, W, S) of a cell."""
    i, j = cell
    row = maze.height - 1 - j
    x_mid = MARGIN + i * CELL + CELL // 2
    y_mid = MARGIN + row * CELL + CELL // 2
    return {
        0: (MARGIN + (i + 1) * CELL, y_mid),
        1: (x_mid, MARGIN + row * CELL),
        2: (MARGIN + i * CELL, y_mid),
        3: (x_mid, MARGIN + (row + 1) * CELL),
    }[side]


def color_at(array: np.ndarray, xy: tuple[int, int]) -> tuple[int, ...]:
    x, y = xy
    return tuple(int(v) for v in array[y, x])


# -- geometry --------------------------------------------------------------------------


@pytest.mark.parametrize(("text", "cell"), [("M1_7x5", 20), ("M2_2x2", 4), ("M3_3x9", 33)])
def test_image_size_follows_cell_size_and_maze_size(text: str, cell: int) -> None:
    maze = Maze.from_string(text)
    image = render_maze(maze, cell_size=cell, wall_width=1, margin=6)
    assert image.size == (maze.width * cell + 12, maze.height * cell + 12)
    assert MazeLayout.of(maze, RenderOptions(cell_size=cell, wall_width=1, margin=6)).size == (
        image.size
    )


@pytest.mark.parametrize("text", ["M1_2x2", "M1_10x10", "M1_5x10_U", "M1_37x12", "M1_100x100"])
def test_default_size_is_sensible(text: str) -> None:
    maze = Maze.from_string(text)
    width, height = render_maze(maze).size
    assert max(width, height) <= 900
    if max(maze.width, maze.height) >= 10:
        assert max(width, height) >= 600
    assert width / height == pytest.approx(maze.width / maze.height, rel=0.1)


@pytest.mark.parametrize("text", ["M4_6x5", "M11_4x7_SE", "M5_9x3_NW_R"])
def test_wall_pixels_match_the_walls_north_up(text: str) -> None:
    maze = Maze.from_string(text)
    colors = palette("light")
    array = pixels(render_maze(maze, markers=False, **FIXED))
    observed = np.zeros_like(maze.walls)
    for i in range(maze.width):
        for j in range(maze.height):
            for side in range(4):
                color = color_at(array, edge_pixel(maze, (i, j), side))
                assert color in (colors.wall, colors.background), (i, j, side, color)
                observed[i, j, side] = color == colors.wall
    np.testing.assert_array_equal(observed, maze.walls)
    # The check discriminates: the picture is not also consistent with south up.
    assert not np.array_equal(observed[:, ::-1][..., [0, 3, 2, 1]], maze.walls)


def test_layout_helpers_agree_with_the_documented_geometry() -> None:
    maze = Maze.from_string("M4_6x5")
    layout = MazeLayout.of(maze, RenderOptions(**FIXED))
    for cell in [(0, 0), (5, 4), (2, 3)]:
        assert layout.cell_center(*cell) == centre(maze, cell)
        for side in range(4):
            x0, y0, x1, y1 = layout.wall_box(*cell, side)
            x, y = edge_pixel(maze, cell, side)
            assert x0 <= x <= x1 and y0 <= y <= y1
            assert min(x1 - x0, y1 - y0) + 1 == WALL


# -- colours and markers ----------------------------------------------------------------


@pytest.mark.parametrize("colorblind", [False, True])
def test_start_and_goal_colours_at_their_cells(colorblind: bool) -> None:
    maze = Maze.from_string("M4_6x5")
    colors = palette("light", colorblind)
    array = pixels(render_maze(maze, colorblind=colorblind, **FIXED))
    assert color_at(array, centre(maze, maze.start)) == colors.start
    assert color_at(array, centre(maze, maze.end)) == colors.goal
    assert colors.start != colors.goal
    if colorblind:
        assert (colors.start, colors.goal) == (CB_START, CB_GOAL)
    else:
        assert colors.start[0] > 150 > colors.start[1]  # red
        assert colors.goal[1] > 120 > colors.goal[0]  # green
    plain = pixels(render_maze(maze, markers=False, **FIXED))
    assert color_at(plain, centre(maze, maze.start)) == colors.background


def luminance(color: tuple[int, ...]) -> float:
    r, g, b = color[:3]
    return 0.299 * r + 0.587 * g + 0.114 * b


def test_themes_light_and_dark() -> None:
    maze = Maze.from_string("M4_6x5")
    light = pixels(render_maze(maze, theme="light", **FIXED))
    dark = pixels(render_maze(maze, theme="dark", **FIXED))
    assert luminance(color_at(light, (1, 1))) > 200
    assert luminance(color_at(dark, (1, 1))) < 60
    # The outer west wall: dark on light, light on dark.
    west = edge_pixel(maze, (0, 2), 2)
    assert luminance(color_at(light, west)) < 60
    assert luminance(color_at(dark, west)) > 200
    # Most of a picture is background.
    assert light.mean() > 180 > 100 > dark.mean()


def path_midpoints(maze: Maze) -> list[tuple[int, int]]:
    """Pixels half-way between the centres of consecutive solution cells."""
    points = []
    for a, b in zip(maze.solution, maze.solution[1:], strict=False):
        (xa, ya), (xb, yb) = centre(maze, a), centre(maze, b)
        points.append(((xa + xb) // 2, (ya + yb) // 2))
    return points


def test_solution_is_drawn_only_when_asked() -> None:
    maze = Maze.from_string("M4_6x5")
    colors = palette("light")
    without = pixels(render_maze(maze, **FIXED))
    with_path = pixels(render_maze(maze, solution=True, **FIXED))
    assert not np.all(without == colors.path, axis=-1).any()
    on_path = np.all(with_path == colors.path, axis=-1)
    # Roughly one band of path per step between cells.
    width = MazeLayout.of(maze, RenderOptions(**FIXED)).path_width
    assert on_path.sum() >= (len(maze.solution) - 1) * CELL * width * 0.8
    for point in path_midpoints(maze):
        assert color_at(with_path, point) == colors.path, point
    # A cell far from the path keeps the background colour.
    off = [
        (i, j) for i in range(maze.width) for j in range(maze.height) if (i, j) not in maze.solution
    ]
    assert off, "the test maze must have cells off the solution"
    assert color_at(with_path, centre(maze, off[0])) == colors.background


def test_colorblind_changes_the_path_colour() -> None:
    maze = Maze.from_string("M4_6x5")
    point = path_midpoints(maze)[0]
    normal = color_at(pixels(render_maze(maze, solution=True, **FIXED)), point)
    safe = color_at(pixels(render_maze(maze, solution=True, colorblind=True, **FIXED)), point)
    assert normal != safe
    assert safe == CB_PATH
    dark_safe = render_maze(maze, solution=True, colorblind=True, theme="dark", **FIXED)
    assert color_at(pixels(dark_safe), point) == CB_PATH


def test_unreachable_cells_of_unicursive_mazes_are_filled() -> None:
    maze = Maze.from_string("M16_5x10_U")
    assert maze.unicursive
    mask = unreachable_cells(maze)
    assert mask.sum() == maze.width * maze.height - len(maze.solution) > 0
    colors = palette("light")
    array = pixels(render_maze(maze, **FIXED))
    for i in range(maze.width):
        for j in range(maze.height):
            color = color_at(array, centre(maze, (i, j)))
            if mask[i, j]:
                assert color == colors.unreachable, (i, j)
            elif (i, j) not in (maze.start, maze.end):
                assert color == colors.background, (i, j)
    unfilled = pixels(render_maze(maze, unreachable=False, **FIXED))
    assert not np.all(unfilled == colors.unreachable, axis=-1).any()
    # Mazes with intersections have no unreachable cell.
    assert not unreachable_cells(Maze.from_string("M4_10x10_C1")).any()


# -- signs -------------------------------------------------------------------------------


def tile(array: np.ndarray, maze: Maze, cell: tuple[int, int], size: int) -> np.ndarray:
    """The central pixels of a cell of ``size`` pixels, inside the walls and the tile gap."""
    x, y = centre(maze, cell, size)
    half = size // 2 - 2 * WALL
    return array[y - half : y + half, x - half : x + half].astype(int)


def test_sign_pixels_appear_in_their_cell_pointing_their_way() -> None:
    maze = Maze.from_string("M4_10x10_C1_l.25_L.25_t.5_T.5")
    kinds = {placed.kind for placed in maze.signs}
    assert kinds == {SignKind.CLUE, SignKind.LURE, SignKind.TRAP}
    size = 40
    array = pixels(render_maze(maze, markers=False, cell_size=size, wall_width=WALL, margin=MARGIN))
    for placed in maze.signs:
        region = tile(array, maze, placed.cell, size)
        gray = region[..., 0]
        assert (gray == region[..., 1]).all() and (gray == region[..., 2]).all()
        level = round(255 * placed.sign.value)
        # The black tile and the sign at its full gray level (the lightness an agent sees).
        assert (gray == 0).mean() > 0.3, placed
        assert abs(gray.max() - level) <= 1, placed
        # An arrow's head is its widest part: it lies in the half the arrow points to.
        mask = gray > level // 2
        across = mask.sum(axis=0 if placed.direction in (0, 2) else 1)  # per column / row
        half = len(across) // 2
        low, high = across[:half].max(), across[-half:].max()  # west / north, east / south
        forward, backward = (high, low) if placed.direction in (0, 3) else (low, high)
        assert forward > 1.5 * backward, (placed, across)
    signed = {placed.cell for placed in maze.signs}
    empty = next(
        (i, j) for i in range(maze.width) for j in range(maze.height) if (i, j) not in signed
    )
    assert (tile(array, maze, empty, size) == 255).all()


def test_signs_can_be_hidden_and_kinds_outlined() -> None:
    maze = Maze.from_string("M4_10x10_C1_l.25_L.25_t.5_T.5")
    options = RenderOptions(markers=False, **FIXED)
    layout = MazeLayout.of(maze, options)
    hidden = pixels(render_maze(maze, options, signs=False))
    plain = pixels(render_maze(maze, options))
    outlined = pixels(render_maze(maze, options, sign_kinds=True))
    colors = palette("light")
    for placed in maze.signs:
        x, y = layout.cell_center(*placed.cell)
        assert color_at(hidden, (x, y)) == colors.background
        x0, _, _, _ = layout.cell_interior(*placed.cell)
        gap_pixel = (x0 + layout.tile_gap // 2, y)
        assert color_at(plain, gap_pixel) == colors.background
        assert color_at(outlined, gap_pixel) == colors.kind_color(placed.kind), placed
    assert len({colors.clue, colors.lure, colors.trap}) == 3


def test_a_sign_on_the_start_cell_keeps_the_start_colour_visible() -> None:
    maze = Maze.from_string("M4_10x10_C1_l.25_L.25_t.5_T.5")
    assert maze.start in {placed.cell for placed in maze.signs}
    options = RenderOptions(sign_kinds=True, cell_size=40, wall_width=3, margin=5)
    layout = MazeLayout.of(maze, options)
    array = pixels(render_maze(maze, options))
    x0, y0, _, y1 = layout.cell_interior(*maze.start)
    assert color_at(array, (x0, (y0 + y1) // 2)) == palette("light").start
    assert color_at(array, (x0 + layout.tile_gap, (y0 + y1) // 2)) == palette("light").lure


# -- files, strings, grids ---------------------------------------------------------------


def test_save_png_and_reopen(tmp_path) -> None:
    maze = Maze.from_string("M20000018_20x20_C1_l.25_L.25_t.5_T.5")
    path = save_maze_png(maze, tmp_path / "sub" / "maze.png", solution=True, theme="dark")
    assert path.exists() and path.suffix == ".png"
    with Image.open(path) as reopened:
        assert reopened.format == "PNG"
        np.testing.assert_array_equal(
            np.asarray(reopened.convert("RGB")),
            pixels(render_maze(maze, solution=True, theme="dark")),
        )


def test_maze_strings_and_options_objects_are_accepted() -> None:
    text = "M4_6x5"
    options = RenderOptions(theme="dark", **FIXED)
    a = pixels(render_maze(text, options))
    b = pixels(render_maze(Maze.from_string(text), theme="dark", **FIXED))
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("text", ["M0_2x2", "M9_2x100_U", "M3_100x100_C1_l.2_L.5_t.5_T.25"])
def test_extreme_sizes_render(text: str) -> None:
    maze = Maze.from_string(text)
    for cell in (4, None):
        image = render_maze(maze, cell_size=cell, solution=True, sign_kinds=True)
        assert min(image.size) > 2 * maze.width or maze.width == 2


def test_grid_tiles_mazes_with_captions() -> None:
    mazes = [Maze.from_string(s) for s in ("M1_5x5", "M2_5x5_U", "M3_8x4_C1")]
    one_row = render_mazes_grid(mazes, columns=3, labels=False, cell_size=10)
    one_col = render_mazes_grid(mazes, columns=1, labels=False, cell_size=10)
    assert one_row.width > one_col.width and one_row.height < one_col.height
    captioned = render_mazes_grid(mazes, columns=3, cell_size=10)
    assert captioned.height > one_row.height and captioned.width == one_row.width
    # Captions add text pixels below the mazes only.
    cap = pixels(captioned)[one_row.height - 8 :]
    assert (cap.min(axis=-1) < 128).any()
    custom = render_mazes_grid(mazes, columns=2, labels=["a", "b", "c"], theme="dark")
    assert luminance(custom.getpixel((1, 1))) < 60
    with pytest.raises(ValueError, match="2 labels for 3 mazes"):
        render_mazes_grid(mazes, columns=2, labels=["a", "b"])
    with pytest.raises(ValueError, match="columns 0"):
        render_mazes_grid(mazes, columns=0)
    with pytest.raises(ValueError, match="at least one maze"):
        render_mazes_grid([], columns=2)


# -- bad options -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("overrides", "named"),
    [
        ({"theme": "blue"}, "'blue'"),
        ({"cell_size": 3}, "cell_size 3"),
        ({"cell_size": 2.5}, "cell_size 2.5"),
        ({"cell_size": True}, "cell_size True"),
        ({"wall_width": 0}, "wall_width 0"),
        ({"cell_size": 10, "wall_width": 5}, "wall_width=5"),
        ({"margin": -1}, "margin -1"),
        ({"cell_size": 10, "wall_width": 4, "margin": 2}, "margin=2"),
        ({"solution": "yes"}, "solution='yes'"),
        ({"colour": "red"}, "'colour'"),
    ],
)
def test_bad_options_raise_value_error_naming_the_value(overrides: dict, named: str) -> None:
    maze = Maze.from_string("M4_6x5")
    with pytest.raises(ValueError) as error:
        render_maze(maze, **overrides)
    assert named in str(error.value)


def test_bad_arguments_raise_value_error() -> None:
    with pytest.raises(ValueError, match="'dark-ish'"):
        RenderOptions(theme="dark-ish")
    with pytest.raises(ValueError, match="RenderOptions"):
        render_maze("M4_6x5", {"theme": "dark"})  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="Maze or a maze string"):
        render_maze(42)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="'sepia'"):
        palette("sepia")
    with pytest.raises(ValueError, match="cell_size=200"):
        render_maze("M1_100x100", cell_size=200)
