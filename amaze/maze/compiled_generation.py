"""Maze generation in one compiled call, bit-identical to :mod:`amaze.maze.generation`.

:func:`amaze.maze.generation.generate` is the readable definition: the
reference's phases written with ``random.Random``. :func:`generate` here runs
the same phases in one numba kernel, drawing from :mod:`amaze.maze.mersenne`
(CPython's generator and conversions in compiled code), so no interpreter
runs inside the loops; only the seed's key goes in and the arrays of the
parts come out. ``tests/amaze/maze/test_compiled_generation.py`` checks the
two agree on every fixture and on thousands of random specs (every corner,
rotation mode, size and sign combination); :meth:`amaze.maze.maze.Maze.generate`
uses this one.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from amaze.maze.directions import OFFSETS, Direction
from amaze.maze.generation import MazeParts
from amaze.maze.mersenne import choice_index, randbelow, sample, seed_key, seeded_state, shuffle
from amaze.maze.signs import PlacedSign, SignKind
from amaze.maze.spec import MazeSpec

_OFFSET_I = np.array([d[0] for d in OFFSETS], dtype=np.int64)
_OFFSET_J = np.array([d[1] for d in OFFSETS], dtype=np.int64)
_DIRECTIONS = tuple(Direction)


@numba.njit(cache=True, nogil=True, inline="always")
def _direction_between(ai, aj, bi, bj):
    """Direction (0=E, 1=N, 2=W, 3=S) of the step from cell ``a`` to its neighbour ``b``."""
    if bi > ai:
        return 0
    if bj > aj:
        return 1
    if bi < ai:
        return 2
    return 3


@numba.njit(cache=True, nogil=True)
def _carve(mt, width, height, start_i, start_j, end_i, end_j):
    """Depth-first carving (reference §3.2): ``(walls, solution)``.

    Cells are numbered on a grid padded by one visited cell on every side
    (``p = (i + 1) * (height + 2) + j + 1``), so a neighbour needs no bounds check.
    """
    stride = height + 2
    step = np.array([stride, 1, -stride, -1])  # E, N, W, S
    visited = np.ones((width + 2) * stride, dtype=np.bool_)
    for i in range(width):
        visited[(i + 1) * stride + 1 : (i + 1) * stride + 1 + height] = False
    walls = np.ones(((width + 2) * stride, 4), dtype=np.bool_)
    stack = np.empty(width * height + 1, dtype=np.int64)
    solution = stack[:0].copy()
    neighbour_dirs = np.empty(4, dtype=np.int64)
    start = (start_i + 1) * stride + start_j + 1
    end = (end_i + 1) * stride + end_j + 1
    stack[0] = start
    top = 1
    visited[start] = True
    while top > 0:
        if stack[top - 1] == end:
            solution = stack[:top].copy()
        top -= 1
        current = stack[top]
        n = 0
        for d in range(4):
            if not visited[current + step[d]]:
                neighbour_dirs[n] = d
                n += 1
        if n == 0:
            continue
        d = neighbour_dirs[choice_index(mt, n)]
        cell = current + step[d]
        visited[cell] = True
        walls[current, d] = False
        walls[cell, (d + 2) % 4] = False
        stack[top] = current
        stack[top + 1] = cell
        top += 2
    cells = np.empty((solution.shape[0], 2), dtype=np.int64)
    for k in range(solution.shape[0]):
        cells[k, 0] = solution[k] // stride - 1
        cells[k, 1] = solution[k] % stride - 1
    return walls.reshape(width + 2, stride, 4)[1:-1, 1:-1].copy(), cells


@numba.njit(cache=True, nogil=True)
def _rotate(walls, cells, k):
    """Turn the south-west maze ``k`` quarter turns counter-clockwise (§3.3), ``cells`` in place.

    One turn maps cell ``(i, j)`` of a ``W x H`` maze to ``(H-1-j, i)`` of an
    ``H x W`` one and a wall on side ``d`` to side ``d+1``, as the reference's
    ``np.roll(np.rot90(walls, -k, axes=(1, 0)), k, axis=2)``.
    """
    for _ in range(k):
        width, height = walls.shape[0], walls.shape[1]
        turned = np.empty((height, width, 4), dtype=np.bool_)
        for a in range(height):
            for b in range(width):
                for d in range(4):
                    turned[a, b, (d + 1) % 4] = walls[b, height - 1 - a, d]
        for c in range(cells.shape[0]):
            i, j = cells[c, 0], cells[c, 1]
            cells[c, 0], cells[c, 1] = height - 1 - j, i
        walls = turned
    return walls


@numba.njit(cache=True, nogil=True)
def _set_wall(walls, i, j, d):
    """Close side ``d`` of cell ``(i, j)`` and the matching side of its neighbour."""
    walls[i, j, d] = True
    ni, nj = i + _OFFSET_I[d], j + _OFFSET_J[d]
    if 0 <= ni < walls.shape[0] and 0 <= nj < walls.shape[1]:
        walls[ni, nj, (d + 2) % 4] = True


@numba.njit(cache=True, nogil=True)
def _round_half_even(x):
    """Python's ``round(x)`` for a non-negative float."""
    r = math.floor(x)
    fraction = x - r
    if fraction > 0.5 or (fraction == 0.5 and r % 2 == 1):
        r += 1
    return int(r)


