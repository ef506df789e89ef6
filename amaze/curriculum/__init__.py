"""Curricula: which mazes an agent meets, stage after stage.

* :mod:`~amaze.curriculum.interpolation`: the paper's interpolation regime,
  ``curriculum(end, n)`` from a trivial maze to a target.
"""

from amaze.curriculum.interpolation import InterpolationError, curriculum, interpolate

__all__ = ["InterpolationError", "curriculum", "interpolate"]
