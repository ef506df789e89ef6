"""Species: speciation, fitness sharing, offspring allotment, stagnation."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from evolution.neat import (
    Genome,
    InnovationTracker,
    NeatAlgorithm,
    NeatConfig,
    Species,
    allot_offspring,
    compatibility_distance,
    new_genome,
    remove_stagnant,
    shared_fitness,
    speciate,
)
from evolution.neat.operators import connection_table, distance_kernel
from tests.evolution.neat.conftest import grown_genomes


def _cluster(center: Genome, size: int, spread: float) -> list[Genome]:
    genomes = []
    for _ in range(size):
        genome = center.copy()
        for gene in genome.connections.values():
            gene.weight += random.gauss(0.0, spread)
        genomes.append(genome)
    return genomes


def test_speciation_separates_distant_genomes():
    random.seed(8)
    config = NeatConfig()
    tracker = InnovationTracker(8, 4)
    a, b = new_genome("DD", tracker, config), new_genome("DD", tracker, config)
    for gene in b.connections.values():
        gene.weight += 3.0
    genomes = _cluster(a, 6, 0.05) + _cluster(b, 4, 0.05)
    species, next_id = speciate(genomes, [], 0.5, config, generation=0, next_id=0)
    assert next_id == 2
    assert [len(s.members) for s in species] == [6, 4]
    assert species[0].members == genomes[:6]
    # species persist into the next generation (an empty one dies), a new cluster founds one
    c = a.copy()
    for gene in c.connections.values():
        gene.weight -= 3.0
    later, next_id = speciate(_cluster(c, 2, 0.05) + genomes[:3], species, 0.5, config, 1, 2)
    assert [(s.id, len(s.members)) for s in later] == [(0, 3), (2, 2)]
    assert later[1].created == 1


def test_fitness_sharing_and_offspring_allotment():
    random.seed(9)
    tracker = InnovationTracker(8, 4)
    genomes = [new_genome("DD", tracker, NeatConfig()) for _ in range(11)]
    for genome, value in zip(genomes, [2.0] * 8 + [2.0, 0.0, 4.0], strict=True):
        genome.fitness.values = (value,)
    big = Species(0, genomes[0], 0, genomes[:8])
    small = Species(1, genomes[8], 0, genomes[8:9])
    other = Species(2, genomes[9], 0, genomes[9:])
    # adjusted fitness: (fitness - worst) / species size, summed per species
    assert shared_fitness([big, small, other]) == pytest.approx([2.0, 2.0, 2.0])
    assert allot_offspring([2.0, 2.0, 2.0], 30, minimum=2) == [10, 10, 10]
    assert allot_offspring([3.0, 1.0], 100, minimum=2) == [74, 26]
    assert allot_offspring([1.0, 1.0, 1.0], 10, minimum=1) == [4, 3, 3]
    assert allot_offspring([0.0, 0.0], 9, minimum=2) == [5, 4]
    assert allot_offspring([0.0, 5.0, 1.0], 4, minimum=2) == [0, 2, 2]


def test_stagnant_species_are_removed_but_the_best():
    random.seed(10)
    tracker = InnovationTracker(8, 4)
    genomes = [new_genome("DD", tracker, NeatConfig()) for _ in range(3)]
    for genome, value in zip(genomes, [1.0, 5.0, 2.0], strict=True):
        genome.fitness.values = (value,)
    species = [
        Species(i, g, 0, [g], best_fitness=g.fitness.values[0], last_improved=last)
        for i, (g, last) in enumerate(zip(genomes, [2, 0, 10], strict=True))
    ]
    kept = remove_stagnant(species, generation=17, stagnation=15)
    assert [s.id for s in kept] == [1, 2]  # species 0 stagnated; 1 stagnated but is the best
    assert [s.id for s in remove_stagnant(species, 40, 15)] == [1]


def test_constant_fitness_leaves_at_most_one_stagnant_species():
    config = NeatConfig(population_size=30, stagnation=3, compatibility_threshold=0.3)
    algorithm = NeatAlgorithm(config, "DD", seed=2)
    counts = []
    for _ in range(8):
        genomes = algorithm.ask()
        algorithm.tell(genomes, np.ones(len(genomes)))
        generation = algorithm.generation - 1
        stale = [s for s in algorithm.species if generation - s.last_improved >= 3]
        assert len(stale) <= 1
        counts.append(algorithm.stats()["n_species"])
    assert max(counts) > 1


def _plain_speciate(genomes, species, threshold, config, generation, next_id):
    """Speciation genome by genome with :func:`compatibility_distance` (the definition)."""
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


def test_compiled_distance_is_compatibility_distance_to_the_bit():
    genomes = grown_genomes("DD", 30, 12, seed=5)
    genomes[3].connections = {}  # an empty genome against full ones
    config = NeatConfig(compatibility_excess=1.3, compatibility_disjoint=0.7)
    indptr, innovations, weights = connection_table(genomes)
    for a in range(len(genomes)):
        for b in range(len(genomes)):
            sa, sb = slice(indptr[a], indptr[a + 1]), slice(indptr[b], indptr[b + 1])
            compiled = distance_kernel(
                innovations[sa], weights[sa], innovations[sb], weights[sb],
                config.compatibility_excess, config.compatibility_disjoint,
                config.compatibility_weight,
            )  # fmt: skip
            assert compiled == compatibility_distance(genomes[a], genomes[b], config)
    assert innovations[indptr[3] : indptr[4]].size == 0
    assert np.all(np.diff(innovations[indptr[0] : indptr[1]]) > 0)


@pytest.mark.parametrize("threshold", [0.3, 1.0, 3.0])
def test_speciation_matches_the_genome_by_genome_definition(threshold):
    genomes = grown_genomes("DD", 60, 6, seed=11)
    config = NeatConfig()
    old = [Species(4, genomes[7].copy(), 0, []), Species(2, genomes[40].copy(), 0, [])]
    old.append(Species(9, grown_genomes("DD", 1, 30, seed=12)[0], 1, []))  # matches nobody
    got, got_next = speciate(genomes, old, threshold, config, 5, 10)
    want, want_next = _plain_speciate(genomes, old, threshold, config, 5, 10)
    assert got_next == want_next
    assert [s.id for s in got] == [s.id for s in want]
    for a, b in zip(got, want, strict=True):
        assert [id(g) for g in a.members] == [id(g) for g in b.members]
        assert a.representative is b.representative
        fields = ("created", "best_fitness", "last_improved")
        assert [getattr(a, f) for f in fields] == [getattr(b, f) for f in fields]
