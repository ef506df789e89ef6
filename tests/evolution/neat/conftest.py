"""Shared helpers of the NEAT tests: grown genomes, a reference evaluator, a toy task."""

from __future__ import annotations

import dataclasses
import math
import random
from collections import defaultdict

import numpy as np
import pytest

from evolution.neat import Genome, InnovationTracker, NeatAlgorithm, NeatConfig, mutate, new_genome
from evolution.neat.compile import robot_io


@pytest.fixture(autouse=True)
def _keep_global_random():
    """The operators draw from ``random``; tests seed it and then give it back."""
    state = random.getstate()
    yield
    random.setstate(state)


# A configuration that grows structure quickly, to exercise the evaluator.
GROWING = NeatConfig(
    add_node_rate=0.5,
    add_connection_rate=0.8,
    toggle_enable_rate=0.2,
    activation_mutate_rate=0.3,
    image_connection_fraction=0.2,
)


_FUNCTIONS = {
    "identity": lambda x: x,
    "tanh": math.tanh,
    "sigmoid": lambda x: 1.0 / (1.0 + math.exp(-x)),
    "relu": lambda x: max(x, 0.0),
    "gauss": lambda x: math.exp(-x * x),
    "sin": math.sin,
}


def reference_outputs(genome: Genome, inputs: np.ndarray) -> list[float]:
    """Plain recursive evaluation of a genome on one input vector (already scaled)."""
    incoming = defaultdict(list)
    for gene in genome.connections.values():
        if gene.enabled:
            incoming[gene.out_node].append(gene)
    memo: dict[int, float] = {}

    def value(node: int) -> float:
        if node < genome.n_inputs:
            return float(inputs[node])
        if node not in memo:
            total = genome.nodes[node].bias
            total += sum(g.weight * value(g.in_node) for g in incoming[node])
            memo[node] = _FUNCTIONS[genome.nodes[node].activation](total)
        return memo[node]

    return [value(genome.n_inputs + o) for o in range(genome.n_outputs)]


def grown_genomes(
    robot: str, count: int, steps: int, seed: int, symmetry: str = "none"
) -> list[Genome]:
    """Genomes after many mutations (structural ones included), from a shared tracker."""
    random.seed(seed)
    config = dataclasses.replace(GROWING, symmetry=symmetry)
    tracker = InnovationTracker(*robot_io(robot, symmetry))
    genomes = []
    for _ in range(count):
        genome = new_genome(robot, tracker, config)
        for _ in range(steps):
            mutate(genome, config, tracker)
        genomes.append(genome)
    return genomes


def is_acyclic(genome: Genome) -> bool:
    """Kahn's algorithm over every connection gene, enabled or not."""
    pending = defaultdict(int)
    children = defaultdict(list)
    for gene in genome.connections.values():
        pending[gene.out_node] += 1
        children[gene.in_node].append(gene.out_node)
    ready = [n for n in genome.nodes if pending[n] == 0]
    seen = 0
    while ready:
        node = ready.pop()
        seen += 1
        for child in children[node]:
            pending[child] -= 1
            if pending[child] == 0:
                ready.append(child)
    return seen == len(genome.nodes)


def fingerprint(genomes: list[Genome]) -> list[tuple]:
    return [
        (
            tuple((n.id, n.kind, n.bias, n.activation) for n in g.nodes.values()),
            tuple(
                (c.innovation, c.in_node, c.out_node, c.weight, c.enabled)
                for c in g.connections.values()
            ),
        )
        for g in genomes
    ]


# A toy task without the maze engine: the argmax of x[:4] - x[4:] from 8 inputs.
TASK_INPUTS = np.random.default_rng(0).random((64, 8)).astype(np.float32)


TASK_TARGET = np.argmax(TASK_INPUTS[:, :4] - TASK_INPUTS[:, 4:], axis=1)


def toy_fitness(algorithm: NeatAlgorithm, genomes: list[Genome]) -> np.ndarray:
    policy = algorithm.population_policy(genomes)
    actions = policy(np.tile(TASK_INPUTS, (len(genomes), 1))).reshape(len(genomes), -1)
    return (actions == TASK_TARGET).mean(axis=1)


def evolve(algorithm: NeatAlgorithm, generations: int) -> None:
    for _ in range(generations):
        genomes = algorithm.ask()
        algorithm.tell(genomes, toy_fitness(algorithm, genomes))
