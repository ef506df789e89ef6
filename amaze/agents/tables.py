"""Flat per-cell lookup tables of a batch of mazes, for the batch engine.

Mazes of different sizes are concatenated: maze ``m`` owns the global cells
``cell_offset[m] .. cell_offset[m] + width[m] * height[m]``, cell ``(i, j)``
being global cell ``cell_offset[m] + i * height[m] + j`` (the order of
``Maze.walls``). Everything an agent perceives is precomputed once here, so
that a step of the engine is a few table look-ups:

* moves: the global cell reached through each side of every cell, -1 behind a
  wall (``neighbours``), so that a discrete move is one look-up;

* discrete robots: the 8-float observation of every (cell, arrival side), the
  arrival side being 0 (none, at the start) or ``1 + d`` for side ``d`` (E, N,
  W, S) leading back to the previous cell;
* image robots (hybrid and continuous): the ``v x v`` uint8 tile of every cell
  *without* the origin marker (the marker depends on the arrival side and is
  drawn at observation time), and for each maze one zero-padded canvas made of
  those tiles (row 0 = north), so that the continuous sub-cell window is a slice.

The single-agent environment (:mod:`amaze.envs.gym_env`) uses the per-maze pieces
directly: :func:`neighbour_cells` for moves, :func:`discrete_observations` and
:func:`cell_tiles` (with :func:`marker_pixel`) for observations.

Gray levels are ``k = round(255 * x)`` of the reference's float images: walls
and the origin marker are 255, sign pixels are the sign image's levels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR, RewardScheme
from amaze.agents.robot import Robot, as_robot
from amaze.maze.maze import Maze, as_maze
from amaze.maze.sign_images import sign_frames_u8
from amaze.maze.spec import MazeSpec

#: Gray level of walls and of the origin marker.
WHITE = 255

#: Number of arrival codes: none, then arrival from E, N, W, S.
N_ARRIVALS = 5


@dataclass(frozen=True)
class MazeTables:
    """Compiled tables of a list of mazes for one robot (see the module docstring).

    Per maze (length ``n_mazes``): ``width``, ``height``, ``cell_offset``,
    ``start``/``end`` (global cell indices), ``start_ij``/``end_ij`` (local
    ``(i, j)``), ``path_length`` (the paper's ``l``), ``deadline`` (in steps, a
    float as in the reference), ``finish`` (the ``2l - 1`` bonus), ``dt``.
    Per cell (length ``n_cells``): ``walls`` (bit ``d`` set when side ``d`` has
    a wall) and ``neighbours`` int32 ``(n_cells, 4)`` (the global cell through
    side ``d``, -1 behind a wall). Observation tables: ``discrete_obs`` float32 ``(n_cells, 5, 8)``
    for discrete robots; ``tiles`` uint8 ``(n_cells, v, v)``, ``canvas`` (flat
    uint8) with ``canvas_offset`` per maze for image robots (else empty).
    """

    robot: Robot
    dt: float
    deadline_factor: float
    width: np.ndarray
    height: np.ndarray
    cell_offset: np.ndarray
    start: np.ndarray
    end: np.ndarray
    start_ij: np.ndarray
    end_ij: np.ndarray
    path_length: np.ndarray
    deadline: np.ndarray
    finish: np.ndarray
    walls: np.ndarray
    neighbours: np.ndarray
    discrete_obs: np.ndarray
    tiles: np.ndarray
    canvas: np.ndarray
    canvas_offset: np.ndarray

    @property
    def n_mazes(self) -> int:
        return int(self.width.shape[0])

    @property
    def n_cells(self) -> int:
        return int(self.walls.shape[0])

    @property
    def vision(self) -> int:
        """Image side ``v`` (0 for discrete robots)."""
        return int(self.robot.vision or 0)


def wall_bits(maze: Maze) -> np.ndarray:
    """uint8 ``(width * height,)``: bit ``d`` set when the cell has a wall on side ``d``."""
    walls = maze.walls.reshape(-1, 4).astype(np.uint8)
    return (walls * np.array([1, 2, 4, 8], dtype=np.uint8)).sum(axis=1).astype(np.uint8)


def neighbour_cells(maze: Maze) -> np.ndarray:
    """int64 ``(width * height, 4)``: the cell reached from each cell through side ``d``.

    Cells are numbered ``i * height + j`` (the order of :func:`wall_bits`); the
    entry is -1 where side ``d`` has a wall (or is the maze border), so that a
    discrete move is one look-up.
    """
    w, h = maze.width, maze.height
    index = np.arange(w * h, dtype=np.int64).reshape(w, h)
    shifts = np.array([h, 1, -h, -1], dtype=np.int64)  # E, N, W, S
    target = index[:, :, None] + shifts
    blocked = maze.walls.astype(bool).copy()
    blocked[-1, :, 0] = True
    blocked[:, -1, 1] = True
    blocked[0, :, 2] = True
    blocked[:, 0, 3] = True
    return np.where(blocked, -1, target).reshape(w * h, 4)


def marker_pixel(side: int, vision: int) -> tuple[int, int]:
    """Row and column of the origin marker drawn on ``side`` (0..3) of a ``v x v`` image."""
    half = vision // 2
    return ((half, vision - 1), (0, half), (half, 0), (vision - 1, half))[side]


def discrete_observations(maze: Maze) -> np.ndarray:
    """float32 ``(width * height, 5, 8)``: the discrete observation of each (cell, arrival).

    ``[W_e, W_n, W_w, W_s, S_e, S_n, S_w, S_s]``: walls are 1/0, the arrival side
    (the side back to the previous cell) is 0.5, and a clue, lure or trap puts
    its value at slot ``4 + direction`` (reference §5.1).
    """
    w, h = maze.width, maze.height
    obs = np.zeros((w, h, N_ARRIVALS, 8), dtype=np.float32)
    obs[:, :, :, :4] = maze.walls[:, :, None, :]
    for d in range(4):
        obs[:, :, 1 + d, d] = 0.5
    for placed in maze.signs:  # clues, then lures, then traps: the reference's order
        i, j = placed.cell
        obs[i, j, :, 4:] = 0.0
        obs[i, j, :, 4 + int(placed.direction)] = np.float32(placed.sign.value)
    return obs.reshape(w * h, N_ARRIVALS, 8)


def cell_tiles(maze: Maze, vision: int) -> np.ndarray:
    """uint8 ``(width * height, v, v)``: each cell's image without the origin marker.

    Borders are the walls (255), each corner the OR of its two walls, and the
    interior the frame of the cell's sign for its direction (reference §5.2).
    """
    v = vision
    walls = maze.walls.reshape(-1, 4)
    tiles = np.zeros((walls.shape[0], v, v), dtype=np.uint8)
    east, north, west, south = (walls[:, d] for d in range(4))
    tiles[:, :, -1] = WHITE * east[:, None]
    tiles[:, 0, :] = WHITE * north[:, None]
    tiles[:, :, 0] = WHITE * west[:, None]
    tiles[:, -1, :] = WHITE * south[:, None]
    tiles[:, 0, -1] = WHITE * (north | east)
    tiles[:, 0, 0] = WHITE * (north | west)
    tiles[:, -1, -1] = WHITE * (south | east)
    tiles[:, -1, 0] = WHITE * (south | west)
    for placed in maze.signs:
        i, j = placed.cell
        frames = sign_frames_u8(placed.sign, v - 2)
        tiles[i * maze.height + j, 1:-1, 1:-1] = frames[int(placed.direction)]
    return tiles


def maze_canvas(maze: Maze, tiles: np.ndarray, vision: int) -> np.ndarray:
    """uint8 ``((h + 2) v, (w + 2) v)``: the whole maze drawn from its tiles, row 0 = north.

    One ring of empty (0) tiles surrounds the maze: the continuous observation
    shows nothing outside the maze. Cell ``(i, j)`` starts at row
    ``(h - j) * v`` and column ``(i + 1) * v``.
    """
    v, w, h = vision, maze.width, maze.height
    canvas = np.zeros(((h + 2) * v, (w + 2) * v), dtype=np.uint8)
    grid = tiles.reshape(w, h, v, v)[:, ::-1]  # (i, north-first j, row, col)
    canvas[v : (h + 1) * v, v : (w + 1) * v] = grid.transpose(1, 2, 0, 3).reshape(h * v, w * v)
    return canvas


def compile_mazes(
    mazes: Sequence[Maze | MazeSpec | str],
    robot: Robot | str,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
) -> MazeTables:
    """Compile ``mazes`` (or their specs or strings) into the lookup tables of ``robot``'s mode."""
    robot = as_robot(robot)
    mazes = [as_maze(m) for m in mazes]
    if not mazes:
        raise ValueError("compile_mazes needs at least one maze")
    dt = 1.0 if robot.discrete_outputs else 0.1
    n = len(mazes)
    width = np.array([m.width for m in mazes], dtype=np.int64)
    height = np.array([m.height for m in mazes], dtype=np.int64)
    sizes = width * height
    cell_offset = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    start_ij = np.array([m.start for m in mazes], dtype=np.int64).reshape(n, 2)
    end_ij = np.array([m.end for m in mazes], dtype=np.int64).reshape(n, 2)
    start = cell_offset + start_ij[:, 0] * height + start_ij[:, 1]
    end = cell_offset + end_ij[:, 0] * height + end_ij[:, 1]
    schemes = [RewardScheme(m.path_length, dt, deadline_factor) for m in mazes]
    path_length = np.array([m.path_length for m in mazes], dtype=np.int64)
    deadline = np.array([s.deadline for s in schemes], dtype=np.float64)
    finish = np.array([s.finish for s in schemes], dtype=np.float64)
    walls = np.concatenate([wall_bits(m) for m in mazes])
    neighbours = np.concatenate(
        [
            np.where(local < 0, -1, local + offset)
            for local, offset in zip((neighbour_cells(m) for m in mazes), cell_offset, strict=True)
        ]
    ).astype(np.int32)

    empty_u8 = np.zeros(0, dtype=np.uint8)
    if robot.discrete_inputs:
        discrete_obs = np.concatenate([discrete_observations(m) for m in mazes])
        tiles = np.zeros((0, 1, 1), dtype=np.uint8)
        canvas, canvas_offset = empty_u8, np.zeros(n, dtype=np.int64)
    else:
        v = int(robot.vision)
        discrete_obs = np.zeros((0, N_ARRIVALS, 8), dtype=np.float32)
        per_maze = [cell_tiles(m, v) for m in mazes]
        tiles = np.ascontiguousarray(np.concatenate(per_maze))
        if robot.discrete_outputs:
            canvas, canvas_offset = empty_u8, np.zeros(n, dtype=np.int64)
        else:
            canvases = [maze_canvas(m, t, v).ravel() for m, t in zip(mazes, per_maze, strict=True)]
            lengths = np.array([c.size for c in canvases], dtype=np.int64)
            canvas_offset = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
            canvas = np.concatenate(canvases)

    return MazeTables(
        robot=robot,
        dt=dt,
        deadline_factor=float(deadline_factor),
        width=width,
        height=height,
        cell_offset=cell_offset,
        start=start,
        end=end,
        start_ij=start_ij,
        end_ij=end_ij,
        path_length=path_length,
        deadline=deadline,
        finish=finish,
        walls=walls,
        neighbours=np.ascontiguousarray(neighbours),
        discrete_obs=np.ascontiguousarray(discrete_obs),
        tiles=tiles,
        canvas=canvas,
        canvas_offset=canvas_offset,
    )
