"""Curricula: which mazes an agent meets, stage after stage.

* :mod:`~amaze.curriculum.interpolation`: the paper's interpolation regime,
  ``curriculum(end, n)`` from a trivial maze to a target;
* :mod:`~amaze.curriculum.regimes`: the regimes as stage lists for any
  trainer, and how a budget is shared between stages.
"""

from amaze.curriculum.interpolation import InterpolationError, curriculum, interpolate
from amaze.curriculum.regimes import REGIMES, Stage, regime_stages, stage_end

__all__ = [
    "REGIMES",
    "InterpolationError",
    "Stage",
    "curriculum",
    "interpolate",
    "regime_stages",
    "stage_end",
]
