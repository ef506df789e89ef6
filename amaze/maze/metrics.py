"""Maze complexity metrics: surprisingness, deceptiveness, inseparability.

The metrics describe how hard a maze is for an agent that perceives the
discrete 8-value input of each cell (``docs/reference-behaviour.md`` §5.1 and §6):

* 4 wall slots (E, N, W, S), 1 for a wall and 0 for an opening; on a
  trajectory the side the agent came from reads 0.5 instead of 0;
* 4 sign slots: the lightness of the cell's sign in the slot of the direction
  it points to, 0 elsewhere (all 0 in a cell without a sign).

All entropies are in bits (base-2 logarithms). The numbers equal those of the
reference library amaze-benchmarker 1.0 (``Simulation.compute_metrics``) to
rounding, including its deceptiveness, whose quirks are documented in
:func:`deceptiveness`. :func:`invariant_deceptiveness` is the paper's
definition, which does not depend on the orientation of the maze.

Implementation: every input vector is packed into one small integer
(``wall code * radix + sign code``, where the wall code writes the 4 wall
slots in base 3 and the sign code numbers the (direction, lightness) pairs of
the maze) and the frequencies are counted with :func:`numpy.bincount`, so the
work per maze is a fixed number of array operations whatever its size.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import lru_cache
from itertools import chain
from math import log2
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

if TYPE_CHECKING:
    from amaze.maze.maze import Maze
    from amaze.maze.signs import Sign
    from amaze.maze.spec import MazeSpec

__all__ = [
    "SURPRISINGNESS_VARIANTS",
    "MazeMetrics",
    "compute_metrics",
    "deceptiveness",
    "inseparability",
    "invariant_deceptiveness",
    "mutual_information",
    "surprisingness",
]

#: The input sets :func:`surprisingness` can measure.
SURPRISINGNESS_VARIANTS: tuple[str, ...] = ("path", "all")

SurprisingnessVariant = Literal["path", "all"]

# Base-3 digits of a wall slot: open (input 0), the side the agent came from
# (input 0.5) and wall (input 1).
_OPEN, _ARRIVAL, _WALL = 0, 1, 2
_POW3 = np.array([1, 3, 9, 27], dtype=np.int64)
_N_WALL_CODES = 81

#: For each of the 81 wall codes: True when at most one slot reads exactly 1
#: (a wall), i.e. the reference's "intersection" class of a state.
_INTERSECTION = np.array(
    [sum((code // 3**d) % 3 == _WALL for d in range(4)) <= 1 for code in range(_N_WALL_CODES)]
)


# -- input encoding ----------------------------------------------------------


class _Encoded:
    """The inputs of one maze packed into integers (see the module docstring).

    Attributes: ``radix`` (number of sign codes), ``base`` (flat ``w*h`` array,
    the key of each cell's input without an arrival mark), ``opened`` (flat
    ``(w*h, 4)`` bool, True on open sides), ``path`` (flat indices of the
    solution cells), ``exits`` (direction of the move out of each solution cell,
    -1 at the goal), ``path_keys`` (the inputs along the optimal trajectory,
    arrival side marked), ``path_wall_codes`` (their wall part), ``sign_direction``
    (where the sign of each solution cell points, -1 without a sign) and the
    frequencies ``state_counts`` (of each path key) and ``config_counts`` (of
    each path wall code).
    """

    __slots__ = (
        "base",
        "config_counts",
        "exits",
        "opened",
        "path",
        "path_keys",
        "path_wall_codes",
        "radix",
        "sign_direction",
        "state_counts",
    )

    def __init__(self, maze: Maze) -> None:
        height = maze.walls.shape[1]
        walls = maze.walls.reshape(-1, 4)
        signs = maze.cell_signs
        direction = signs.direction.reshape(-1).astype(np.int64)
        signed = np.flatnonzero(direction >= 0)
        lightness = signs.value.reshape(-1)[signed]
        values = _sign_values(maze.spec.clue, maze.spec.lure, maze.spec.trap)
        index = np.searchsorted(values, lightness)
        if signed.size and (
            not values.size or not np.array_equal(values.take(index, mode="clip"), lightness)
        ):  # a sign whose value is not in the spec (a hand-made maze)
            values = np.unique(lightness)
            index = np.searchsorted(values, lightness)
        n_values = len(values)
        # Sign code: 0 without a sign, else 1 + direction * n_values + lightness index.
        sign_code = np.zeros(len(direction), dtype=np.int64)
        sign_code[signed] = 1 + direction[signed] * n_values + index
        self.radix = radix = 4 * n_values + 1
        wall_code = walls @ (_WALL * _POW3)
        self.base = wall_code * radix + sign_code
        self.opened = ~walls

        length = len(maze.solution)
        cells = np.fromiter(chain.from_iterable(maze.solution), np.int64, 2 * length)
        cells = cells.reshape(length, 2)
        self.path = path = cells[:, 0] * height + cells[:, 1]
        steps = cells[1:] - cells[:-1]
        # (1, 0) -> E=0, (0, 1) -> N=1, (-1, 0) -> W=2, (0, -1) -> S=3
        moves = np.where(steps[:, 0] != 0, 1 - steps[:, 0], 2 - steps[:, 1])
        exits = np.empty(length, dtype=np.int64)
        exits[:-1] = moves
        exits[-1] = -1
        self.exits = exits
        arrival = np.zeros(length, dtype=np.int64)
        arrival[1:] = _POW3[(moves + 2) % 4]
        self.path_wall_codes = wall_code[path] + arrival
        self.path_keys = self.base[path] + arrival * radix
        self.sign_direction = direction[path]
        self.state_counts = np.bincount(self.path_keys, minlength=self.n_keys)
        self.config_counts = np.bincount(self.path_wall_codes, minlength=_N_WALL_CODES)

    @property
    def n_keys(self) -> int:
        return _N_WALL_CODES * self.radix


@lru_cache(maxsize=1024)
def _sign_values(*kinds: tuple[Sign, ...]) -> np.ndarray:
    """The sorted distinct lightness values of some sign types (read-only)."""
    values = np.array(sorted({sign.value for signs in kinds for sign in signs}), dtype=np.float64)
    values.flags.writeable = False
    return values


def _entropy(counts: np.ndarray, total: int) -> float:
    """Shannon entropy (bits) of the empirical distribution given by ``counts``."""
    p = counts[counts > 0] / total
    return float(-(p * np.log2(p)).sum())


def _surprisingness_path(enc: _Encoded) -> tuple[float, int]:
    length = len(enc.path_keys)
    return _entropy(enc.state_counts, length), length


def _surprisingness_all(enc: _Encoded, unicursive: bool) -> tuple[float, int]:
    if unicursive:
        base, opened = enc.base[enc.path], enc.opened[enc.path]
    else:
        base, opened = enc.base, enc.opened
    # Every open side of every cell, in turn read as the arrival side ...
    keys = (base[:, None] + _POW3 * enc.radix)[opened]
    counts = np.bincount(keys, minlength=enc.n_keys)
    # ... plus the start cell as first seen (no arrival side).
    counts[enc.base[enc.path[0]]] += 1
    total = len(keys) + 1
    return _entropy(counts, total), total


def _conditional_terms(enc: _Encoded, costly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``-p(s|c) log2 p(s|c)`` of each distinct path state ``s`` with a positive cost.

    ``c`` is the wall part of ``s`` (walls and arrival mark). Returns the terms
    and, for each, whether ``c`` is in the reference's intersection class.
    """
    states = np.flatnonzero(np.bincount(enc.path_keys[costly], minlength=enc.n_keys))
    wall_codes = states // enc.radix
    p = enc.state_counts[states] / enc.config_counts[wall_codes]
    return -p * np.log2(p), _INTERSECTION[wall_codes]


