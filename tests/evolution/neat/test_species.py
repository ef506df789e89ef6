"""Species: speciation, fitness sharing, offspring allotment, stagnation."""

from __future__ import annotations

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
    new_genome,
    remove_stagnant,
    shared_fitness,
    speciate,
)


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
