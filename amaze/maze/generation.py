"""Maze generation, bit-identical to amaze-benchmarker 1.0 (``docs/reference-behaviour.md`` §3).

The reference draws from Python's ``random.Random(seed)`` (MT19937), re-created
from the same seed before each phase. The phases, in order:

1. depth-first carving of a perfect maze on the un-rotated frame;
2. rotation of the south-west maze to the requested corner;
3. intersections along the solution (cells with 3-4 openings);
4. unicursive mode: wall off every side branch of the solution;
5. clue types assigned to intersections (cycle + shuffle);
6. lures placed on non-intersection path cells (``sample`` + ``choice``);
7. some clues turned into traps pointing a wrong, open way.

This module is the readable definition, written with ``random.Random`` as
the reference is; :mod:`amaze.maze.compiled_generation` runs the same phases
in one compiled call (what :meth:`amaze.maze.maze.Maze.generate` uses), and
the tests check the two agree.

One deliberate difference: at a four-way crossing a trap has two wrong open
directions to choose from, and the reference picks by iterating a ``set`` of
enum members, whose order depends on ``PYTHONHASHSEED`` (it is not
reproducible across processes). We order the candidates as the lure directions
are ordered (E, N, W, S rotated by the start corner), which is deterministic and
rotation-equivariant: the four rotations of a maze carry the same traps, so
Surprisingness is rotation invariant. The number of random draws is unchanged,
so nothing else differs; such traps are flagged ``reference_undefined``.
"""

from __future__ import annotations

import random
from itertools import cycle, islice
from typing import NamedTuple

import numpy as np

from amaze.maze.directions import OFFSETS, Cell, Direction, direction_between
from amaze.maze.signs import PlacedSign, SignKind
from amaze.maze.spec import MazeSpec, StartLocation

_DIRECTIONS = tuple(Direction)


def carve(
    seed: int, width: int, height: int, start: Cell, end: Cell
) -> tuple[np.ndarray, list[Cell]]:
    """The reference's depth-first maze for ``seed``: ``(walls, solution)`` (§3.2)."""
    rng = random.Random(seed)
    walls = np.ones((width, height, 4), dtype=bool)
    stack = [start]
    visited = {start}
    solution: list[Cell] = []
    while stack:
        if stack[-1] == end:
            solution = list(stack)
        current = stack.pop()
        neighbours = [
            (d, (current[0] + di, current[1] + dj))
            for d, (di, dj) in enumerate(OFFSETS)
            if 0 <= current[0] + di < width
            and 0 <= current[1] + dj < height
            and (current[0] + di, current[1] + dj) not in visited
        ]
        if neighbours:
            d, cell = rng.choice(neighbours)
            visited.add(cell)
            _set_wall(walls, current, d, False)
            stack += [current, cell]
    return walls, solution


def _rotate(
    walls: np.ndarray, cells: list[Cell], start: StartLocation
) -> tuple[np.ndarray, list[Cell]]:
    """Turn the south-west maze so that it starts from ``start`` (reference §3.3)."""
    k = int(start)
    walls = np.roll(np.rot90(walls, -k, axes=(1, 0)), k, axis=2)
    w, h = walls.shape[:2]
    if start == StartLocation.SOUTH_EAST:
        cells = [(w - 1 - j, i) for i, j in cells]
    elif start == StartLocation.NORTH_EAST:
        cells = [(w - 1 - i, h - 1 - j) for i, j in cells]
    elif start == StartLocation.NORTH_WEST:
        cells = [(j, h - 1 - i) for i, j in cells]
    return walls, cells


def _set_wall(walls: np.ndarray, cell: Cell, d: int, value: bool) -> None:
    """Set the wall on side ``d`` of ``cell`` and the matching side of its neighbour."""
    i, j = cell
    walls[i, j, d] = value
    di, dj = OFFSETS[d]
    if 0 <= i + di < walls.shape[0] and 0 <= j + dj < walls.shape[1]:
        walls[i + di, j + dj, (d + 2) % 4] = value


def _find_intersections(walls: np.ndarray, solution: list[Cell]) -> list[tuple[int, Direction]]:
    n_walls = walls.sum(axis=2)
    return [
        (index, direction_between(solution[index], solution[index + 1]))
        for index in range(1, len(solution) - 1)
        if n_walls[solution[index]] < 2
    ]


def _make_unicursive(
    walls: np.ndarray, solution: list[Cell], intersections: list[tuple[int, Direction]]
) -> None:
    """Wall off every side branch of the solution, and of the goal cell (§3.5)."""
    for index, forward in intersections:
        cell = solution[index]
        backward = direction_between(cell, solution[index - 1])
        for d in range(4):
            if d not in (backward, forward):
                _set_wall(walls, cell, d, True)
    end = solution[-1]
    if walls[end].sum() < 3:
        backward = direction_between(end, solution[-2])
        for d in range(4):
            if d != backward:
                _set_wall(walls, end, d, True)


