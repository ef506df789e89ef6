"""Curricula: which mazes an agent meets, stage after stage.

* :mod:`~amaze.curriculum.interpolation`: the paper's interpolation regime,
  ``curriculum(end, n)`` from a trivial maze to a target;
* :mod:`~amaze.curriculum.regimes`: the regimes' names, and how a
  curriculum's budget is shared between stages and branches;
* :mod:`~amaze.curriculum.genome`: the maze genome of curators: mutation
  operators on maze strings (:class:`MazeGenome`), a difficulty order
  (:func:`difficulty`, :func:`harder_or_equal`) and a distance
  (:func:`maze_distance`);
* :mod:`~amaze.curriculum.curators`: the curator protocol and registry
  (:func:`make_curator`, :func:`curator_names`, plug-ins under the
  ``amaze.curators`` entry points); the curators themselves are in
  :mod:`~amaze.curriculum.strategies` (careful, moderate, risky, random,
  interpolation) and :mod:`~amaze.curriculum.human` (a person at a terminal).
"""

from amaze.curriculum.curators import (
    Candidate,
    Curator,
    CuratorContext,
    CuratorError,
    History,
    MazeResults,
    StageRecord,
    curator_names,
    make_curator,
)
from amaze.curriculum.difficulty import (
    DifficultyProfile,
    difficulty,
    difficulty_profile,
    harder_or_equal,
)
from amaze.curriculum.distance import maze_distance
from amaze.curriculum.genome import GenomeError, MazeGenome, SignSet
from amaze.curriculum.interpolation import InterpolationError, curriculum, interpolate
from amaze.curriculum.regimes import REGIMES, branch_allowance

__all__ = [
    "REGIMES",
    "Candidate",
    "Curator",
    "CuratorContext",
    "CuratorError",
    "DifficultyProfile",
    "GenomeError",
    "History",
    "InterpolationError",
    "MazeGenome",
    "MazeResults",
    "SignSet",
    "StageRecord",
    "branch_allowance",
    "curator_names",
    "curriculum",
    "difficulty",
    "difficulty_profile",
    "harder_or_equal",
    "interpolate",
    "make_curator",
    "maze_distance",
]
