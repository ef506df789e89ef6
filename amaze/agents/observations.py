"""What an agent perceives in a cell: the readable definitions (reference §5).

* Discrete inputs: 8 floats ``[W_e, W_n, W_w, W_s, S_e, S_n, S_w, S_s]``, wall
  slots 1/0 with the side the agent arrived from set to 0.5, and the sign's
  lightness in the slot of the direction it points to (0 elsewhere). Signs of
  every kind look alike except for their lightness.
* Image inputs (hybrid and continuous robots): a ``v x v`` float image, row 0 =
  north, column 0 = west; the border shows the walls (1), corners are lit when
  either of their walls is, the interior holds the sign image (the sign shape
  pointing its direction, at its lightness quantised to 8 bits), and the pixel
  in the middle of the border on the arrival side is 1.
* Continuous robots see a ``v x v`` window that follows their position inside
  the cell, cut from the ``3v x 3v`` picture of the cell and its neighbours
  (cells outside the maze are black; only the robot's own cell shows the
  arrival pixel).

Two layers: :func:`discrete_input` and :func:`draw_cell` build an input from
the content of a cell given directly (its walls, arrival side and sign), so
that inputs can be synthesised without a maze (the input-recognition test,
:mod:`amaze.evaluation.inputs`, enumerates them that way); :func:`discrete_observation`,
:func:`cell_image` and :func:`continuous_observation` read that content from a
maze. These functions are the definition; the batch engine reproduces them
from precomputed tables and is cross-checked against them in the tests.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from amaze.agents.robot import MIN_VISION
from amaze.errors import AmazeError
from amaze.maze.maze import Maze
from amaze.maze.sign_images import sign_frames
from amaze.maze.signs import Sign
from amaze.validation import check_integer, check_number

__all__ = [
    "ObservationError",
    "cell_image",
    "continuous_observation",
    "discrete_input",
    "discrete_observation",
    "draw_cell",
]


class ObservationError(AmazeError):
    """A cell description given to an input builder is invalid (the message names the value)."""


# -- inputs from the content of a cell ------------------------------------------------


def discrete_input(
    walls: Sequence[int] | np.ndarray,
    arrival: int | None = None,
    sign_value: float | None = None,
    sign_direction: int | None = None,
) -> np.ndarray:
    """The 8-float discrete input of a cell described by its content.

    ``walls`` gives the four sides E, N, W, S (1 = wall, 0 = open); ``arrival``
    is the open side the agent came from (``None`` on the first step);
    ``sign_value`` and ``sign_direction`` describe the sign in the cell, if any
    (both or neither). A sign may point anywhere, walls included (lures do).

    :raises ObservationError: naming the bad value.
    """
    wall_array = _check_walls(walls)
    arrival = _check_side("arrival", arrival)
    if arrival is not None and wall_array[arrival]:
        raise ObservationError(f"arrival side {arrival} is walled in walls {_wall_code(walls)}")
    if (sign_value is None) != (sign_direction is None):
        raise ObservationError(
            f"sign_value={sign_value!r} and sign_direction={sign_direction!r}: give both or neither"
        )
    if sign_value is not None:
        check_number(
            "sign_value",
            sign_value,
            minimum=0,
            strict_minimum=True,
            maximum=1,
            error=ObservationError,
        )
    sign_direction = _check_side("sign_direction", sign_direction)
    return _discrete_input(wall_array, arrival, sign_value, sign_direction)


def draw_cell(
    walls: Sequence[int] | np.ndarray,
    vision: int,
    arrival: int | None = None,
    sign: Sign | None = None,
    sign_direction: int | None = None,
) -> np.ndarray:
    """The ``vision x vision`` float32 image of a cell described by its content (§5.2).

    Arguments as in :func:`discrete_input`, except that the sign is a
    :class:`~amaze.maze.signs.Sign` (its shape is drawn, at its lightness).
    ``vision`` is odd and at least 5 (the sign image needs 3 pixels).

    :raises ObservationError: naming the bad value.
    """
    wall_array = _check_walls(walls)
    check_integer("vision", vision, minimum=MIN_VISION, error=ObservationError)
    if vision % 2 != 1:
        raise ObservationError(f"vision {vision!r} must be an odd integer of at least {MIN_VISION}")
    arrival = _check_side("arrival", arrival)
    if arrival is not None and wall_array[arrival]:
        raise ObservationError(f"arrival side {arrival} is walled in walls {_wall_code(walls)}")
    if (sign is None) != (sign_direction is None):
        raise ObservationError(
            f"sign={sign!r} and sign_direction={sign_direction!r}: give both or neither"
        )
    if sign is not None and not isinstance(sign, Sign):
        raise ObservationError(f"sign {sign!r} is not a Sign")
    sign_direction = _check_side("sign_direction", sign_direction)
    return _draw_cell(wall_array, int(vision), arrival, sign, sign_direction)


def _discrete_input(
    walls: np.ndarray,
    arrival: int | None,
    sign_value: float | None,
    sign_direction: int | None,
) -> np.ndarray:
    obs = np.zeros(8, dtype=np.float32)
    obs[:4] = walls
    if arrival is not None:
        obs[arrival] = 0.5
    if sign_direction is not None:
        obs[4 + sign_direction] = sign_value
    return obs


def _draw_cell(
    walls: np.ndarray,
    vision: int,
    arrival: int | None,
    sign: Sign | None,
    sign_direction: int | None,
) -> np.ndarray:
    east, north, west, south = (float(w) for w in walls)
    image = np.zeros((vision, vision), dtype=np.float32)
    image[:, -1] = east
    image[0, :] = north
    image[:, 0] = west
    image[-1, :] = south
    image[0, -1] = max(north, east)
    image[0, 0] = max(north, west)
    image[-1, -1] = max(south, east)
    image[-1, 0] = max(south, west)
    if sign is not None:
        image[1:-1, 1:-1] = sign_frames(sign, vision - 2)[sign_direction]
    if arrival is not None:
        middle = vision // 2
        image[[(middle, -1), (0, middle), (middle, 0), (-1, middle)][arrival]] = 1.0
    return image


def _check_walls(walls: object) -> np.ndarray:
    try:
        array = np.asarray(walls)
    except (TypeError, ValueError):
        array = None
    if (
        array is None
        or array.shape != (4,)
        or not (np.issubdtype(array.dtype, np.integer) or array.dtype == bool)
        or not np.isin(array, (0, 1)).all()
    ):
        raise ObservationError(f"walls {walls!r} must be four 0/1 values (E, N, W, S)")
    return array.astype(np.uint8)


def _check_side(name: str, side: object) -> int | None:
    if side is None:
        return None
    direction = check_integer(name, side, error=ObservationError)
    if not 0 <= direction <= 3:
        raise ObservationError(f"{name} {side!r} is not a direction 0..3 (E, N, W, S) or None")
    return direction


def _wall_code(walls: Sequence[int] | np.ndarray) -> str:
    return "".join(str(int(w)) for w in np.asarray(walls).reshape(-1))


# -- inputs read from a maze ----------------------------------------------------------


def discrete_observation(maze: Maze, cell: tuple[int, int], arrival: int | None) -> np.ndarray:
    """The 8-float input in ``cell``; ``arrival`` is the side the agent came from."""
    i, j = cell
    direction = int(maze.cell_signs.direction[i, j])
    if direction < 0:
        return _discrete_input(maze.walls[i, j], arrival, None, None)
    return _discrete_input(maze.walls[i, j], arrival, maze.cell_signs.value[i, j], direction)


def cell_image(
    maze: Maze, cell: tuple[int, int], vision: int, arrival: int | None = None
) -> np.ndarray:
    """The ``vision x vision`` float32 image of ``cell`` (reference §5.2)."""
    placed = maze.sign_at(tuple(cell))
    if placed is None:
        return _draw_cell(maze.walls[cell[0], cell[1]], vision, arrival, None, None)
    return _draw_cell(
        maze.walls[cell[0], cell[1]], vision, arrival, placed.sign, int(placed.direction)
    )


def continuous_observation(
    maze: Maze, position: tuple[float, float], vision: int, arrival: int | None
) -> np.ndarray:
    """The window seen by a continuous robot at ``position`` (reference §5.3)."""
    x, y = position
    i, j = int(x), int(y)
    dpx = int((x - i - 0.5) * vision)
    dpy = int((y - j - 0.5) * vision)
    if dpx == 0 and dpy == 0:
        return cell_image(maze, (i, j), vision, arrival)
    v = vision
    buffer = np.zeros((3 * v, 3 * v), dtype=np.float32)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            ci, cj = i + di, j + dj
            if 0 <= ci < maze.width and 0 <= cj < maze.height:
                own = arrival if di == 0 and dj == 0 else None
                rows = slice((1 - dj) * v, (2 - dj) * v)
                cols = slice((di + 1) * v, (di + 2) * v)
                buffer[rows, cols] = cell_image(maze, (ci, cj), v, own)
    return buffer[v - dpy : 2 * v - dpy, v + dpx : 2 * v + dpx].copy()
