"""The NEAT operators: structural mutations, crossover, compatibility distance."""

from __future__ import annotations

import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evolution.neat import (
    GenomePopulation,
    InnovationTracker,
    NeatConfig,
    compatibility_distance,
    crossover,
    mutate,
    mutate_add_connection,
    mutate_add_node,
    new_genome,
)
from tests.evolution.neat.conftest import GROWING, TASK_INPUTS, is_acyclic


def test_add_node_splits_a_connection():
    random.seed(5)
    config = NeatConfig(activation="identity")
    tracker = InnovationTracker(8, 4)
    genome = new_genome("DD", tracker, config)
    other = genome.copy()
    before = GenomePopulation.from_genomes([genome], "DD").outputs(TASK_INPUTS)
    state = random.getstate()
    assert mutate_add_node(genome, tracker, config)
    new = [c for i, c in genome.connections.items() if i not in other.connections]
    disabled = [c for c in genome.connections.values() if not c.enabled]
    assert len(new) == 2 and len(disabled) == 1
    old = disabled[0]
    first = next(c for c in new if c.in_node == old.in_node)
    second = next(c for c in new if c.out_node == old.out_node)
    assert first.out_node == second.in_node == max(genome.nodes) == 12
    assert genome.nodes[12].kind == "hidden"
    assert (first.weight, second.weight) == (1.0, old.weight)
    assert min(first.innovation, second.innovation) >= 32
    # with a linear hidden node, the network computes the same function
    after = GenomePopulation.from_genomes([genome], "DD").outputs(TASK_INPUTS)
    np.testing.assert_allclose(after, before, rtol=1e-12, atol=1e-12)
    # the same split elsewhere gets the same node id and innovation numbers
    random.setstate(state)
    mutate_add_node(other, tracker, config)
    assert sorted(other.connections) == sorted(genome.connections)
    assert sorted(other.nodes) == sorted(genome.nodes)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_add_connection_never_creates_a_cycle(seed):
    random.seed(seed)
    config = NeatConfig(initial_connection_fraction=0.3)
    tracker = InnovationTracker(8, 4)
    genome = new_genome("DD", tracker, config)
    for _ in range(30):
        if random.random() < 0.3:
            mutate_add_node(genome, tracker, config)
        mutate_add_connection(genome, tracker, config)
        assert is_acyclic(genome)
        pairs = [(c.in_node, c.out_node) for c in genome.connections.values()]
        assert len(pairs) == len(set(pairs))
        assert all(genome.nodes[a].kind != "output" for a, _ in pairs)
        assert all(genome.nodes[b].kind != "input" for _, b in pairs)
        innovations = [tracker.connection(a, b) for a, b in pairs]
        assert innovations == list(genome.connections)


def test_add_connection_reports_a_fully_connected_genome():
    tracker = InnovationTracker(8, 4)
    genome = new_genome("DD", tracker, NeatConfig())
    assert not mutate_add_connection(genome, tracker, NeatConfig())
    assert len(genome.connections) == 32


def test_crossover_aligns_genes_by_innovation():
    random.seed(11)
    tracker = InnovationTracker(8, 4)
    ancestor = new_genome("DD", tracker, GROWING)
    first, second = ancestor.copy(), ancestor.copy()
    for genome in (first, second):
        for _ in range(6):
            mutate(genome, GROWING, tracker)
    first.fitness.values, second.fitness.values = (2.0,), (1.0,)
    assert set(first.connections) != set(second.connections)
    from_second = 0
    for _ in range(20):
        child = crossover(first, second, GROWING)
        assert list(child.connections) == sorted(first.connections)
        assert set(child.nodes) == set(first.nodes)
        assert not child.fitness.valid
        for innovation, gene in child.connections.items():
            a, b = first.connections[innovation], second.connections.get(innovation)
            assert (gene.in_node, gene.out_node) == (a.in_node, a.out_node)
            if b is None:  # disjoint or excess: from the fitter parent
                assert (gene.weight, gene.enabled) == (a.weight, a.enabled)
            else:
                assert gene.weight in (a.weight, b.weight)
                if a.enabled and b.enabled:
                    assert gene.enabled
                from_second += gene.weight == b.weight != a.weight
    assert from_second > 0
    second.fitness.values = (3.0,)
    assert set(crossover(first, second, GROWING).connections) == set(second.connections)


def test_compatibility_distance():
    random.seed(3)
    config = NeatConfig()
    tracker = InnovationTracker(8, 4)
    genome = new_genome("DD", tracker, config)
    assert compatibility_distance(genome, genome.copy(), config) == 0.0
    distances = []
    for shift in (0.1, 0.5, 2.0):
        other = genome.copy()
        for gene in other.connections.values():
            gene.weight += shift
        distances.append(compatibility_distance(genome, other, config))
    np.testing.assert_allclose(distances, [0.4 * 0.1, 0.4 * 0.5, 0.4 * 2.0])
    config = NeatConfig(compatibility_excess=1.0, compatibility_disjoint=0.5)
    grown = genome.copy()
    mutate_add_node(grown, tracker, config)  # two excess genes, 34 genes in all
    assert compatibility_distance(genome, grown, config) == pytest.approx(2 / 34)
    assert compatibility_distance(grown, genome, config) == pytest.approx(2 / 34)
    sparse = genome.copy()
    for innovation in (3, 7, 12):
        del sparse.connections[innovation]  # three disjoint genes
    assert compatibility_distance(genome, sparse, config) == pytest.approx(0.5 * 3 / 32)
    small = genome.copy()
    small.connections = {i: small.connections[i] for i in range(10)}
    assert compatibility_distance(small, genome, config) == pytest.approx(22 / 32)
    tiny = small.copy()
    del tiny.connections[9]  # below 20 genes, N = 1: one excess gene
    assert compatibility_distance(small, tiny, config) == pytest.approx(1.0)
