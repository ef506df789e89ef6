"""Continuous actions: one contract for the Simulation, the engine and the environments.

A continuous robot is told an acceleration ``(ax, ay)``; its action space is
``Box(-1, 1, (2,))`` (``docs/reference-behaviour.md`` §4.4). Every entry point
(:class:`~amaze.agents.simulation.Simulation`, ``AMaze-v0``, the
:class:`~amaze.agents.engine.BatchEngine` and the native vector env) applies
the same rules:

* a finite value outside [-1, 1] is clipped per component, as gymnasium's
  ``ClipAction`` wrapper would: any finite float, ``1e308`` included, is a legal
  action, and an action inside the box is used as it is;
* a NaN or an infinity raises :class:`~amaze.errors.ActionError` naming the
  agent and the value. It is always a bug upstream (a diverged network, say),
  and replacing it silently would hide that bug;
* anything else than two real numbers per agent (a wrong shape, strings,
  booleans, complex numbers, objects) raises the same error.

The reference clipped nothing: an acceleration of ``1e6`` moved its robot
thousands of cells in one step, out of the maze, and crashed it with an
``IndexError`` (in compiled code, such an index is a segmentation fault).
Within [-1, 1] the robot moves less than its radius per step, so the wall
handling keeps it inside the maze.

Discrete actions (``0..3`` = E, N, W, S) are checked by
:func:`amaze.maze.directions.discrete_action` and, in the engine, by its
kernels; they raise :class:`~amaze.errors.ActionError` too.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from amaze.errors import ActionError

__all__ = [
    "MAX_ACCELERATION",
    "clip_acceleration",
    "continuous_action",
    "continuous_actions",
    "non_finite_actions_message",
]

#: Accelerations are clipped to ``[-MAX_ACCELERATION, MAX_ACCELERATION]`` (the action space).
MAX_ACCELERATION = 1.0

#: How many offending agents an error message lists.
_SHOWN = 10

#: numpy dtype kinds that hold real numbers (signed, unsigned, float): no bool, complex, object.
_REAL_KINDS = "iuf"

_NOT_FINITE = (
    "a NaN or an infinity is a bug upstream (a diverged network?), finite values are"
    f" clipped to [-{MAX_ACCELERATION:g}, {MAX_ACCELERATION:g}]"
)


def clip_acceleration(value: float) -> float:
    """A finite acceleration component clipped to the action space [-1, 1]."""
    return min(max(value, -MAX_ACCELERATION), MAX_ACCELERATION)


def _describe(value: Any) -> str:
    """A short ``repr`` of a bad action for an error message."""
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def continuous_action(action: Any) -> tuple[float, float]:
    """One agent's acceleration ``(ax, ay)``, checked and clipped to [-1, 1].

    ``action`` is any array-like of two real numbers (shape ``(2,)``: a list, a
    tuple, a numpy array of any real dtype). Raises :class:`ActionError` for
    another shape or type and for a NaN or an infinity.
    """
    try:
        array = np.asarray(action)
    except (TypeError, ValueError):
        array = None
    if array is None or array.dtype.kind not in _REAL_KINDS or array.shape != (2,):
        kind = "" if array is None else f" (shape {array.shape}, dtype {array.dtype})"
        raise ActionError(
            f"continuous action {_describe(action)}{kind} is not an acceleration (ax, ay):"
            " expected 2 real numbers"
        )
    ax, ay = float(array[0]), float(array[1])
    if not (math.isfinite(ax) and math.isfinite(ay)):
        raise ActionError(f"continuous action ({ax!r}, {ay!r}) is not finite; {_NOT_FINITE}")
    return clip_acceleration(ax), clip_acceleration(ay)


def continuous_actions(actions: Any, n_agents: int) -> np.ndarray:
    """The accelerations of ``n_agents`` agents as a float64 ``(n_agents, 2)`` array.

    Checks the shape and the type only: the batch engine checks finiteness and
    clips in its kernels, in the same pass that steps the agents (an array is
    returned as it is when it is already float64). Raises :class:`ActionError`.
    """
    try:
        array = np.asarray(actions)
    except (TypeError, ValueError):
        array = None
    if array is None or array.dtype.kind not in _REAL_KINDS or array.shape != (n_agents, 2):
        kind = (
            f"{type(actions).__name__}" if array is None else f"shape {array.shape} {array.dtype}"
        )
        raise ActionError(
            f"continuous actions must be {n_agents} accelerations, real numbers of shape"
            f" ({n_agents}, 2), got {kind}"
        )
    return array if array.dtype == np.float64 else array.astype(np.float64)


def non_finite_actions_message(actions: np.ndarray) -> str:
    """The error message naming the agents whose acceleration holds a NaN or an infinity."""
    bad = np.flatnonzero(~np.isfinite(actions).all(axis=1))
    more = f" (and {bad.size - _SHOWN} more)" if bad.size > _SHOWN else ""
    shown = bad[:_SHOWN]
    return (
        f"continuous actions must be finite: agents {shown.tolist()} got"
        f" {actions[shown].tolist()}{more}; {_NOT_FINITE}"
    )