@numba.njit(cache=True, nogil=True)
def _type_indices(mt, n_types, count):
    """Sign-type indices cycled then shuffled (``generation._type_indices``)."""
    indices = np.empty(count, dtype=np.int64)
    for c in range(count):
        indices[c] = c % n_types
    shuffle(mt, indices)
    return indices


@numba.njit(cache=True, nogil=True)
def _generate(
    key, width, height, start_k, rotated, unicursive, n_clue, n_lure, p_lure, n_trap, p_trap
):
    """Every phase of ``generation.generate`` (§3.2-§3.8) on arrays.

    Returns ``(walls, cells, intersections, clues, lures, traps)``: ``cells`` is
    start, end then the solution; ``intersections`` rows are ``(solution index,
    direction)``; sign rows are ``(type index, solution index, direction,
    truth, reference_undefined)``.
    """
    seeded = seeded_state(key)
    mt = seeded.copy()
    if rotated:
        start_i, start_j = 0, 0
        end_i, end_j = width - 1, height - 1
    else:
        start_i = 0 if start_k == 0 or start_k == 3 else width - 1
        start_j = 0 if start_k == 0 or start_k == 1 else height - 1
        end_i, end_j = width - 1 - start_i, height - 1 - start_j
    walls, solution = _carve(mt, width, height, start_i, start_j, end_i, end_j)
    n_path = solution.shape[0]
    cells = np.empty((n_path + 2, 2), dtype=np.int64)
    cells[0, 0], cells[0, 1] = start_i, start_j
    cells[1, 0], cells[1, 1] = end_i, end_j
    cells[2:] = solution
    if rotated and start_k != 0:
        walls = _rotate(walls, cells, start_k)
    path = cells[2:]

    # Intersections: solution cells other than start and end with 3-4 openings.
    intersections = np.empty((max(n_path - 2, 0), 2), dtype=np.int64)
    n_int = 0
    for index in range(1, n_path - 1):
        i, j = path[index, 0], path[index, 1]
        if walls[i, j, 0] + walls[i, j, 1] + walls[i, j, 2] + walls[i, j, 3] < 2:
            intersections[n_int, 0] = index
            intersections[n_int, 1] = _direction_between(
                i, j, path[index + 1, 0], path[index + 1, 1]
            )
            n_int += 1
    intersections = intersections[:n_int]

    if unicursive:
        for r in range(n_int):
            index, forward = intersections[r, 0], intersections[r, 1]
            i, j = path[index, 0], path[index, 1]
            backward = _direction_between(i, j, path[index - 1, 0], path[index - 1, 1])
            for d in range(4):
                if d != backward and d != forward:
                    _set_wall(walls, i, j, d)
        ei, ej = path[n_path - 1, 0], path[n_path - 1, 1]
        if walls[ei, ej, 0] + walls[ei, ej, 1] + walls[ei, ej, 2] + walls[ei, ej, 3] < 3:
            backward = _direction_between(ei, ej, path[n_path - 2, 0], path[n_path - 2, 1])
            for d in range(4):
                if d != backward:
                    _set_wall(walls, ei, ej, d)
        n_int = 0
        intersections = intersections[:0]

    # Clues: one entry per intersection (placeholders of type -1 without clue types).
    clues = np.empty((n_int, 5), dtype=np.int64)
    if n_clue > 0:
        mt[:] = seeded
        clues[:, 0] = _type_indices(mt, n_clue, n_int)
    else:
        clues[:, 0] = -1
    clues[:, 1] = intersections[:, 0]
    clues[:, 2] = intersections[:, 1]
    clues[:, 3] = intersections[:, 1]
    clues[:, 4] = 0

    # Sign directions in the order E, N, W, S rotated by the start corner.
    ordered = np.empty(4, dtype=np.int64)
    for d in range(4):
        ordered[d] = (d + start_k) % 4

    lures = np.empty((0, 5), dtype=np.int64)
    if p_lure != 0 and n_lure > 0:
        mt[:] = seeded
        is_candidate = np.ones(max(n_path - 1, 0), dtype=np.bool_)
        for r in range(n_int):
            is_candidate[intersections[r, 0]] = False
        candidates = np.nonzero(is_candidate)[0].astype(np.int64)
        n_lures = _round_half_even(p_lure * candidates.shape[0])
        lure_types = _type_indices(mt, n_lure, n_lures)
        chosen = sample(mt, candidates, n_lures)
        lures = np.empty((n_lures, 5), dtype=np.int64)
        others = np.empty(3, dtype=np.int64)
        for r in range(n_lures):
            index = chosen[r]
            truth = _direction_between(
                path[index, 0], path[index, 1], path[index + 1, 0], path[index + 1, 1]
            )
            n_others = 0
            for d in ordered:
                if d != truth:
                    others[n_others] = d
                    n_others += 1
            lures[r, 0] = lure_types[r]
            lures[r, 1] = index
            lures[r, 2] = others[choice_index(mt, 3)]
            lures[r, 3] = truth
            lures[r, 4] = 0

    traps = np.empty((0, 5), dtype=np.int64)
    if p_trap != 0 and n_trap > 0:
        mt[:] = seeded
        n_traps = _round_half_even(p_trap * n_int)
        positions = np.sort(sample(mt, np.arange(n_int), n_traps))
        trap_types = _type_indices(mt, n_trap, n_traps)
        traps = np.empty((n_traps, 5), dtype=np.int64)
        kept = np.ones(n_int, dtype=np.bool_)
        candidates = np.empty(4, dtype=np.int64)
        for r in range(n_traps):
            position = positions[n_traps - 1 - r]
            kept[position] = False
            index, truth = clues[position, 1], clues[position, 3]
            i, j = path[index, 0], path[index, 1]
            backward = _direction_between(i, j, path[index - 1, 0], path[index - 1, 1])
            n_candidates = 0
            for d in ordered:
                if d != truth and d != backward and not walls[i, j, d]:
                    candidates[n_candidates] = d
                    n_candidates += 1
            traps[r, 2] = candidates[randbelow(mt, n_candidates)]
            traps[r, 0] = trap_types[n_traps - 1 - r]
            traps[r, 1] = index
            traps[r, 3] = truth
            traps[r, 4] = n_candidates > 1
        clues = clues[kept]
    if n_clue == 0:
        clues = clues[:0]
    return walls, cells, intersections, clues, lures, traps