def _type_indices(rng: random.Random, n_types: int, count: int) -> list[int]:
    """Sign-type indices used ⌊count/n⌋ or ⌈count/n⌉ times each, in shuffled order."""
    indices = list(islice(cycle(range(n_types)), count))
    rng.shuffle(indices)
    return indices


class MazeParts(NamedTuple):
    """The parts of a generated maze, from which :class:`~amaze.maze.maze.Maze` is built."""

    walls: np.ndarray
    start: Cell
    end: Cell
    solution: list[Cell]
    intersections: list[tuple[int, Direction]]
    clues: list[PlacedSign]
    lures: list[PlacedSign]
    traps: list[PlacedSign]


def generate(spec: MazeSpec) -> MazeParts:
    """The walls, solution and placed signs of the maze described by ``spec``.

    :meth:`amaze.maze.maze.Maze.generate` wraps them into a ``Maze``; keeping
    this module free of the ``Maze`` class keeps the import graph acyclic.
    """
    w, h = spec.width, spec.height
    if spec.rotated:
        start, end = (0, 0), (w - 1, h - 1)
    else:
        start = spec.start.corner(w, h)
        end = (w - 1 - start[0], h - 1 - start[1])
    walls, solution = carve(spec.seed, w, h, start, end)
    if spec.rotated and spec.start != StartLocation.SOUTH_WEST:
        walls, cells = _rotate(walls, [start, end, *solution], spec.start)
        start, end, solution = cells[0], cells[1], cells[2:]
    walls = np.array(walls, dtype=bool)  # own, writable, C-ordered copy

    intersections = _find_intersections(walls, solution)
    if spec.unicursive:
        _make_unicursive(walls, solution, intersections)
        intersections = []

    # Clues: one entry per intersection; without clue types the entries are
    # placeholders that traps may still convert (as in the reference).
    if spec.clue:
        clue_types = _type_indices(random.Random(spec.seed), len(spec.clue), len(intersections))
    else:
        clue_types = [-1] * len(intersections)
    clue_entries = [
        (clue_types[k], index, direction, direction)
        for k, (index, direction) in enumerate(intersections)
    ]

    # Sign directions in the order E, N, W, S rotated by the start corner, so
    # that signs are rotation-equivariant across the four rotations.
    k = int(spec.start)
    ordered_dirs = [_DIRECTIONS[(d + k) % 4] for d in range(4)]

    lure_entries = []
    if spec.p_lure and spec.lure:
        rng = random.Random(spec.seed)
        candidates = set(range(len(solution) - 1)) - {index for index, _ in intersections}
        n_lures = round(spec.p_lure * len(candidates))
        lure_types = _type_indices(rng, len(spec.lure), n_lures)
        # list(set) of small non-negative ints is ascending in CPython, as in the reference.
        for sign_index, index in zip(
            lure_types, rng.sample(list(candidates), n_lures), strict=True
        ):
            truth = direction_between(solution[index], solution[index + 1])
            direction = rng.choice([d for d in ordered_dirs if d != truth])
            lure_entries.append((sign_index, index, direction, truth, False))

    trap_entries = []
    if spec.p_trap and spec.trap:
        rng = random.Random(spec.seed)
        n_traps = round(spec.p_trap * len(clue_entries))
        chosen = sorted(rng.sample(range(len(intersections)), n_traps))
        trap_types = _type_indices(rng, len(spec.trap), n_traps)
        for position in reversed(chosen):
            _, index, _, truth = clue_entries.pop(position)
            cell = solution[index]
            backward = direction_between(cell, solution[index - 1])
            candidates = [
                d for d in ordered_dirs if d not in (truth, backward) and not walls[cell][d]
            ]
            direction = rng.choice(candidates)
            trap_entries.append((trap_types.pop(), index, direction, truth, len(candidates) > 1))

    if not spec.clue:
        clue_entries = []

    def placed(kind: SignKind, types: tuple, entry: tuple) -> PlacedSign:
        sign_index, index, direction, truth, *undefined = entry
        return PlacedSign(
            kind=kind,
            sign_index=sign_index,
            sign=types[sign_index],
            solution_index=index,
            cell=solution[index],
            direction=_DIRECTIONS[direction],
            truth=_DIRECTIONS[truth],
            reference_undefined=bool(undefined and undefined[0]),
        )

    return MazeParts(
        walls=walls,
        start=start,
        end=end,
        solution=solution,
        intersections=intersections,
        clues=[placed(SignKind.CLUE, spec.clue, e) for e in clue_entries],
        lures=[placed(SignKind.LURE, spec.lure, e) for e in lure_entries],
        traps=[placed(SignKind.TRAP, spec.trap, e) for e in trap_entries],
    )
