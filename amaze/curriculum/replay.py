"""The replay distribution of a maze population (prioritized level replay's).

Which members of a co-evolved maze population a batch replays: each drawn
with a probability mixing a rank of its score (:func:`rank_weights`, PLR's
rank prioritisation with a temperature) and its staleness (generations since
it was last played, :func:`staleness_weights`), as :func:`replay_distribution`
combines them (Jiang et al., 2021). Used by
:class:`~amaze.curriculum.maze_population.MazePopulation`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from amaze.errors import AmazeError
from amaze.validation import check_number

__all__ = ["CoevolutionError", "rank_weights", "replay_distribution", "staleness_weights"]


class CoevolutionError(AmazeError):
    """A bad option of the maze population, or results that do not fit its batch."""


def rank_weights(scores: Sequence[float] | np.ndarray, temperature: float) -> np.ndarray:
    """PLR's rank prioritisation: ``h(rank) = rank ** (-1 / temperature)``, normalised.

    ``scores`` is flattened first; rank 1 is the highest score, ties ranked
    in the order of the scores (a stable sort). The temperature is an
    exponent: lower is greedier.

    >>> rank_weights([0.2, 0.9, 0.5], temperature=1.0).round(3)  # ranks 3, 1, 2
    array([0.182, 0.545, 0.273])
    >>> rank_weights([0.2, 0.9, 0.5], temperature=0.1).round(3)  # greedier
    array([0.   , 0.999, 0.001])
    """
    values = np.asarray(scores, dtype=np.float64).reshape(-1)
    if values.size == 0:
        return values
    temperature = check_number(
        "temperature", temperature, minimum=0, strict_minimum=True, error=CoevolutionError
    )
    order = np.argsort(-values, kind="stable")
    ranks = np.empty(values.size, dtype=np.float64)
    ranks[order] = np.arange(1, values.size + 1)
    weights = ranks ** (-1.0 / temperature)
    return weights / weights.sum()


def staleness_weights(last_played: Sequence[int] | np.ndarray, now: int) -> np.ndarray:
    """PLR's staleness distribution ``(now - last_i) / sum_j (now - last_j)``.

    Uniform when every member was played at ``now``.

    >>> staleness_weights([3, 5, 5], now=6)  # ages 3, 1, 1
    array([0.6, 0.2, 0.2])
    """
    ages = now - np.asarray(last_played, dtype=np.float64).reshape(-1)
    if ages.size == 0:
        return ages
    if np.any(ages < 0):
        raise CoevolutionError(f"a member was played after generation {now}")
    total = ages.sum()
    if total <= 0:
        return np.full(ages.size, 1.0 / ages.size)
    return ages / total


def replay_distribution(
    scores: Sequence[float] | np.ndarray,
    last_played: Sequence[int] | np.ndarray,
    now: int,
    *,
    temperature: float,
    staleness: float,
) -> np.ndarray:
    """``(1 - staleness) * rank_weights + staleness * staleness_weights`` over the members.

    >>> replay_distribution([0.2, 0.9, 0.5], [3, 5, 5], 6, temperature=1.0, staleness=0.1).round(3)
    array([0.224, 0.511, 0.265])
    """
    return (1.0 - staleness) * rank_weights(scores, temperature) + staleness * staleness_weights(
        last_played, now
    )
