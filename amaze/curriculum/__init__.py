"""Curricula: which mazes an agent meets, stage after stage.

* :mod:`~amaze.curriculum.interpolation`: the paper's interpolation regime,
  ``curriculum(end, n)`` from a trivial maze to a target;
* :mod:`~amaze.curriculum.regimes`: the regimes' names, and how a
  curriculum's budget is shared between stages and branches;
* :mod:`~amaze.curriculum.genome`: the maze genome of curators: mutation
  operators on maze strings (:class:`MazeGenome`), a difficulty order
  (:func:`difficulty`, :func:`harder_or_equal`) and a distance
  (:func:`maze_distance`).
"""

from amaze.curriculum.genome import (
    DifficultyProfile,
    GenomeError,
    MazeGenome,
    SignSet,
    difficulty,
    difficulty_profile,
    harder_or_equal,
    maze_distance,
)
from amaze.curriculum.interpolation import InterpolationError, curriculum, interpolate
from amaze.curriculum.regimes import REGIMES, branch_allowance

__all__ = [
    "REGIMES",
    "DifficultyProfile",
    "GenomeError",
    "InterpolationError",
    "MazeGenome",
    "SignSet",
    "branch_allowance",
    "curriculum",
    "difficulty",
    "difficulty_profile",
    "harder_or_equal",
    "interpolate",
    "maze_distance",
]
