"""Cardinal directions and their grid offsets.

Directions are numbered as in the reference library and the paper:
EAST=0, NORTH=1, WEST=2, SOUTH=3 ("direct order"). Cell ``(i, j)`` has
``i`` growing east and ``j`` growing north; ``(0, 0)`` is the south-west corner.
"""

from __future__ import annotations

import operator
from enum import IntEnum
from typing import Any

import numpy as np

from amaze.errors import ActionError

#: A maze cell ``(i, j)``; ``(0, 0)`` is the south-west corner, ``i`` grows east.
Cell = tuple[int, int]


class Direction(IntEnum):
    """One of the four cardinal directions, in the reference's order."""

    EAST = 0
    NORTH = 1
    WEST = 2
    SOUTH = 3

    @property
    def opposite(self) -> Direction:
        """The direction pointing the other way."""
        return Direction((self + 2) % 4)

    @property
    def offset(self) -> tuple[int, int]:
        """The ``(di, dj)`` step towards the neighbouring cell."""
        return OFFSETS[self]


#: ``OFFSETS[d]`` is the ``(di, dj)`` step of direction ``d``.
OFFSETS: tuple[tuple[int, int], ...] = ((1, 0), (0, 1), (-1, 0), (0, -1))

#: The same offsets as an ``int64`` array of shape ``(4, 2)``.
OFFSETS_ARRAY = np.array(OFFSETS, dtype=np.int64)

_FROM_OFFSET = {offset: Direction(d) for d, offset in enumerate(OFFSETS)}


def direction_between(a: tuple[int, int], b: tuple[int, int]) -> Direction:
    """The direction of the step from cell ``a`` to its neighbour ``b``."""
    try:
        return _FROM_OFFSET[(b[0] - a[0], b[1] - a[1])]
    except KeyError:
        raise ValueError(f"cells {tuple(a)} and {tuple(b)} are not neighbours") from None


def discrete_action(action: Any) -> int:
    """``action`` as a direction 0..3; anything else (bools, floats, 4...) is an error.

    Python and numpy integers are accepted; the error is an
    :class:`~amaze.errors.ActionError` (an ``AmazeError``) naming the bad action.
    """
    try:
        direction = operator.index(action)
    except TypeError:
        direction = -1
    if direction not in (0, 1, 2, 3) or isinstance(action, bool):
        raise ActionError(f"discrete action {action!r} is not one of 0, 1, 2, 3 (E, N, W, S)")
    return direction
