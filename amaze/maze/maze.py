"""Generated mazes: walls, solution path, intersections and placed signs.

A :class:`Maze` is produced from a :class:`~amaze.maze.spec.MazeSpec` by
:meth:`Maze.generate` (or :meth:`Maze.from_string`), which builds it from the
parts :func:`amaze.maze.compiled_generation.generate` computes, and is immutable.
Conventions (shared with the reference library and the ``amaze inspect --json``
contract):

* ``walls[i, j, d]`` is True when cell ``(i, j)`` has a wall on side ``d``
  (0=E, 1=N, 2=W, 3=S); ``(0, 0)`` is the south-west corner, ``i`` grows east;
* ``solution`` lists the cells from ``start`` to ``end``, both included (its
  length is the paper's path length ``l``);
* every placed sign knows its kind (clue, lure, trap), the index of its sign
  type in the spec, its solution index and cell, where it points
  (``direction``) and the correct move there (``truth``).
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import IntEnum
from functools import cached_property
from typing import Any

import numpy as np

from amaze.maze.compiled_generation import generate
from amaze.maze.directions import Cell, Direction
from amaze.maze.signs import PlacedSign, SignKind
from amaze.maze.spec import MazeSpec


class MazeClass(IntEnum):
    """The paper's maze classes, with the reference's numeric values."""

    TRIVIAL = 0b000
    SIMPLE = 0b001
    LURES = 0b011
    TRAPS = 0b101
    COMPLEX = 0b111
    INVALID = 0xFF

    @property
    def label(self) -> str:
        """Lower-case name: trivial, simple, lures, traps, complex or invalid."""
        return self.name.lower()


class CellSigns:
    """Per-cell sign lookup tables, shape ``(width, height)`` each.

    ``value`` is the sign's lightness (0 where there is no sign), ``direction``
    where it points (-1 where there is none), ``kind`` 0/1/2 for clue/lure/trap
    (-1 where there is none). A cell holds at most one sign.
    """

    def __init__(self, maze: Maze) -> None:
        shape = (maze.width, maze.height)
        self.value = np.zeros(shape, dtype=np.float64)
        self.direction = np.full(shape, -1, dtype=np.int8)
        self.kind = np.full(shape, -1, dtype=np.int8)
        kinds = list(SignKind)
        for placed in maze.signs:
            i, j = placed.cell
            self.value[i, j] = placed.sign.value
            self.direction[i, j] = placed.direction
            self.kind[i, j] = kinds.index(placed.kind)
        for array in (self.value, self.direction, self.kind):
            array.flags.writeable = False


class Maze:
    """A generated maze. Build one with :meth:`from_string` or :meth:`generate`."""

    def __init__(
        self,
        spec: MazeSpec,
        walls: np.ndarray,
        start: Cell,
        end: Cell,
        solution: list[Cell],
        intersections: list[tuple[int, Direction]],
        clues: list[PlacedSign],
        lures: list[PlacedSign],
        traps: list[PlacedSign],
    ) -> None:
        walls = np.ascontiguousarray(walls, dtype=bool)
        walls.flags.writeable = False
        self.spec = spec
        self.walls = walls
        self.width, self.height = int(walls.shape[0]), int(walls.shape[1])
        self.start = start
        self.end = end
        self.solution: tuple[Cell, ...] = tuple(solution)
        #: ``(solution index, direction of the correct move)`` of each
        #: intersection (a path cell other than start and end with 3-4 openings).
        self.intersections: tuple[tuple[int, Direction], ...] = tuple(intersections)
        self.clues: tuple[PlacedSign, ...] = tuple(clues)
        self.lures: tuple[PlacedSign, ...] = tuple(lures)
        self.traps: tuple[PlacedSign, ...] = tuple(traps)

    # -- construction -----------------------------------------------------

    @classmethod
    def generate(cls, spec: MazeSpec) -> Maze:
        """Generate the maze of ``spec`` (bit-identical to amaze-benchmarker 1.0)."""
        return cls(spec, **generate(spec)._asdict())

    @classmethod
    def from_string(cls, text: str, **overrides: object) -> Maze:
        """Generate the maze of a maze string (see :mod:`amaze.maze.spec`)."""
        return cls.generate(MazeSpec.from_string(text, **overrides))

    # -- description ------------------------------------------------------

    def to_string(self) -> str:
        """The canonical maze string; it regenerates exactly this maze."""
        return self.spec.to_string()

    def __repr__(self) -> str:
        return f"Maze('{self.to_string()}')"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Maze):
            return NotImplemented
        return (
            self.spec == other.spec
            and np.array_equal(self.walls, other.walls)
            and self.solution == other.solution
            and self.signs == other.signs
        )

    def __hash__(self) -> int:
        return hash(self.spec)

    @property
    def path_length(self) -> int:
        """Number of cells of the solution, start and end included (the paper's ``l``)."""
        return len(self.solution)

    def path_positions(self) -> np.ndarray:
        """float64 ``(width * height,)``: each cell's place on the solution, -1 off it.

        Cell ``(i, j)`` at ``i * height + j``; the solution's ``k``-th cell holds
        ``k / (l - 1)``: the start 0, the goal 1. What path progress is read from.
        """
        positions = np.full(self.width * self.height, -1.0)
        solution = np.asarray(self.solution, dtype=np.int64).reshape(-1, 2)
        cells = solution[:, 0] * self.height + solution[:, 1]
        positions[cells] = np.arange(len(solution)) / max(1, len(solution) - 1)
        return positions

    @property
    def n_intersections(self) -> int:
        return len(self.intersections)

    @property
    def unicursive(self) -> bool:
        """True when the solution path has no intersection."""
        return not self.intersections

    @property
    def signs(self) -> tuple[PlacedSign, ...]:
        """Every placed sign: clues, then lures, then traps."""
        return self.clues + self.lures + self.traps

    @cached_property
    def _signs_by_cell(self) -> dict[Cell, PlacedSign]:
        return {placed.cell: placed for placed in self.signs}

    def sign_at(self, cell: Cell) -> PlacedSign | None:
        """The sign placed in ``cell``, or ``None`` (a cell holds at most one)."""
        return self._signs_by_cell.get(cell)

    @cached_property
    def cell_signs(self) -> CellSigns:
        """Per-cell arrays of sign value, direction and kind."""
        return CellSigns(self)

    def stats(self) -> dict[str, Any]:
        """Size, path length and counts, as the reference's ``Maze.stats()``."""
        return {
            "size": (self.width, self.height),
            "path": self.path_length,
            "intersections": self.n_intersections,
            "clues": len(self.clues),
            "lures": len(self.lures),
            "traps": len(self.traps),
        }

    @property
    def maze_class(self) -> MazeClass:
        """Trivial, simple, lures, traps, complex or invalid (reference §3.9)."""
        n = self.n_intersections
        if n == 0:
            return MazeClass.TRIVIAL
        c, l, t = len(self.clues), len(self.lures), len(self.traps)
        if c == n and t == 0:
            return MazeClass.SIMPLE if l == 0 else MazeClass.LURES
        if c < n and t > 0 and c + t == n:
            return MazeClass.TRAPS if l == 0 else MazeClass.COMPLEX
        return MazeClass.INVALID


def _as_spec(maze: Maze | MazeSpec | str) -> MazeSpec:
    """The spec of a maze, of a spec (itself) or of a maze string (parsed, not generated)."""
    if isinstance(maze, Maze):
        return maze.spec
    if isinstance(maze, MazeSpec):
        return maze
    if isinstance(maze, str):
        return MazeSpec.from_string(maze)
    raise ValueError(f"expected a MazeSpec, a Maze or a maze string, not {maze!r}")


def _as_items(
    mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str],
) -> list[Maze | MazeSpec | str]:
    """One maze (or spec, or string) or a sequence of them, as a non-empty list."""
    items = [mazes] if isinstance(mazes, str | Maze | MazeSpec) else list(mazes)
    if not items:
        raise ValueError("mazes: give at least one maze")
    return items


def as_maze(maze: Maze | MazeSpec | str) -> Maze:
    """A :class:`Maze` from a maze, its spec or its string."""
    return maze if isinstance(maze, Maze) else Maze.generate(_as_spec(maze))


def as_mazes(mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str]) -> list[Maze]:
    """A non-empty list of mazes from one maze (or spec, or string) or a sequence of them."""
    return [as_maze(m) for m in _as_items(mazes)]


def rotations(mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str]) -> list[str]:
    """Canonical strings of every maze of ``mazes`` started from each corner, maze by maze.

    The four rotations of a maze come in the reference's order (NW, NE, SW,
    SE, :meth:`MazeSpec.all_rotations`); this is the one place that expands
    mazes to their rotations (training sets, evaluation sets, the suite).
    Mazes, specs and strings are accepted; none is generated here (a string is
    only parsed), and the strings returned are what run folders and reports
    record, so they are generated once, where they are played.
    """
    specs = [_as_spec(maze) for maze in _as_items(mazes)]
    return [rotated.to_string() for spec in specs for rotated in spec.all_rotations()]