def _deceptiveness(enc: _Encoded) -> float:
    # The reference reads the pointed direction as argmax of the sign slots,
    # which is EAST (0) in a cell without a sign, and gives the goal (no exit)
    # a cost of 1.
    pointed = np.maximum(enc.sign_direction, 0)
    terms, intersection = _conditional_terms(enc, pointed != enc.exits)
    entropy_intersections = float(terms[intersection].sum())
    entropy_corridors = float(terms[~intersection].sum())
    length = len(enc.path_keys)
    n_intersections = int(enc.config_counts[_INTERSECTION].sum())
    n_corridors = length - n_intersections
    return (n_intersections * entropy_corridors + n_corridors * entropy_intersections) / length


def _invariant_deceptiveness(enc: _Encoded) -> float:
    misleading = (enc.sign_direction >= 0) & (enc.sign_direction != enc.exits)
    terms, _ = _conditional_terms(enc, misleading)
    return float(terms.sum())


# -- public functions ----------------------------------------------------------


def surprisingness(maze: Maze, variant: SurprisingnessVariant = "path") -> float:
    """Entropy (bits) of the inputs an agent perceives in ``maze``.

    ``"path"`` is the paper's S(M): the inputs met along the optimal trajectory,
    start and goal cells included, each with its arrival side marked (except the
    start). High values mean that the agent keeps seeing new situations.
    ``"all"`` is the reference's all-cells variant: the start cell's input plus,
    for every cell (only the solution cells when the maze has no intersection)
    and every open side, the input with that side as the arrival side.
    """
    if variant not in SURPRISINGNESS_VARIANTS:
        raise ValueError(
            f"unknown surprisingness variant {variant!r} (expected one of "
            f"{', '.join(map(repr, SURPRISINGNESS_VARIANTS))})"
        )
    enc = _Encoded(maze)
    if variant == "path":
        return _surprisingness_path(enc)[0]
    return _surprisingness_all(enc, maze.unicursive)[0]


