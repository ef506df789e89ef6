"""A distance between mazes, for novelty: :func:`maze_distance`.

A metric on maze specs, a sum of per-field terms in [0, 1] (a small
constant, :data:`SEED_DISTANCE`, when only the seeds differ), and optionally
of their metrics (Surprisingness, Deceptiveness).
"""

from __future__ import annotations

import math
from functools import lru_cache

from amaze.curriculum.mutations import GenomeError, as_spec
from amaze.maze.maze import Maze
from amaze.maze.metrics import compute_metrics
from amaze.maze.signs import Sign, SignKind
from amaze.maze.spec import MAX_SIZE, MIN_SIZE, MazeSpec, StartLocation
from amaze.validation import check_number

__all__ = ["SEED_DISTANCE", "distance_components", "maze_distance"]

MazeLike = MazeSpec | Maze | str

#: The distance between two mazes that differ only in their seed.
SEED_DISTANCE = 0.1
#: What two signs at the same position differ by when their shapes differ.
SHAPE_DISTANCE = 0.5
#: What a sign differs by from no sign (a sign list shorter than the other).
MISSING_SIGN_DISTANCE = 1.0

_LOG_SIZE_RANGE = math.log(MAX_SIZE / MIN_SIZE)


def _signs_distance(a: tuple[Sign, ...], b: tuple[Sign, ...]) -> float:
    total = 0.0
    for k in range(max(len(a), len(b))):
        if k >= len(a) or k >= len(b):
            total += MISSING_SIGN_DISTANCE
        else:
            total += abs(a[k].value - b[k].value) + SHAPE_DISTANCE * (a[k].shape != b[k].shape)
    return min(total, 1.0)


def _log_gap(a: int, b: int) -> float:
    return abs(math.log(a) - math.log(b))


def _corner_bits(start: StartLocation) -> tuple[bool, bool]:
    east = start in (StartLocation.SOUTH_EAST, StartLocation.NORTH_EAST)
    north = start in (StartLocation.NORTH_EAST, StartLocation.NORTH_WEST)
    return east, north


@lru_cache(maxsize=4096)
def _metric_point(spec: MazeSpec) -> tuple[float, float]:
    metrics = compute_metrics(Maze.generate(spec))
    return metrics.surprisingness, metrics.invariant_deceptiveness


def distance_components(
    a: MazeLike, b: MazeLike, *, metrics_weight: float = 0.0
) -> dict[str, float]:
    """The terms of :func:`maze_distance`, by name (each a metric or pseudometric, >= 0)."""
    weight = check_number("metrics_weight", metrics_weight, minimum=0, error=GenomeError)
    x, y = as_spec(a), as_spec(b)
    (xe, xn), (ye, yn) = _corner_bits(x.start), _corner_bits(y.start)
    terms = {
        # differences of logarithms (not the logarithm of a ratio): exactly symmetric
        "size": (_log_gap(x.width, y.width) + _log_gap(x.height, y.height)) / (2 * _LOG_SIZE_RANGE),
        "start": ((xe != ye) + (xn != yn)) / 2,
        "rotated": float(x.rotated != y.rotated),
        "unicursive": float(x.unicursive != y.unicursive),
        **{k.value: _signs_distance(getattr(x, k.value), getattr(y, k.value)) for k in SignKind},
        "p_lure": abs((x.p_lure or 0.0) - (y.p_lure or 0.0)),
        "p_trap": abs((x.p_trap or 0.0) - (y.p_trap or 0.0)),
        "seed": SEED_DISTANCE * (x.seed != y.seed),
    }
    if weight:
        (sx, dx), (sy, dy) = _metric_point(x), _metric_point(y)
        terms["metrics"] = weight * (abs(sx - sy) + abs(dx - dy))
    return terms


def maze_distance(a: MazeLike, b: MazeLike, *, metrics_weight: float = 0.0) -> float:
    """A distance between maze strings, field by field, for novelty among curated mazes.

    The sum of per-field terms, each in [0, 1] (so roughly "how many fields
    differ"):

    * ``size``: ``(|ln w_a - ln w_b| + |ln h_a - ln h_b|) / (2 ln(100/2))``;
      relative, as going from 5 to 10 cells changes a maze as much as from
      50 to 100;
    * ``start``: half the number of axes (east-west, south-north) on which the
      corners differ: 1/2 for a neighbouring corner, 1 for the opposite one;
    * ``rotated``, ``unicursive``: 1 when the flags differ;
    * ``clue``, ``lure``, ``trap``: 1 when one maze has that kind and the other
      not; otherwise, sign by sign in the list's order, the difference of
      lightness plus 1/2 when the shapes differ (1 per sign one list has
      beyond the other), capped at 1;
    * ``p_lure``, ``p_trap``: the difference of probabilities (0 without the kind);
    * ``seed``: :data:`SEED_DISTANCE` (0.1) when the seeds differ. Another
      seed gives other walls but the same family of mazes: different, yet
      closer than any change of the description that is not small;
    * with ``metrics_weight > 0``: that weight times the differences of
      Surprisingness and (invariant) Deceptiveness in bits
      (``|S_a - S_b| + |D_a - D_b|``); the mazes are generated for it (once
      per spec, cached).

    Each term is a metric or a pseudometric on specs and together they
    separate specs, so the sum is a metric on maze specifications: symmetric,
    zero exactly for the same spec, and it satisfies the triangle inequality.
    Dormant clues and traps of a unicursive maze count, as they act again when
    intersections are turned on.

    >>> maze_distance("M4_10x10_C1", "M5_10x10_C1")  # another seed
    0.1
    >>> round(maze_distance("M4_10x10_C1", "M4_20x20_C1"), 3)  # twice the size
    0.177
    >>> maze_distance("M4_10x10_C1", "M4_10x10_NE_C1")  # the opposite corner
    1.0
    >>> maze_distance("M4_10x10_C1", "M4_10x10_C1_l.25_L.25")  # lures (1) at p = 0.25
    1.25
    """
    return math.fsum(distance_components(a, b, metrics_weight=metrics_weight).values())
