"""A NEAT-like genetic algorithm (NeuroEvolution of Augmenting Topologies) on ``deap``.

Genomes are lists of node genes (input, output, hidden; bias and activation)
and connection genes (source, target, weight, enabled flag, innovation
number). Evolution starts from minimal networks and complexifies them:

* **innovation numbers** identify structural genes. The :class:`InnovationTracker`
  (part of the algorithm's state) gives a connection ``(in, out)`` one number
  wherever and whenever it appears, and the hidden node splitting a given
  connection one id (a fresh one only when a genome already holds it). This
  is a stronger form of NEAT's rule that the same structural mutation within a
  generation gets the same innovation, and it is deterministic;
* **mutations**: weights (perturbed, or with a small probability replaced),
  biases, add-connection (feed-forward only: the whole connection graph,
  disabled genes included, stays acyclic, so that re-enabling a gene is always
  safe), add-node (a connection is split: disabled, ``in -> new`` with weight 1,
  ``new -> out`` with the old weight), toggle enable, optionally activation;
* **crossover** aligns genes by innovation number: matching genes come from
  either parent at random (disabled with a probability if disabled in either),
  disjoint and excess genes from the fitter parent;
* **speciation** by compatibility distance ``c1 E / N + c2 D / N + c3 W̄``
  against each species' representative, with a threshold optionally adapted
  to a target number of species; **explicit fitness sharing** (a genome's
  adjusted fitness is its fitness over its species' size) allots offspring to
  species; the best members of each species are kept (elitism); species that
  have not improved for ``stagnation`` generations are removed, except the best.

``deap`` provides the toolbox (``mate``, ``mutate``, ``select`` with
``tools.selTournament`` within species), the statistics and logbook, and the
hall of fame holding the champion. deap draws from Python's global ``random``;
the algorithm swaps its own saved state in and out around each of its steps,
so that a run is deterministic given its seed and a pickled algorithm resumes
bit-identically, whatever else uses ``random`` meanwhile.

Initial topology: every input connected to every output for discrete-input
robots (8 x 4 connections); for image robots a sparse random connectivity, a
fraction ``image_connection_fraction`` of the pixel-output pairs (each output
gets at least one), which keeps the genomes and the compatibility distance
sane with 121 or 225 pixel inputs.

Genomes compile to a batched evaluator, see :mod:`evolution.neat_compile`.
"""

from __future__ import annotations

import contextlib
import math
import random
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np
from deap import base, tools

from amaze.agents.robot import Robot, as_robot
from amaze.runs.folder import config_from_dict
from evolution import EvolutionConfigError
from evolution.neat_compile import (
    ACTIVATIONS,
    GenomePopulation,
    genome_to_arrays,
    policy_from_arrays,
    robot_io,
)

__all__ = [
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
    "crossover",
    "genome_to_arrays",
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
    "shared_fitness",
    "speciate",
    "update_progress",
]

#: Below this many connection genes, the compatibility distance is not
#: normalised by genome size (N = 1), as in the NEAT paper.
SMALL_GENOME = 20


# -----------------------------------------------------------------------------
# Configuration


