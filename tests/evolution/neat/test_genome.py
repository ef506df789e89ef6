"""Genomes: innovation numbers, the initial topologies, genomes crossing process boundaries."""

from __future__ import annotations

import multiprocessing
import random

import numpy as np

from evolution.neat import (
    Genome,
    InnovationTracker,
    NeatAlgorithm,
    NeatConfig,
    NodeGene,
    genome_to_arrays,
    new_genome,
)
from tests.evolution.neat.conftest import evolve, fingerprint


def test_innovation_tracker_numbers_connections_and_split_nodes():
    random.seed(1)
    tracker = InnovationTracker(8, 4)
    assert tracker.n_innovations == 32 and tracker.next_node == 12
    assert tracker.connection(3, 8 + 2) == 3 * 4 + 2  # inputs to outputs first, in order
    assert tracker.connection(0, 12) == 32
    assert tracker.connection(0, 12) == 32 and tracker.n_innovations == 33
    genome = new_genome("DD", tracker, NeatConfig())
    assert list(genome.connections) == list(range(32))
    assert [g.innovation for g in genome.connections.values()] == list(range(32))
    # splitting a connection gives the node id recorded for it, unless the genome holds it
    assert tracker.split_node(5, genome) == tracker.split_node(5, genome) == 12
    genome.nodes[12] = NodeGene(12, "hidden", 0.0, "tanh")
    assert tracker.split_node(5, genome) == 13
    assert tracker.split_node(6, genome) == 14
    assert tracker.next_node == 15


def test_image_robots_start_sparse():
    algorithm = NeatAlgorithm(NeatConfig(population_size=10), "H15", seed=0)
    for genome in algorithm.ask():
        assert genome.n_inputs == 225 and genome.n_outputs == 4
        assert 15 <= len(genome.connections) <= 90
        assert {c.out_node for c in genome.connections.values()} == set(range(225, 229))
    continuous = NeatAlgorithm(NeatConfig(population_size=10), "CC11", seed=0).ask()[0]
    assert continuous.n_outputs == 2 and continuous.nodes[121].activation == "tanh"


def test_genomes_travel_through_a_spawn_pool():
    algorithm = NeatAlgorithm(NeatConfig(population_size=10), "DD", seed=1)
    evolve(algorithm, 2)
    genomes = algorithm.ask()[:4]
    for i, genome in enumerate(genomes):
        genome.fitness.values = (float(i),)
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        back = pool.map(Genome.copy, genomes)
        arrays, _ = pool.apply(genome_to_arrays, (genomes[0],))
    assert fingerprint(back) == fingerprint(genomes)
    assert [g.fitness.values for g in back] == [g.fitness.values for g in genomes]
    for key, value in genome_to_arrays(genomes[0])[0].items():
        np.testing.assert_array_equal(arrays[key], value)
