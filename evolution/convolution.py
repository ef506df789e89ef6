"""A convolutional feature stage for image robots: a few 3x3 filters shared across the retina.

A network with ``filters = F`` (:class:`~evolution.networks.NetworkSpec`)
reads its ``v x v`` image through ``F`` evolved 3x3 filters, each with a bias,
slid over the retina with ``stride`` ``s`` (no padding) and followed by the
network's activation: ``F`` feature maps of ``g x g``, ``g = (v - 3) / s + 1``,
which are the dense layers' inputs (``F g^2`` of them, filter-major). Pixels
are scaled to [0, 1]. The stride must tile the retina (``(v - 3) % s == 0``),
so that no pixel row is left out and the grid is the same seen from every
side; the default is the largest of 3, 2, 1 that does (``H15``: 3, five
non-overlapping 3x3 blocks a side, where the pooled network averages the same
blocks; ``H11``: 2, a 5 x 5 grid of overlapping blocks). Where pooling gives
each block one fixed summary (its mean), a filter learns what to look for in
it (an arrow's head, a corner of wall), the same everywhere.

**Symmetry.** With ``symmetry = "rotations"`` the network scores each
direction ``d`` on the image turned ``d`` quarter-turns clockwise
(:mod:`evolution.networks`). Turning the image commutes with the convolution
if the filters turn the other way: ``conv(T_d(I), w) = T_d(conv(I, T_d^-1(w)))``
on a grid that tiles the retina. So the kernel convolves the image once with
the ``4 F`` turned filters (:func:`turned_filters`), and the inputs of
direction ``d`` are a gather of those maps (:func:`feature_turns`): exactly the
features of the turned image, at the cost of one convolution.

**Cost.** ``F g^2 x 9`` multiply-adds per agent and step (``4 F g^2 x 9``
with rotations), in float32, before the dense layers; the dense layers then
have ``F g^2`` inputs instead of the pooled ``pool^2``.
"""

from __future__ import annotations

import numba
import numpy as np

from amaze.agents.network_inputs import (
    FILTER_SIDE,
    MAX_FILTERS,
    default_stride,
    grid_side,
    stride_problem,
)
from amaze.validation import check_integer
from evolution import EvolutionConfigError
from evolution.activations import activate

__all__ = [
    "FILTER_SIDE",
    "MAX_FILTERS",
    "check_stride",
    "convolve",
    "default_stride",
    "feature_turns",
    "grid_side",
    "turned_filters",
]


def check_stride(stride: object, vision: int) -> int:
    """``stride`` checked: 1 to 3 (no pixel skipped), tiling the ``vision``-pixel retina."""
    stride = check_integer("stride", stride, minimum=1, maximum=3, error=EvolutionConfigError)
    problem = stride_problem(stride, vision)
    if problem:
        raise EvolutionConfigError(problem)
    return stride


def turned_filters(weights: np.ndarray, biases: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The filters of each individual in their 4 turns: ``(P, 4 F, 9)`` and ``(P, 4 F)``.

    Filter ``d F + f`` is filter ``f`` turned ``d`` quarter-turns
    anticlockwise (``np.rot90(w, d)``, the inverse of the image's turn for
    direction ``d``); ``weights`` is ``(P, F, 9)`` (row-major 3 x 3), ``biases``
    ``(P, F)``.
    """
    p, f = weights.shape[:2]
    square = weights.reshape(p, f, FILTER_SIDE, FILTER_SIDE)
    turned = [np.rot90(square, d, axes=(2, 3)).reshape(p, f, -1) for d in range(4)]
    return (
        np.ascontiguousarray(np.concatenate(turned, axis=1), dtype=np.float32),
        np.ascontiguousarray(np.tile(biases, (1, 4)), dtype=np.float32),
    )


def feature_turns(filters: int, side: int) -> np.ndarray:
    """int64 ``(4, F g^2)``: the inputs of direction ``d``, gathered from the turned filters' maps.

    Input ``f g^2 + q`` of direction ``d`` (filter ``f`` at position ``q`` of
    the turned image) is the map of filter ``d F + f`` at the position ``q``
    comes from when the grid turns ``d`` times clockwise
    (``np.rot90(grid, -d)``).
    """
    grid = np.arange(side * side, dtype=np.int64).reshape(side, side)
    cells = side * side
    rows = []
    for d in range(4):
        turned = np.rot90(grid, -d).ravel()
        rows.append(np.concatenate([(d * filters + f) * cells + turned for f in range(filters)]))
    return np.stack(rows)


@numba.njit(cache=True, error_model="numpy")
def _convolve_agent(images, k, p, weights, biases, stride, side, activation, patch, out):
    """The feature maps of agent ``k`` with the filters of individual ``p`` (``patch``: room
    for one 3 x 3 patch)."""
    n_filters = weights.shape[1]
    scale = np.float32(1.0 / 255.0)
    for gi in range(side):
        for gj in range(side):
            r0, c0 = gi * stride, gj * stride
            for a in range(FILTER_SIDE):
                for b in range(FILTER_SIDE):
                    patch[a * FILTER_SIDE + b] = np.float32(images[k, r0 + a, c0 + b]) * scale
            q = gi * side + gj
            for e in range(n_filters):
                total = biases[p, e]
                for t in range(FILTER_SIDE * FILTER_SIDE):
                    total += weights[p, e, t] * patch[t]
                out[k, e * side * side + q] = activate(total, activation)


@numba.njit(cache=True, error_model="numpy")
def _convolve_serial(images, rows, m, weights, biases, stride, side, activation, out):
    patch = np.empty(FILTER_SIDE * FILTER_SIDE, dtype=np.float32)
    for j in range(rows.shape[0]):
        k = rows[j]
        _convolve_agent(images, k, k // m, weights, biases, stride, side, activation, patch, out)


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _convolve_parallel(images, rows, m, weights, biases, stride, side, activation, out):
    for j in numba.prange(rows.shape[0]):
        k = rows[j]
        patch = np.empty(FILTER_SIDE * FILTER_SIDE, dtype=np.float32)
        _convolve_agent(images, k, k // m, weights, biases, stride, side, activation, patch, out)


def convolve(
    images: np.ndarray,
    rows: np.ndarray,
    m: int,
    weights: np.ndarray,
    biases: np.ndarray,
    stride: int,
    activation: int,
    out: np.ndarray,
    *,
    parallel: bool = False,
) -> None:
    """Fill ``out[k]`` (float32 ``(n, E g^2)``) with the feature maps of the agents ``rows``.

    ``images``: uint8 ``(n, v, v)``; agent ``k`` belongs to individual
    ``k // m``, whose ``E`` filters are ``weights[p]`` (float32 ``(E, 9)``)
    and ``biases[p]``; ``activation`` is a code of
    :data:`~evolution.activations.ACTIVATION_CODES`. Rows not listed are left
    as they are.
    """
    side = grid_side(images.shape[1], stride)
    kernel = _convolve_parallel if parallel else _convolve_serial
    kernel(images, rows, m, weights, biases, stride, side, activation, out)