_PROBABILITY = (lambda v: 0 <= v <= 1, "a probability in [0, 1]")
_FRACTION = (lambda v: 0 < v <= 1, "in (0, 1]")
_NON_NEGATIVE = (lambda v: v >= 0, "non-negative")
_POSITIVE = (lambda v: v > 0, "positive")
_RULES = {
    "population_size": (lambda v: v >= 2, "at least 2"),
    "stagnation": (lambda v: v >= 1, "at least 1"),
    "min_species_size": (lambda v: v >= 1, "at least 1"),
    "tournament_size": (lambda v: v >= 1, "at least 1"),
    "elitism": _NON_NEGATIVE,
    "target_species": (lambda v: v >= 0, "non-negative (0: a fixed threshold)"),
    "compatibility_threshold": _POSITIVE,
    "threshold_step": _POSITIVE,
    "weight_max": _POSITIVE,
    **dict.fromkeys(
        ("initial_connection_fraction", "image_connection_fraction", "survival_fraction"),
        _FRACTION,
    ),
    **dict.fromkeys(
        (
            "weight_init_stdev",
            "weight_mutate_power",
            "bias_init_stdev",
            "bias_mutate_power",
            "compatibility_excess",
            "compatibility_disjoint",
            "compatibility_weight",
        ),
        _NON_NEGATIVE,
    ),
    **dict.fromkeys(
        (
            "weight_mutate_rate",
            "weight_replace_rate",
            "bias_mutate_rate",
            "bias_replace_rate",
            "add_connection_rate",
            "add_node_rate",
            "toggle_enable_rate",
            "activation_mutate_rate",
            "crossover_rate",
            "disable_inherit_rate",
        ),
        _PROBABILITY,
    ),
}


@dataclass
class NeatConfig:
    """Parameters of the NEAT-like algorithm (defaults after Stanley & Miikkulainen, 2002).

    Probabilities are per offspring unless said otherwise. ``activation`` is
    the hidden nodes' activation (outputs are linear for discrete actions,
    tanh for accelerations). ``target_species`` > 0 adapts the compatibility
    threshold each generation towards that many species, multiplying or dividing
    it by ``1 + threshold_step``. The threshold (1.0, lower than the paper's 3.0)
    suits the normalised distance of genomes of 20 connection genes or more,
    where weight differences dominate.
    """

    population_size: int = 100
    activation: str = "tanh"
    initial_connection_fraction: float = 1.0
    image_connection_fraction: float = 0.05
    weight_init_stdev: float = 1.0
    weight_max: float = 8.0
    weight_mutate_rate: float = 0.8
    weight_replace_rate: float = 0.1
    weight_mutate_power: float = 0.5
    bias_init_stdev: float = 1.0
    bias_mutate_rate: float = 0.7
    bias_replace_rate: float = 0.1
    bias_mutate_power: float = 0.5
    add_connection_rate: float = 0.1
    add_node_rate: float = 0.05
    toggle_enable_rate: float = 0.01
    activation_mutate_rate: float = 0.0
    crossover_rate: float = 0.75
    disable_inherit_rate: float = 0.75
    compatibility_excess: float = 1.0
    compatibility_disjoint: float = 1.0
    compatibility_weight: float = 0.4
    compatibility_threshold: float = 1.0
    target_species: int = 8
    threshold_step: float = 0.1
    stagnation: int = 15
    elitism: int = 1
    survival_fraction: float = 0.2
    min_species_size: int = 2
    tournament_size: int = 2

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise :class:`EvolutionConfigError` naming the first bad value."""
        for field in fields(self):
            value = getattr(self, field.name)
            if field.type == "int":
                if not isinstance(value, int | np.integer) or isinstance(value, bool):
                    raise EvolutionConfigError(
                        f"NEAT config '{field.name}' must be an integer, got {value!r}"
                    )
                setattr(self, field.name, int(value))
            elif field.type == "float":
                if not isinstance(value, int | float | np.number) or isinstance(value, bool):
                    raise EvolutionConfigError(
                        f"NEAT config '{field.name}' must be a number, got {value!r}"
                    )
                value = float(value)
                if not math.isfinite(value):
                    raise EvolutionConfigError(
                        f"NEAT config '{field.name}' must be finite, got {value!r}"
                    )
                setattr(self, field.name, value)
        if self.activation not in ACTIVATIONS:
            raise EvolutionConfigError(
                f"NEAT config 'activation' must be one of {', '.join(ACTIVATIONS)}, "
                f"got {self.activation!r}"
            )
        for name in fields(self):
            value = getattr(self, name.name)
            rule = _RULES.get(name.name)
            if rule is not None and not rule[0](value):
                raise EvolutionConfigError(
                    f"NEAT config '{name.name}' must be {rule[1]}, got {value!r}"
                )

    def to_dict(self) -> dict[str, Any]:
        """The configuration as a JSON-ready dictionary."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> NeatConfig:
        """A configuration from a dictionary; missing keys take their defaults.

        Unknown keys and bad values raise :class:`EvolutionConfigError` naming them.
        """
        return config_from_dict(cls, data, EvolutionConfigError, "NEAT config")