def _placed(kind: SignKind, types: tuple, rows: np.ndarray, solution: list) -> list[PlacedSign]:
    """``PlacedSign`` records of the kernel's sign rows (positional: this runs per sign)."""
    directions = _DIRECTIONS
    return [
        PlacedSign(
            kind,
            sign_index,
            types[sign_index],
            index,
            solution[index],
            directions[direction],
            directions[truth],
            undefined == 1,
        )
        for sign_index, index, direction, truth, undefined in rows.tolist()
    ]


def generate(spec: MazeSpec) -> MazeParts:
    """The parts of the maze of ``spec``, equal to :func:`amaze.maze.generation.generate`'s."""
    walls, cells, intersections, clues, lures, traps = _generate(
        seed_key(spec.seed),
        spec.width,
        spec.height,
        int(spec.start),
        spec.rotated,
        spec.unicursive,
        len(spec.clue),
        len(spec.lure),
        float(spec.p_lure or 0.0),
        len(spec.trap),
        float(spec.p_trap or 0.0),
    )
    points = list(map(tuple, cells.tolist()))
    solution = points[2:]
    return MazeParts(
        walls=walls,
        start=points[0],
        end=points[1],
        solution=solution,
        intersections=[(index, _DIRECTIONS[d]) for index, d in intersections.tolist()],
        clues=_placed(SignKind.CLUE, spec.clue, clues, solution),
        lures=_placed(SignKind.LURE, spec.lure, lures, solution),
        traps=_placed(SignKind.TRAP, spec.trap, traps, solution),
    )
