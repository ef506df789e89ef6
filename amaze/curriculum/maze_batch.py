"""One generation's batch of a co-evolved maze population, and what comes back from it.

The values :class:`~amaze.curriculum.maze_population.MazePopulation` and a
run's loop pass each other once a generation: the batch's mazes
(:class:`BatchMaze`, from ``propose``), how the agents fared on each
(:class:`MazeResult`, given to ``update``) and what ``update`` did
(:class:`GenerationReport`). They live only within a generation, never in a
checkpoint; :mod:`amaze.curriculum.maze_population` gives them too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amaze.curriculum.replay import CoevolutionError

__all__ = ["BatchMaze", "GenerationReport", "MazeResult"]


@dataclass(frozen=True)
class BatchMaze:
    """One maze of a generation's batch: a replayed member or a new maze."""

    maze: str
    member: int | None = None  # the record id of a replayed member
    parent: int | None = None  # the record id a mutant comes from
    origin: str = "replay"  # replay, mutant or family


@dataclass(frozen=True)
class MazeResult:
    """How the agent population fared on one batch maze (all agents, 4 rotations each).

    ``success_rate`` and ``normalized_reward`` are means over every episode,
    ``best_normalized_reward`` the best agent's mean R̄ over its rotations,
    ``solved`` whether any episode reached the goal.
    """

    success_rate: float
    normalized_reward: float
    best_normalized_reward: float
    solved: bool

    @classmethod
    def of(cls, success: np.ndarray, reward: np.ndarray) -> MazeResult:
        """From ``(agents, rotations)`` arrays of successes and R̄."""
        success = np.asarray(success, dtype=np.float64)
        reward = np.asarray(reward, dtype=np.float64)
        if success.ndim != 2 or success.shape != reward.shape or success.size == 0:
            raise CoevolutionError(
                f"results of shapes {success.shape} and {reward.shape}:"
                " give (agents, rotations) arrays"
            )
        return cls(
            success_rate=float(success.mean()),
            normalized_reward=float(reward.mean()),
            best_normalized_reward=float(reward.mean(axis=1).max()),
            solved=bool(success.any()),
        )


@dataclass
class GenerationReport:
    """What one ``MazePopulation.update`` did (a few columns of ``progress.csv``)."""

    replayed: int = 0
    new: int = 0
    admitted: int = 0
    retired: int = 0
    batch_difficulty: float = 0.0
    batch_score: float = 0.0