# -----------------------------------------------------------------------------
# Genes and genomes


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
    n_inputs, n_outputs = robot_io(robot)
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


# -----------------------------------------------------------------------------
# Mutations (all draw from ``random``)


def _clip(value: float, bound: float) -> float:
    return max(-bound, min(bound, value))


def mutate_weights(genome: Genome, config: NeatConfig) -> None:
    """Perturb every connection weight (Gaussian), or replace it with ``weight_replace_rate``."""
    for innovation in sorted(genome.connections):
        gene = genome.connections[innovation]
        if random.random() < config.weight_replace_rate:
            gene.weight = random.gauss(0.0, config.weight_init_stdev)
        else:
            gene.weight += random.gauss(0.0, config.weight_mutate_power)
        gene.weight = _clip(gene.weight, config.weight_max)


def mutate_biases(genome: Genome, config: NeatConfig) -> None:
    """Perturb every output and hidden bias, or replace it with ``bias_replace_rate``."""
    for node_id in sorted(genome.nodes):
        node = genome.nodes[node_id]
        if node.kind == "input":
            continue
        if random.random() < config.bias_replace_rate:
            node.bias = random.gauss(0.0, config.bias_init_stdev)
        else:
            node.bias += random.gauss(0.0, config.bias_mutate_power)
        node.bias = _clip(node.bias, config.weight_max)


def mutate_add_node(genome: Genome, tracker: InnovationTracker, config: NeatConfig) -> bool:
    """Split a random enabled connection ``a -> b`` with a new hidden node ``h``.

    The old gene is disabled; ``a -> h`` gets weight 1 and ``h -> b`` the old
    weight, so that the network computes nearly what it did (exactly with a
    linear ``h``). Returns whether a node was added.
    """
    enabled = [i for i in sorted(genome.connections) if genome.connections[i].enabled]
    if not enabled:
        return False
    old = genome.connections[random.choice(enabled)]
    old.enabled = False
    node = tracker.split_node(old.innovation, genome)
    genome.nodes[node] = NodeGene(node, "hidden", 0.0, config.activation)
    first = tracker.connection(old.in_node, node)
    second = tracker.connection(node, old.out_node)
    genome.connections[first] = ConnectionGene(first, old.in_node, node, 1.0)
    genome.connections[second] = ConnectionGene(second, node, old.out_node, old.weight)
    return True


def _descendants(genome: Genome, node: int) -> set[int]:
    """``node`` and every node reachable from it through any connection gene."""
    children: dict[int, list[int]] = {}
    for gene in genome.connections.values():
        children.setdefault(gene.in_node, []).append(gene.out_node)
    seen = {node}
    stack = [node]
    while stack:
        for child in children.get(stack.pop(), ()):
            if child not in seen:
                seen.add(child)
                stack.append(child)
    return seen


def mutate_add_connection(genome: Genome, tracker: InnovationTracker, config: NeatConfig) -> bool:
    """Add a connection between two unconnected nodes without creating a cycle.

    Sources are inputs and hidden nodes, targets hidden nodes and outputs; a
    source may not be reachable from its target through any gene (enabled or
    not). Returns whether a connection was added (False when the genome is
    fully connected).
    """
    targets = sorted(i for i, n in genome.nodes.items() if n.kind != "input")
    random.shuffle(targets)
    for target in targets:
        forbidden = _descendants(genome, target)
        forbidden.update(g.in_node for g in genome.connections.values() if g.out_node == target)
        sources = [
            i
            for i in sorted(genome.nodes)
            if genome.nodes[i].kind != "output" and i not in forbidden
        ]
        if sources:
            source = random.choice(sources)
            innovation = tracker.connection(source, target)
            weight = random.gauss(0.0, config.weight_init_stdev)
            genome.connections[innovation] = ConnectionGene(innovation, source, target, weight)
            return True
    return False


