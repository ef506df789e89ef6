"""Deprecated: the old name of :mod:`amaze.curriculum.maze_population`.

Importing it issues a :class:`DeprecationWarning` and gives the public names
of :mod:`amaze.curriculum.maze_population`; the old name goes in the next
release. Checkpoints that name its classes are read as the new module's
(:data:`amaze.runs.state_document.RENAMED_MODULES`).
"""

from __future__ import annotations

import warnings

from amaze.curriculum.maze_population import (
    DESCRIPTOR_SCALES,
    MAZES_CSV_FIELDS,
    SCORES,
    BatchMaze,
    CoevolutionError,
    GenerationReport,
    MazePopulation,
    MazePopulationConfig,
    MazeRecord,
    MazeResult,
    descriptor,
    mazes_csv,
    options_from_dict,
    rank_weights,
    replay_distribution,
    staleness_weights,
)

__all__ = [
    "DESCRIPTOR_SCALES",
    "MAZES_CSV_FIELDS",
    "SCORES",
    "BatchMaze",
    "CoevolutionError",
    "GenerationReport",
    "MazePopulation",
    "MazePopulationConfig",
    "MazeRecord",
    "MazeResult",
    "descriptor",
    "mazes_csv",
    "options_from_dict",
    "rank_weights",
    "replay_distribution",
    "staleness_weights",
]

warnings.warn(
    "amaze.curriculum.coevolution is renamed amaze.curriculum.maze_population;"
    " the old name goes in the next release",
    DeprecationWarning,
    stacklevel=2,
)
