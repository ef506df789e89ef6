"""NEAT species: speciation, stagnation, explicit fitness sharing and offspring allotment.

**Speciation** by compatibility distance (:func:`~evolution.neat.operators.compatibility_distance`)
against each species' representative, with a threshold optionally adapted
to a target number of species; **explicit fitness sharing** (a genome's
adjusted fitness is its fitness over its species' size) allots offspring to
species; the best members of each species are kept (elitism); species that
have not improved for ``stagnation`` generations are removed, except the best.

These are the population-level steps of a generation, kept apart from the
genome operators; :class:`~evolution.neat.algorithm.NeatAlgorithm` chains them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from evolution.neat.config import NeatConfig
from evolution.neat.genome import Genome
from evolution.neat.operators import compatibility_distance

__all__ = [
    "Species",
    "allot_offspring",
    "remove_stagnant",
    "shared_fitness",
    "speciate",
    "update_progress",
]


@dataclass
class Species:
    """A species: its representative, this generation's members and its progress.

    ``best_fitness`` is the best member fitness it ever had, reached in
    generation ``last_improved``.
    """

    id: int
    representative: Genome
    created: int
    members: list[Genome]
    best_fitness: float = -math.inf
    last_improved: int = 0

    def fitnesses(self) -> np.ndarray:
        return np.asarray([g.fitness.values[0] for g in self.members], dtype=np.float64)


def speciate(
    genomes: Sequence[Genome],
    species: Sequence[Species],
    threshold: float,
    config: NeatConfig,
    generation: int,
    next_id: int,
) -> tuple[list[Species], int]:
    """Assign ``genomes`` to species; returns the non-empty species and the next free id.

    Each genome joins the first species (by id) whose representative is
    within ``threshold``, else founds a new one. A surviving species' new
    representative is its member closest to the old one.
    """
    current = [
        Species(s.id, s.representative, s.created, [], s.best_fitness, s.last_improved)
        for s in sorted(species, key=lambda s: s.id)
    ]
    for genome in genomes:
        for s in current:
            if compatibility_distance(genome, s.representative, config) < threshold:
                s.members.append(genome)
                break
        else:
            current.append(Species(next_id, genome, generation, [genome], -math.inf, generation))
            next_id += 1
    alive = [s for s in current if s.members]
    for s in alive:
        s.representative = min(
            s.members, key=lambda g, r=s.representative: compatibility_distance(g, r, config)
        )
    return alive, next_id


def update_progress(species: Sequence[Species], generation: int) -> None:
    """Record each species' best member fitness, and when it last improved."""
    for s in species:
        best = float(s.fitnesses().max())
        if best > s.best_fitness:
            s.best_fitness = best
            s.last_improved = generation


def remove_stagnant(species: Sequence[Species], generation: int, stagnation: int) -> list[Species]:
    """The species that improved within ``stagnation`` generations, plus the best one.

    The best species (with the best member this generation, the first on a
    tie) is never removed, so that the population cannot die out.
    """
    if not species:
        return []
    best = max(species, key=lambda s: float(s.fitnesses().max()))
    return [s for s in species if s is best or generation - s.last_improved < stagnation]


def allot_offspring(scores: Sequence[float], total: int, minimum: int = 1) -> list[int]:
    """Offspring per species, proportional to non-negative ``scores``, summing to ``total``.

    Each species first gets ``minimum`` (in order of decreasing score while
    the total lasts), the rest is shared in proportion to the scores by
    largest remainders (ties to the earlier species); equal shares when all
    scores are zero.
    """
    n = len(scores)
    if n == 0:
        return []
    s = np.maximum(np.asarray(scores, dtype=np.float64), 0.0)
    counts = np.zeros(n, dtype=np.int64)
    left = total
    for i in np.argsort(-s, kind="stable"):
        take = min(minimum, left)
        counts[i] += take
        left -= take
    if left > 0:
        weights = s if s.sum() > 0 else np.ones(n)
        raw = left * weights / weights.sum()
        floor = np.floor(raw).astype(np.int64)
        counts += floor
        remainder = left - int(floor.sum())
        for i in np.argsort(-(raw - floor), kind="stable")[:remainder]:
            counts[i] += 1
    return counts.tolist()


def shared_fitness(species: Sequence[Species]) -> list[float]:
    """Explicit fitness sharing: each species' sum of its members' adjusted fitness.

    A member's adjusted fitness is its fitness (shifted so that the worst
    genome of the population scores 0) over its species' size, so a species
    scores its mean shifted fitness.
    """
    lowest = min(float(s.fitnesses().min()) for s in species)
    return [float(np.sum((s.fitnesses() - lowest) / len(s.members))) for s in species]