def mutate_toggle_enable(genome: Genome) -> bool:
    """Flip the enabled flag of a random connection (always safe: the gene graph is acyclic)."""
    if not genome.connections:
        return False
    gene = genome.connections[random.choice(sorted(genome.connections))]
    gene.enabled = not gene.enabled
    return True


def mutate_activation(genome: Genome) -> bool:
    """Give a random hidden node a random activation."""
    hidden = sorted(i for i, n in genome.nodes.items() if n.kind == "hidden")
    if not hidden:
        return False
    genome.nodes[random.choice(hidden)].activation = random.choice(ACTIVATIONS)
    return True


def mutate(genome: Genome, config: NeatConfig, tracker: InnovationTracker) -> tuple[Genome]:
    """Apply NEAT's mutations with their rates, in place (deap's convention: a 1-tuple).

    The fitness is invalidated.
    """
    if random.random() < config.add_node_rate:
        mutate_add_node(genome, tracker, config)
    if random.random() < config.add_connection_rate:
        mutate_add_connection(genome, tracker, config)
    if random.random() < config.weight_mutate_rate:
        mutate_weights(genome, config)
    if random.random() < config.bias_mutate_rate:
        mutate_biases(genome, config)
    if random.random() < config.toggle_enable_rate:
        mutate_toggle_enable(genome)
    if random.random() < config.activation_mutate_rate:
        mutate_activation(genome)
    del genome.fitness.values
    return (genome,)


def crossover(first: Genome, second: Genome, config: NeatConfig) -> Genome:
    """A child of two genomes aligned by innovation number.

    Matching genes (same innovation in both) come from either parent at
    random, and are disabled with ``disable_inherit_rate`` if disabled in
    either; disjoint and excess genes come from the fitter parent (``first``
    on a tie), so the child has the fitter parent's structure. Unlike deap's
    in-place ``mate`` operators it returns one new genome (invalid fitness).
    """
    fitter, other = (first, second) if not second.fitness > first.fitness else (second, first)
    child = Genome(fitter.n_inputs, fitter.n_outputs)
    for node_id in sorted(fitter.nodes):
        node = fitter.nodes[node_id]
        match = other.nodes.get(node_id)
        if node.kind != "input" and match is not None and random.random() < 0.5:
            node = match
        child.nodes[node_id] = NodeGene(node_id, node.kind, node.bias, node.activation)
    for innovation in sorted(fitter.connections):
        gene = fitter.connections[innovation]
        match = other.connections.get(innovation)
        enabled = gene.enabled
        if match is not None:
            if random.random() < 0.5:
                gene = match
            enabled = True
            if not (fitter.connections[innovation].enabled and match.enabled):
                enabled = random.random() >= config.disable_inherit_rate
        child.connections[innovation] = ConnectionGene(
            innovation, gene.in_node, gene.out_node, gene.weight, enabled
        )
    return child


# -----------------------------------------------------------------------------
# Species


