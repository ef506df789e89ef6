"""A NEAT-like genetic algorithm (NeuroEvolution of Augmenting Topologies) on ``deap``.

Genomes are lists of node genes (input, output, hidden; bias and activation)
and connection genes (source, target, weight, enabled flag, innovation
number). Evolution starts from minimal networks and complexifies them. The
package is split by concept, like ``deap.tools`` (crossover, mutation,
selection) beside ``deap.algorithms``:

* :mod:`evolution.neat.config`: :class:`NeatConfig`, every rate and size of the GA;
* :mod:`evolution.neat.genome`: genes, genomes, innovation numbers
  (:class:`InnovationTracker`) and the minimal initial genomes;
* :mod:`evolution.neat.operators`: mutations, crossover aligned by innovation
  number, and the compatibility distance;
* :mod:`evolution.neat.species`: speciation, stagnation, explicit fitness
  sharing and the offspring each species gets;
* :mod:`evolution.neat.algorithm`: :class:`NeatAlgorithm`, the ask / tell
  loop that chains them (deap toolbox, logbook, hall of fame);
* :mod:`evolution.neat.compile`: genomes compiled to a batched feed-forward
  evaluator (numba), the population policy of the run loop and the arrays
  of agent files.

Every public name is re-exported here: ``from evolution.neat import
NeatAlgorithm, NeatConfig, Genome`` needs no knowledge of the layout.
"""

from __future__ import annotations

from evolution.neat.algorithm import NeatAlgorithm
from evolution.neat.compile import (
    ACTIVATIONS,
    ARRAY_KEYS,
    GenomePopulation,
    genome_to_arrays,
    genomes_to_arrays,
    policy_from_arrays,
    robot_io,
)
from evolution.neat.config import NeatConfig
from evolution.neat.genome import (
    ConnectionGene,
    Genome,
    GenomeFitness,
    InnovationTracker,
    NodeGene,
    new_genome,
)
from evolution.neat.operators import (
    SMALL_GENOME,
    compatibility_distance,
    connection_table,
    crossover,
    distance_kernel,
    mutate,
    mutate_activation,
    mutate_add_connection,
    mutate_add_node,
    mutate_biases,
    mutate_toggle_enable,
    mutate_weights,
)
from evolution.neat.species import (
    Species,
    allot_offspring,
    remove_stagnant,
    shared_fitness,
    speciate,
    update_progress,
)

__all__ = [
    "ACTIVATIONS",
    "ARRAY_KEYS",
    "SMALL_GENOME",
    "ConnectionGene",
    "Genome",
    "GenomeFitness",
    "GenomePopulation",
    "InnovationTracker",
    "NeatAlgorithm",
    "NeatConfig",
    "NodeGene",
    "Species",
    "allot_offspring",
    "compatibility_distance",
    "connection_table",
    "crossover",
    "distance_kernel",
    "genome_to_arrays",
    "genomes_to_arrays",
    "mutate",
    "mutate_activation",
    "mutate_add_connection",
    "mutate_add_node",
    "mutate_biases",
    "mutate_toggle_enable",
    "mutate_weights",
    "new_genome",
    "policy_from_arrays",
    "remove_stagnant",
    "robot_io",
    "shared_fitness",
    "speciate",
    "update_progress",
]
