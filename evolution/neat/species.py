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

import numba
import numpy as np

from evolution.neat.config import NeatConfig
from evolution.neat.genome import Genome
from evolution.neat.operators import connection_table, distance_kernel

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
    representative is its member closest to the old one (the first on ties).
    Distances are those of :func:`~evolution.neat.operators.compatibility_distance`,
    computed by one compiled call over the whole population.
    """
    current = [
        Species(s.id, s.representative, s.created, [], s.best_fitness, s.last_improved)
        for s in sorted(species, key=lambda s: s.id)
    ]
    genome_ptr, genome_innovations, genome_weights = connection_table(genomes)
    rep_ptr, rep_innovations, rep_weights = connection_table([s.representative for s in current])
    assigned, closest = _speciate_kernel(
        genome_ptr, genome_innovations, genome_weights,
        rep_ptr, rep_innovations, rep_weights, float(threshold),
        float(config.compatibility_excess), float(config.compatibility_disjoint),
        float(config.compatibility_weight),
    )  # fmt: skip
    for index, genome in zip(assigned.tolist(), genomes, strict=True):
        if index == len(current):
            current.append(Species(next_id, genome, generation, [], -math.inf, generation))
            next_id += 1
        current[index].members.append(genome)
    alive = [s for s in current if s.members]
    for s, member in zip(current, closest.tolist(), strict=False):
        if s.members:
            s.representative = genomes[member]
    return alive, next_id


@numba.njit(cache=True)
def _speciate_kernel(g_ptr, g_inn, g_w, r_ptr, r_inn, r_w, threshold, c1, c2, c3):
    """Species index of each genome and each species' closest member to its representative.

    Species ``0 .. m - 1`` are those of ``r_*`` (old representatives); a genome
    that fits none founds species ``m, m + 1, ...`` and is its representative.
    ``closest[s]`` is the index of the member of species ``s`` nearest to its
    representative (the first on ties; -1 for a species without members).
    """
    n = g_ptr.shape[0] - 1
    m = r_ptr.shape[0] - 1
    founder = np.full(m + n, -1, dtype=np.int64)  # -1: an old representative
    assigned = np.empty(n, dtype=np.int64)
    n_species = m
    for j in range(n):
        ia, wa = g_inn[g_ptr[j] : g_ptr[j + 1]], g_w[g_ptr[j] : g_ptr[j + 1]]
        assigned[j] = -1
        for s in range(n_species):
            f = founder[s]
            if f < 0:
                ib, wb = r_inn[r_ptr[s] : r_ptr[s + 1]], r_w[r_ptr[s] : r_ptr[s + 1]]
            else:
                ib, wb = g_inn[g_ptr[f] : g_ptr[f + 1]], g_w[g_ptr[f] : g_ptr[f + 1]]
            if distance_kernel(ia, wa, ib, wb, c1, c2, c3) < threshold:
                assigned[j] = s
                break
        if assigned[j] < 0:
            founder[n_species] = j
            assigned[j] = n_species
            n_species += 1
    best = np.full(n_species, np.inf)
    closest = np.full(n_species, -1, dtype=np.int64)
    for j in range(n):
        s = assigned[j]
        ia, wa = g_inn[g_ptr[j] : g_ptr[j + 1]], g_w[g_ptr[j] : g_ptr[j + 1]]
        f = founder[s]
        if f < 0:
            ib, wb = r_inn[r_ptr[s] : r_ptr[s + 1]], r_w[r_ptr[s] : r_ptr[s + 1]]
        else:
            ib, wb = g_inn[g_ptr[f] : g_ptr[f + 1]], g_w[g_ptr[f] : g_ptr[f + 1]]
        d = distance_kernel(ia, wa, ib, wb, c1, c2, c3)
        if closest[s] < 0 or d < best[s]:
            best[s] = d
            closest[s] = j
    return assigned, closest


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