def compatibility_distance(a: Genome, b: Genome, config: NeatConfig) -> float:
    """NEAT's compatibility distance ``c1 E / N + c2 D / N + c3 W̄``.

    ``E`` counts excess genes (innovations beyond the other genome's last),
    ``D`` disjoint ones, ``W̄`` is the mean weight difference of matching genes
    and ``N`` the larger genome's number of connection genes (1 below
    :data:`SMALL_GENOME`).
    """
    ka, kb = a.connections, b.connections
    if not ka and not kb:
        return 0.0
    matching = ka.keys() & kb.keys()
    unmatched = ka.keys() ^ kb.keys()
    last = min(max(ka, default=-1), max(kb, default=-1))
    excess = sum(1 for i in unmatched if i > last)
    disjoint = len(unmatched) - excess
    weight = (
        sum(abs(ka[i].weight - kb[i].weight) for i in matching) / len(matching) if matching else 0.0
    )
    size = max(len(ka), len(kb))
    n = 1.0 if size < SMALL_GENOME else float(size)
    return (
        config.compatibility_excess * excess / n
        + config.compatibility_disjoint * disjoint / n
        + config.compatibility_weight * weight
    )


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


# -----------------------------------------------------------------------------
# The algorithm


def _fitness_value(genome: Genome) -> float:
    return genome.fitness.values[0]