def deceptiveness(maze: Maze) -> float:
    """The reference's D; equals published numbers; NOT rotation invariant.

    This is exactly what amaze-benchmarker 1.0 computes (``docs/reference-behaviour.md``
    §6), quirks included, so that results can be compared with published ones:
    along the optimal trajectory a state costs 1 when the direction its sign
    slots point to differs from the correct move, where a cell without a sign
    counts as pointing EAST and the goal always costs 1; the conditional
    entropies of the costly states given their wall part are summed separately
    for intersection states (at most one slot reads 1) and corridor states, and
    each sum is weighted by the number of states of the *other* class, over the
    path length. The EAST convention makes the value depend on the orientation of
    the maze; :func:`invariant_deceptiveness` is the paper's definition.
    """
    return _deceptiveness(_Encoded(maze))


def invariant_deceptiveness(maze: Maze) -> float:
    """The paper's deceptiveness D(M) (bits), independent of the maze's orientation.

    ``D(M) = sum_c sum_{s: s[0:4] = c, cost(s) > 0} -p(s|c) log2 p(s|c)`` over the
    states ``s`` of the optimal trajectory (the 8-value inputs with the arrival
    side marked), where ``c`` is the wall part of a state and a state costs
    something only when its cell holds a lure or a trap, that is a sign that does
    not point the correct way. It measures how unpredictable the misleading signs
    are in situations that look alike. Rotating or mirroring the maze permutes
    the slots of every state the same way, so the value does not change (unlike
    :func:`deceptiveness`).
    """
    return _invariant_deceptiveness(_Encoded(maze))


def _spec_of(maze_or_spec: Maze | MazeSpec) -> MazeSpec:
    return getattr(maze_or_spec, "spec", maze_or_spec)


def inseparability(maze_or_spec: Maze | MazeSpec) -> float:
    """How hard it is to tell clues, lures and traps apart by their lightness (bits).

    The sign types (lures only with a lure probability, traps only with a trap
    probability) are sorted by value; neighbouring values of the same kind form
    one range and the boundary between two kinds lies halfway between their
    values, the ranges covering [0, 1]. The result is the entropy of the range
    widths, as in the reference (C1, L.25, T.5 gives 1.5613).
    """
    spec = _spec_of(maze_or_spec)
    lures = spec.lure if spec.p_lure else ()
    traps = spec.trap if spec.p_trap else ()
    return _inseparability(spec.clue, lures, traps)


