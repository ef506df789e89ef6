"""NEAT genomes: node and connection genes, innovation numbers and the initial genomes.

Genomes are lists of node genes (input, output, hidden; bias and activation)
and connection genes (source, target, weight, enabled flag, innovation
number). They are plain module-level classes, so that they pickle
(checkpoints, process pools) and compile to a batched evaluator
(:mod:`evolution.neat.compile`).

**Innovation numbers** identify structural genes. The :class:`InnovationTracker`
(part of the algorithm's state) gives a connection ``(in, out)`` one number
wherever and whenever it appears, and the hidden node splitting a given
connection one id (a fresh one only when a genome already holds it). This
is a stronger form of NEAT's rule that the same structural mutation within a
generation gets the same innovation, and it is deterministic.

**Initial topology** (:func:`new_genome`): every input connected to every
output for discrete-input robots (8 x 4 connections); for image robots a
sparse random connectivity, a fraction ``image_connection_fraction`` of the
pixel-output pairs (each output gets at least one), which keeps the genomes
and the compatibility distance sane with 121 or 225 pixel inputs.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

from deap import base

from amaze.agents.robot import Robot, as_robot
from evolution.neat.compile import robot_io
from evolution.neat.config import NeatConfig

__all__ = [
    "ConnectionGene",
    "Genome",
    "GenomeFitness",
    "InnovationTracker",
    "NodeGene",
    "new_genome",
]


class GenomeFitness(base.Fitness):
    """A single maximised fitness value (deap's ``Fitness``, weights (1.0,))."""

    weights = (1.0,)


@dataclass(slots=True)
class NodeGene:
    """A node: ``kind`` is ``input``, ``output`` or ``hidden``; inputs ignore bias/activation."""

    id: int
    kind: str
    bias: float
    activation: str


@dataclass(slots=True)
class ConnectionGene:
    """A connection ``in_node -> out_node``, identified by its innovation number."""

    innovation: int
    in_node: int
    out_node: int
    weight: float
    enabled: bool = True


class Genome:
    """A NEAT genome: node genes by id and connection genes by innovation number.

    Node ids: inputs ``0..n_inputs-1``, outputs ``n_inputs..n_inputs+n_outputs-1``,
    hidden nodes above. ``fitness`` is a deap fitness (invalid until evaluated).
    A module-level class, so that genomes pickle (checkpoints, process pools).
    """

    def __init__(self, n_inputs: int, n_outputs: int) -> None:
        self.n_inputs = n_inputs
        self.n_outputs = n_outputs
        self.nodes: dict[int, NodeGene] = {}
        self.connections: dict[int, ConnectionGene] = {}
        self.fitness = GenomeFitness()

    def copy(self) -> Genome:
        """An independent copy (genes and fitness)."""
        other = Genome(self.n_inputs, self.n_outputs)
        other.nodes = {
            i: NodeGene(n.id, n.kind, n.bias, n.activation) for i, n in self.nodes.items()
        }
        other.connections = {
            i: ConnectionGene(c.innovation, c.in_node, c.out_node, c.weight, c.enabled)
            for i, c in self.connections.items()
        }
        other.fitness.wvalues = self.fitness.wvalues
        return other

    def __deepcopy__(self, memo: dict) -> Genome:
        return self.copy()

    @property
    def n_hidden(self) -> int:
        return len(self.nodes) - self.n_inputs - self.n_outputs

    @property
    def n_enabled(self) -> int:
        return sum(1 for c in self.connections.values() if c.enabled)

    def __repr__(self) -> str:
        fitness = self.fitness.values[0] if self.fitness.valid else None
        return (
            f"Genome(hidden={self.n_hidden}, connections={self.n_enabled}/"
            f"{len(self.connections)}, fitness={fitness})"
        )


class InnovationTracker:
    """Innovation numbers of connections and ids of the nodes splitting them.

    A connection ``(in, out)`` always gets the same innovation number; the
    input-output connections are numbered first (``i * n_outputs + o``), so
    that initial genomes align. Splitting the connection with innovation ``c``
    gives the first node id recorded for ``c`` that the genome does not hold
    yet, or a new one.
    """

    def __init__(self, n_inputs: int, n_outputs: int) -> None:
        self.n_inputs = n_inputs
        self.n_outputs = n_outputs
        self._connections: dict[tuple[int, int], int] = {}
        self._splits: dict[int, list[int]] = {}
        self.next_node = n_inputs + n_outputs
        for i in range(n_inputs):
            for o in range(n_outputs):
                self.connection(i, n_inputs + o)

    @property
    def n_innovations(self) -> int:
        return len(self._connections)

    def connection(self, in_node: int, out_node: int) -> int:
        """The innovation number of the connection ``in_node -> out_node``."""
        key = (in_node, out_node)
        innovation = self._connections.get(key)
        if innovation is None:
            innovation = self._connections[key] = len(self._connections)
        return innovation

    def split_node(self, innovation: int, genome: Genome) -> int:
        """The id of the hidden node splitting connection ``innovation`` in ``genome``."""
        known = self._splits.setdefault(innovation, [])
        for node in known:
            if node not in genome.nodes:
                return node
        node = self.next_node
        self.next_node += 1
        known.append(node)
        return node


def _output_activation(robot: Robot) -> str:
    return "identity" if robot.discrete_outputs else "tanh"


def new_genome(robot: Robot | str, tracker: InnovationTracker, config: NeatConfig) -> Genome:
    """A minimal genome for ``robot``: inputs wired to outputs, no hidden node.

    All pairs for discrete inputs (``initial_connection_fraction``); a sparse
    random subset for images (``image_connection_fraction``), every output
    keeping at least one connection. Draws from ``random``.
    """
    robot = as_robot(robot)
    n_inputs, n_outputs = robot_io(robot, config.symmetry)
    genome = Genome(n_inputs, n_outputs)
    for i in range(n_inputs):
        genome.nodes[i] = NodeGene(i, "input", 0.0, "identity")
    activation = _output_activation(robot)
    for o in range(n_inputs, n_inputs + n_outputs):
        genome.nodes[o] = NodeGene(
            o, "output", random.gauss(0.0, config.bias_init_stdev), activation
        )
    fraction = (
        config.initial_connection_fraction
        if robot.discrete_inputs
        else config.image_connection_fraction
    )
    for o in range(n_inputs, n_inputs + n_outputs):
        if fraction >= 1.0:
            chosen = list(range(n_inputs))
        else:
            chosen = [i for i in range(n_inputs) if random.random() < fraction]
            if not chosen:
                chosen = [random.randrange(n_inputs)]
        for i in chosen:
            innovation = tracker.connection(i, o)
            weight = random.gauss(0.0, config.weight_init_stdev)
            genome.connections[innovation] = ConnectionGene(innovation, i, o, weight)
    genome.connections = dict(sorted(genome.connections.items()))
    return genome