class NeatAlgorithm:
    """NEAT-like evolution of genomes for ``robot``, driven by ask / tell.

    ``ask()`` gives the population to evaluate, :meth:`population_policy`
    compiles it into one policy for the batch engine, ``tell(genomes, fitness)``
    records the fitness, updates the champion (deap hall of fame) and the
    statistics (deap logbook) and breeds the next generation. Deterministic
    given ``seed``; pickling the object is a checkpoint that resumes
    bit-identically.
    """

    def __init__(self, config: NeatConfig, robot: Robot | str, seed: int) -> None:
        if isinstance(config, dict):
            config = NeatConfig.from_dict(config)
        if not isinstance(config, NeatConfig):
            raise EvolutionConfigError(f"expected a NeatConfig, got {type(config).__name__}")
        config.validate()
        self.config = config
        self.robot = as_robot(robot)
        self.seed = int(seed)
        n_inputs, n_outputs = robot_io(self.robot)
        self.tracker = InnovationTracker(n_inputs, n_outputs)
        self.species: list[Species] = []
        self.threshold = config.compatibility_threshold
        self.logbook = tools.Logbook()
        self.hall_of_fame = tools.HallOfFame(1)
        self._generation = 0
        self._next_species = 0
        self._random_state = random.Random(self.seed).getstate()
        self._build_toolbox()
        with self._own_random():
            self.population = [
                new_genome(self.robot, self.tracker, config) for _ in range(config.population_size)
            ]

    # -- state -------------------------------------------------------------

    def _build_toolbox(self) -> None:
        toolbox = base.Toolbox()
        toolbox.register("clone", Genome.copy)
        toolbox.register("mate", crossover, config=self.config)
        toolbox.register("mutate", mutate, config=self.config, tracker=self.tracker)
        toolbox.register("select", tools.selTournament, tournsize=self.config.tournament_size)
        self.toolbox = toolbox

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["toolbox"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._build_toolbox()

    @contextlib.contextmanager
    def _own_random(self) -> Iterator[None]:
        """Run with the algorithm's state in ``random``, leaving the caller's intact."""
        outer = random.getstate()
        random.setstate(self._random_state)
        try:
            yield
        finally:
            self._random_state = random.getstate()
            random.setstate(outer)

    # -- interface ---------------------------------------------------------

    @property
    def generation(self) -> int:
        """Generations told so far."""
        return self._generation

    @property
    def champion(self) -> tuple[Genome, float] | None:
        """The best genome ever evaluated and its fitness, None before the first tell."""
        if len(self.hall_of_fame) == 0:
            return None
        best = self.hall_of_fame[0]
        return best, float(best.fitness.values[0])

    def champion_arrays(self) -> tuple[dict[str, np.ndarray], dict]:
        """The champion compiled by :func:`genome_to_arrays` (for agent files)."""
        champion = self.champion
        if champion is None:
            raise RuntimeError("no champion yet: tell() the fitness of a generation first")
        return genome_to_arrays(champion[0])

    def ask(self) -> list[Genome]:
        """The genomes to evaluate this generation."""
        return list(self.population)

    def population_policy(self, genomes: Sequence[Genome]) -> GenomePopulation:
        """``genomes`` compiled into one population policy (agent ``k`` uses genome ``k // M``)."""
        return GenomePopulation.from_genomes(genomes, self.robot)

    def tell(self, genomes: Sequence[Genome], fitness: np.ndarray) -> None:
        """Record the fitness of the asked genomes and breed the next generation."""
        fitness = np.asarray(fitness, dtype=np.float64).reshape(-1)
        if len(genomes) != len(self.population) or any(
            a is not b for a, b in zip(genomes, self.population, strict=False)
        ):
            raise ValueError("tell() needs the genomes of the last ask(), in the same order")
        if fitness.shape[0] != len(genomes):
            raise ValueError(f"{fitness.shape[0]} fitness values for {len(genomes)} genomes")
        if not np.all(np.isfinite(fitness)):
            raise ValueError("fitness values must be finite")
        for genome, value in zip(genomes, fitness.tolist(), strict=True):
            genome.fitness.values = (value,)
        self.hall_of_fame.update(self.population)
        with self._own_random():
            self._next_generation()

    def stats(self) -> dict[str, float]:
        """The last generation's statistics (best, mean, std, min, n_species...), {} before."""
        if not self.logbook:
            return {}
        return {key: float(value) for key, value in self.logbook[-1].items()}

    # -- one generation ----------------------------------------------------

    def _next_generation(self) -> None:
        config = self.config
        generation = self._generation
        self.species, self._next_species = speciate(
            self.population, self.species, self.threshold, config, generation, self._next_species
        )
        update_progress(self.species, generation)
        n_species = len(self.species)
        self._record(n_species)
        if config.target_species:
            if n_species < config.target_species:
                self.threshold /= 1.0 + config.threshold_step
            elif n_species > config.target_species:
                self.threshold *= 1.0 + config.threshold_step
        self.species = remove_stagnant(self.species, generation, config.stagnation)
        counts = allot_offspring(
            shared_fitness(self.species), config.population_size, config.min_species_size
        )
        offspring: list[Genome] = []
        for s, count in zip(self.species, counts, strict=True):
            offspring.extend(self._reproduce(s, count))
        self.species = [s for s, count in zip(self.species, counts, strict=True) if count]
        for s in self.species:
            s.members = []  # rebuilt by the next speciation; keeps checkpoints small
        self.population = offspring
        self._generation += 1

    def _reproduce(self, species: Species, count: int) -> list[Genome]:
        """``count`` offspring of a species: its elites, then children of its survivors."""
        config, toolbox = self.config, self.toolbox
        ranked = sorted(species.members, key=_fitness_value, reverse=True)
        children: list[Genome] = []
        for elite in ranked[: min(config.elitism, count)]:
            child = toolbox.clone(elite)
            del child.fitness.values
            children.append(child)
        survivors = ranked[: max(1, math.ceil(config.survival_fraction * len(ranked)))]
        while len(children) < count:
            if len(survivors) > 1 and random.random() < config.crossover_rate:
                first, second = toolbox.select(survivors, 2)
                child = toolbox.mate(first, second)
            else:
                child = toolbox.clone(toolbox.select(survivors, 1)[0])
            (child,) = toolbox.mutate(child)
            children.append(child)
        return children

    def _record(self, n_species: int) -> None:
        statistics = tools.Statistics(_fitness_value)
        statistics.register("best", np.max)
        statistics.register("mean", np.mean)
        statistics.register("std", np.std)
        statistics.register("min", np.min)
        record = statistics.compile(self.population)
        self.logbook.record(
            gen=self._generation,
            evals=len(self.population),
            **record,
            champion=self.hall_of_fame[0].fitness.values[0],
            n_species=n_species,
            threshold=self.threshold,
            hidden=float(np.mean([g.n_hidden for g in self.population])),
            connections=float(np.mean([g.n_enabled for g in self.population])),
        )