@lru_cache(maxsize=1024)
def _inseparability(
    clues: tuple[Sign, ...], lures: tuple[Sign, ...], traps: tuple[Sign, ...]
) -> float:
    signs = [(s.value, kind) for kind, lst in enumerate((clues, lures, traps)) for s in lst]
    if not signs:
        return 0.0
    signs.sort(key=lambda pair: pair[0])  # stable: clues, lures, traps on ties
    first_value, first_kind = signs[0]
    ranges = [[0.0, first_value, first_kind]]  # [lower, upper, kind]
    for value, kind in signs[1:]:
        last = ranges[-1]
        if last[2] == kind:
            last[1] = value
        else:
            middle = 0.5 * (last[1] + value)
            last[1] = middle
            ranges.append([middle, value, kind])
    ranges[-1][1] = 1.0
    entropy = 0.0
    for lower, upper, _ in ranges:
        width = upper - lower
        if width > 0:
            entropy += -width * log2(width)
    return entropy


def mutual_information(maze_or_spec: Maze | MazeSpec) -> float:
    """The reference's "mutual information" between a sign's lightness and its truth (bits).

    Each distinct clue or trap value ``x`` is helpful (clue) or not (trap; a
    trap overrides a clue of the same value); ``P(x)`` is uniform and ``P(y)``
    is the total width of the halfway ranges (as in :func:`inseparability`)
    of the values of truth ``y``. The result is
    ``sum_x log2(1 / (P(x) P(truth(x))))``, as the reference computes it (C1 and
    T.5 give 4.415). It can exceed 1 bit: it is not a true mutual information.
    Lures are ignored.
    """
    spec = _spec_of(maze_or_spec)
    traps = spec.trap if spec.p_trap else ()
    return _mutual_information(spec.clue, traps)


@lru_cache(maxsize=1024)
def _mutual_information(clues: tuple[Sign, ...], traps: tuple[Sign, ...]) -> float:
    if not clues and not traps:
        return 0.0
    truth = {s.value: True for s in clues}
    truth.update((s.value, False) for s in traps)
    values = sorted(truth)
    n = len(values)
    p_truth = {True: 0.0, False: 0.0}
    for i, value in enumerate(values):
        lower = 0.0 if i == 0 else 0.5 * (value + values[i - 1])
        upper = 1.0 if i == n - 1 else 0.5 * (values[i + 1] + value)
        p_truth[truth[value]] += upper - lower
    p_value = 1 / n
    mi = 0.0
    for value in values:
        joint = p_value * p_truth[truth[value]]
        if joint:
            mi += log2(1 / joint)
    return mi


@dataclass(frozen=True)
class MazeMetrics:
    """All the complexity metrics of one maze (see :func:`compute_metrics`)."""

    #: The paper's S(M), over the optimal trajectory (:func:`surprisingness`, ``"path"``).
    surprisingness: float
    #: The all-cells variant (:func:`surprisingness`, ``"all"``).
    surprisingness_all: float
    #: The reference's D (:func:`deceptiveness`), orientation dependent.
    deceptiveness: float
    #: The paper's D(M) (:func:`invariant_deceptiveness`).
    invariant_deceptiveness: float
    inseparability: float
    mutual_information: float
    #: Number of inputs on the optimal trajectory (the path length).
    n_inputs_path: int
    #: Size of the all-cells input multiset.
    n_inputs_all: int

    def to_dict(self) -> dict[str, Any]:
        """The metrics as a flat ``{field name: value}`` dictionary (JSON friendly)."""
        return asdict(self)

    def to_reference_dict(self) -> dict[str, Any]:
        """The layout of the reference's ``Simulation.compute_metrics`` (string keys)."""
        return {
            "surprisingness": {"all": self.surprisingness_all, "path": self.surprisingness},
            "deceptiveness": self.deceptiveness,
            "inseparability": self.inseparability,
            "n_inputs": {"all": self.n_inputs_all, "path": self.n_inputs_path},
            "mutual_information": self.mutual_information,
        }


def compute_metrics(maze: Maze) -> MazeMetrics:
    """Every metric of ``maze`` at once (the inputs are encoded a single time)."""
    enc = _Encoded(maze)
    s_path, n_path = _surprisingness_path(enc)
    s_all, n_all = _surprisingness_all(enc, maze.unicursive)
    return MazeMetrics(
        surprisingness=s_path,
        surprisingness_all=s_all,
        deceptiveness=_deceptiveness(enc),
        invariant_deceptiveness=_invariant_deceptiveness(enc),
        inseparability=inseparability(maze),
        mutual_information=mutual_information(maze),
        n_inputs_path=n_path,
        n_inputs_all=n_all,
    )
