"""What a fixed-topology network of either trainer reads: turned inputs and a pooled retina.

Evolution's networks (:mod:`evolution.networks`) and the RL learners' shared
network kind (:mod:`rl_baselines.jax.spec`) read a robot's observation the same
way, so that one network spec means one network in both trainers:

* **pooled retina**: an image robot's ``v x v`` uint8 image reduced over a
  ``pool x pool`` grid of blocks (edges ``floor(linspace(0, v, pool + 1) +
  0.5)``), pixels scaled to [0, 1]: each block's mean (``pooling = "mean"``)
  or its brightest pixel (``"max"``: a sign's lightness whatever the width of
  its strokes); ``"mean-ring"`` and ``"max-ring"`` keep the image's outermost
  ring of pixels in blocks of their own (the grid's outer blocks, one pixel
  deep) and pool the inside over the inner ``pool - 2`` blocks (edges ``[0,
  *floor(linspace(1, v - 1, pool - 1) + 0.5), v]``): a hybrid robot's cell
  image holds its walls and the arrival marker in that ring and its sign
  inside, and plain blocks mix a sign's outermost pixels with them
  (:func:`pooling_problem`); discrete-input robots read their 8 floats;
* **convolution**: ``filters`` 3x3 filters slid over the image with a
  ``stride`` that tiles it (:func:`stride_problem`, :func:`default_stride`),
  ``grid x grid`` positions (:func:`grid_side`), pixels scaled to [0, 1];
* **rotations**: with ``symmetry = "rotations"`` the logit of direction ``d``
  is the network's single output on the inputs turned ``d`` quarter-turns
  clockwise, gathered by :func:`rotation_index`.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ACTIVATIONS",
    "DEFAULT_POOL",
    "FILTER_SIDE",
    "MAX_FILTERS",
    "POOLINGS",
    "SYMMETRIES",
    "default_stride",
    "grid_side",
    "pool_blocks",
    "pool_edges",
    "pool_matrix",
    "pooling_problem",
    "pools_maxima",
    "rotation_index",
    "stride_problem",
]

#: Hidden-layer activations of the fixed-topology networks.
ACTIVATIONS: tuple[str, ...] = ("tanh", "relu", "sigmoid", "identity")
#: Weight sharing across directions.
SYMMETRIES: tuple[str, ...] = ("none", "rotations")
#: Default side of the pooled grid of image robots.
DEFAULT_POOL = 5
#: How the pooled grid is laid out and a block reduced (the first is the default):
#: block means or maxima, over even blocks or with the image's outer ring apart.
POOLINGS: tuple[str, ...] = ("mean", "max", "mean-ring", "max-ring")
#: The poolings that keep the image's outermost ring of pixels in blocks of their own.
RING_POOLINGS: tuple[str, ...] = ("mean-ring", "max-ring")
#: Side of a convolution's filter.
FILTER_SIDE = 3
#: Most filters a network may have (a sanity bound).
MAX_FILTERS = 64


def default_stride(vision: int) -> int:
    """The largest stride of 3, 2 and 1 that tiles a ``vision``-pixel retina."""
    return next(s for s in (3, 2, 1) if (vision - FILTER_SIDE) % s == 0)


def stride_problem(stride: int, vision: int) -> str | None:
    """Why ``stride`` (1 to 3) does not tile a ``vision``-pixel retina, or None when it does."""
    if (vision - FILTER_SIDE) % stride == 0:
        return None
    fitting = " or ".join(str(s) for s in (3, 2, 1) if (vision - FILTER_SIDE) % s == 0)
    return (
        f"stride {stride} does not tile a retina of {vision} pixels"
        f" ({vision} - {FILTER_SIDE} is not a multiple of it): give {fitting}"
    )


def grid_side(vision: int, stride: int) -> int:
    """Side of a feature map: positions of a filter along one axis of the retina."""
    return (vision - FILTER_SIDE) // stride + 1


def rotation_index(side: int | None) -> np.ndarray:
    """int64 ``(4, n)``: row ``d`` gathers the inputs of the cell turned ``d`` times clockwise.

    ``side`` None: the 8 inputs of DD robots (4 walls, then 4 signs, E, N, W,
    S), each group shifted cyclically; else a ``side x side`` image (row 0
    north), turned by ``np.rot90(grid, -d)``. After the gather, side ``d`` of
    the cell lies east.
    """
    if side is None:
        sides = np.array([[(d + j) % 4 for j in range(4)] for d in range(4)], dtype=np.int64)
        return np.concatenate([sides, sides + 4], axis=1)
    grid = np.arange(side * side, dtype=np.int64).reshape(side, side)
    return np.stack([np.rot90(grid, -d).ravel() for d in range(4)])


def pools_maxima(pooling: str) -> bool:
    """Whether ``pooling`` (one of :data:`POOLINGS`) reduces a block to its brightest pixel."""
    return pooling in ("max", "max-ring")


def pooling_problem(pooling: object, pool: int | None) -> str | None:
    """Why ``pooling`` cannot pool a grid of side ``pool``, or None when it can.

    ``pooling`` must be one of :data:`POOLINGS`; a ring pooling needs a grid of
    at least 3 blocks a side (the ring's two and one inside).
    """
    if pooling not in POOLINGS:
        return f"pooling {pooling!r} is not one of {', '.join(POOLINGS)}"
    if pooling in RING_POOLINGS and pool is not None and pool < 3:
        return (
            f"pooling {pooling!r} with pool {pool}: the ring takes the grid's outer blocks,"
            " so its side must be at least 3"
        )
    return None


def pool_edges(vision: int, pool: int, pooling: str = POOLINGS[0]) -> np.ndarray:
    """Block edges of the pooled grid along one image axis (``pool + 1`` integers).

    Even blocks, or with a ring pooling the outermost pixel on each side alone
    and the ``vision - 2`` inside over ``pool - 2`` blocks.
    """
    if pooling in RING_POOLINGS:
        inside = np.floor(np.linspace(1.0, vision - 1.0, pool - 1) + 0.5).astype(np.int64)
        return np.concatenate([[0], inside, [vision]]).astype(np.int64)
    return np.floor(np.linspace(0.0, vision, pool + 1) + 0.5).astype(np.int64)


def pool_matrix(vision: int, pool: int, pooling: str = POOLINGS[0]) -> np.ndarray:
    """float64 ``(vision * vision, pool * pool)``: pixels (row-major) to their block's mean / 255.

    ``images.reshape(n, -1) @ pool_matrix(v, p)`` is the pooled retina, cell
    ``r * pool + c`` the mean of block ``(r, c)`` scaled to [0, 1]; ``pooling``
    lays out the blocks (:func:`pool_edges`).
    """
    edges = pool_edges(vision, pool, pooling)
    matrix = np.zeros((vision, vision, pool, pool), dtype=np.float64)
    for r in range(pool):
        for c in range(pool):
            rows, cols = slice(edges[r], edges[r + 1]), slice(edges[c], edges[c + 1])
            count = (edges[r + 1] - edges[r]) * (edges[c + 1] - edges[c])
            matrix[rows, cols, r, c] = 1.0 / (255.0 * count)
    return matrix.reshape(vision * vision, pool * pool)


def pool_blocks(vision: int, pool: int, pooling: str = POOLINGS[0]) -> np.ndarray:
    """int64 ``(pool * pool, m)``: the pixels (row-major indices) of each block of the grid.

    Row ``r * pool + c`` lists block ``(r, c)``'s pixels, padded to the largest
    block's ``m`` by repeating its first pixel, so that
    ``images.reshape(n, -1)[:, pool_blocks(v, p)].max(axis=-1) / 255`` is the
    max-pooled retina (a repeated pixel does not change a maximum); ``pooling``
    lays out the blocks (:func:`pool_edges`).
    """
    edges = pool_edges(vision, pool, pooling)
    grid = np.arange(vision * vision, dtype=np.int64).reshape(vision, vision)
    blocks = [
        grid[edges[r] : edges[r + 1], edges[c] : edges[c + 1]].ravel()
        for r in range(pool)
        for c in range(pool)
    ]
    width = max(block.size for block in blocks)
    return np.stack([np.pad(b, (0, width - b.size), constant_values=b[0]) for b in blocks])
