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

These functions are the definition; the batch engine reproduces them from
precomputed tables and is cross-checked against them in the tests.
"""

from __future__ import annotations

import numpy as np

from amaze.maze import Maze
from amaze.sign_images import sign_frames


def discrete_observation(maze: Maze, cell: tuple[int, int], arrival: int | None) -> np.ndarray:
    """The 8-float input in ``cell``; ``arrival`` is the side the agent came from."""
    i, j = cell
    obs = np.zeros(8, dtype=np.float32)
    obs[:4] = maze.walls[i, j]
    if arrival is not None:
        obs[arrival] = 0.5
    direction = maze.cell_signs.direction[i, j]
    if direction >= 0:
        obs[4 + direction] = maze.cell_signs.value[i, j]
    return obs


def cell_image(
    maze: Maze, cell: tuple[int, int], vision: int, arrival: int | None = None
) -> np.ndarray:
    """The ``vision x vision`` float32 image of ``cell`` (reference §5.2)."""
    i, j = cell
    east, north, west, south = (float(w) for w in maze.walls[i, j])
    image = np.zeros((vision, vision), dtype=np.float32)
    image[:, -1] = east
    image[0, :] = north
    image[:, 0] = west
    image[-1, :] = south
    image[0, -1] = max(north, east)
    image[0, 0] = max(north, west)
    image[-1, -1] = max(south, east)
    image[-1, 0] = max(south, west)
    sign = maze.sign_at((i, j))
    if sign is not None:
        image[1:-1, 1:-1] = sign_frames(sign.sign, vision - 2)[int(sign.direction)]
    if arrival is not None:
        middle = vision // 2
        image[[(middle, -1), (0, middle), (middle, 0), (-1, middle)][arrival]] = 1.0
    return image


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
