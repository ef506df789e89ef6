"""The NEAT operators on genomes: mutations, crossover and the compatibility distance.

* **mutations**: weights (perturbed, or with a small probability replaced),
  biases, add-connection (feed-forward only: the whole connection graph,
  disabled genes included, stays acyclic, so that re-enabling a gene is always
  safe), add-node (a connection is split: disabled, ``in -> new`` with weight 1,
  ``new -> out`` with the old weight), toggle enable, optionally activation;
* **crossover** aligns genes by innovation number: matching genes come from
  either parent at random (disabled with a probability if disabled in either),
  disjoint and excess genes from the fitter parent;
* the **compatibility distance** ``c1 E / N + c2 D / N + c3 W̄`` between two
  genomes, on which speciation (:mod:`evolution.neat.species`) rests; a
  compiled twin (:func:`connection_table`, :func:`distance_kernel`) computes
  the same value bit for bit on genomes flattened to arrays, for speciating a
  whole population in one call.

The operators follow ``deap``'s conventions (:func:`mutate` works in place and
returns a 1-tuple; they are registered in the algorithm's toolbox) and draw
from Python's global ``random``, into which the algorithm swaps its own state.
"""

from __future__ import annotations

import random
from collections.abc import Sequence

import numba
import numpy as np

from evolution.neat.compile import ACTIVATIONS
from evolution.neat.config import NeatConfig
from evolution.neat.genome import ConnectionGene, Genome, InnovationTracker, NodeGene

__all__ = [
    "SMALL_GENOME",
    "compatibility_distance",
    "connection_table",
    "crossover",
    "distance_kernel",
    "mutate",
    "mutate_activation",
    "mutate_add_connection",
    "mutate_add_node",
    "mutate_biases",
    "mutate_toggle_enable",
    "mutate_weights",
]

#: Below this many connection genes, the compatibility distance is not
#: normalised by genome size (N = 1), as in the NEAT paper.
SMALL_GENOME = 20


# -----------------------------------------------------------------------------
# Mutations (all draw from ``random``)


# The operators run for every offspring of every generation: they read the
# configuration and the ``random`` functions into locals once per call, which
# changes neither the draws nor the arithmetic.


def _perturbed(
    values: list[float], replace: float, init: float, power: float, bound: float
) -> list[float]:
    """Each value replaced (with probability ``replace``) or perturbed, clipped to ``bound``.

    A replacement is drawn from N(0, init), a perturbation adds N(0, power).

    One ``random()`` then one ``gauss`` per value, in order: the draws of the
    weight and bias mutations.
    """
    draw, gauss = random.random, random.gauss
    perturbed = []
    for value in values:
        value = gauss(0.0, init) if draw() < replace else value + gauss(0.0, power)
        perturbed.append(max(-bound, min(bound, value)))
    return perturbed


def mutate_weights(genome: Genome, config: NeatConfig) -> None:
    """Perturb every connection weight (Gaussian), or replace it with ``weight_replace_rate``."""
    genes = [genome.connections[i] for i in sorted(genome.connections)]
    weights = _perturbed(
        [gene.weight for gene in genes],
        config.weight_replace_rate,
        config.weight_init_stdev,
        config.weight_mutate_power,
        config.weight_max,
    )
    for gene, weight in zip(genes, weights, strict=True):
        gene.weight = weight


def mutate_biases(genome: Genome, config: NeatConfig) -> None:
    """Perturb every output and hidden bias, or replace it with ``bias_replace_rate``."""
    nodes = [genome.nodes[i] for i in sorted(genome.nodes) if genome.nodes[i].kind != "input"]
    biases = _perturbed(
        [node.bias for node in nodes],
        config.bias_replace_rate,
        config.bias_init_stdev,
        config.bias_mutate_power,
        config.weight_max,
    )
    for node, bias in zip(nodes, biases, strict=True):
        node.bias = bias


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


def _descendants(children: dict[int, list[int]], node: int) -> set[int]:
    """``node`` and every node reachable from it (``children``: each node's targets)."""
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
    nodes = genome.nodes
    targets = sorted(i for i, n in nodes.items() if n.kind != "input")
    random.shuffle(targets)
    children: dict[int, list[int]] = {}  # through any gene, enabled or not
    parents: dict[int, list[int]] = {}
    for gene in genome.connections.values():
        children.setdefault(gene.in_node, []).append(gene.out_node)
        parents.setdefault(gene.out_node, []).append(gene.in_node)
    candidates = [i for i in sorted(nodes) if nodes[i].kind != "output"]
    for target in targets:
        forbidden = _descendants(children, target)
        forbidden.update(parents.get(target, ()))
        sources = [i for i in candidates if i not in forbidden]
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
    draw, disable = random.random, config.disable_inherit_rate
    child = Genome(fitter.n_inputs, fitter.n_outputs)
    fitter_nodes, other_nodes, child_nodes = fitter.nodes, other.nodes, child.nodes
    for node_id in sorted(fitter_nodes):
        node = fitter_nodes[node_id]
        if node.kind != "input":
            match = other_nodes.get(node_id)
            if match is not None and draw() < 0.5:
                node = match
        child_nodes[node_id] = NodeGene(node_id, node.kind, node.bias, node.activation)
    fitter_genes, other_genes, child_genes = (
        fitter.connections,
        other.connections,
        child.connections,
    )
    for innovation in sorted(fitter_genes):
        own = fitter_genes[innovation]
        match = other_genes.get(innovation)
        if match is None:
            gene, enabled = own, own.enabled
        else:
            gene = match if draw() < 0.5 else own
            enabled = True
            if not (own.enabled and match.enabled):
                enabled = draw() >= disable
        child_genes[innovation] = ConnectionGene(
            innovation, gene.in_node, gene.out_node, gene.weight, enabled
        )
    return child


# -----------------------------------------------------------------------------
# Distance


def compatibility_distance(a: Genome, b: Genome, config: NeatConfig) -> float:
    """NEAT's compatibility distance ``c1 E / N + c2 D / N + c3 W̄``.

    ``E`` counts excess genes (innovations beyond the other genome's last),
    ``D`` disjoint ones, ``W̄`` is the mean weight difference of matching genes
    (summed in increasing innovation order, the order of :func:`distance_kernel`)
    and ``N`` the larger genome's number of connection genes (1 below
    :data:`SMALL_GENOME`).
    """
    ka, kb = a.connections, b.connections
    if not ka and not kb:
        return 0.0
    matching = sorted(ka.keys() & kb.keys())
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


def connection_table(genomes: Sequence[Genome]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The connection genes of ``genomes`` as arrays, for :func:`distance_kernel`.

    Returns ``(indptr, innovations, weights)``: genome ``g``'s genes are
    ``indptr[g]:indptr[g + 1]``, sorted by innovation number.
    """
    sizes = np.fromiter((len(g.connections) for g in genomes), np.int64, len(genomes))
    indptr = np.zeros(len(genomes) + 1, dtype=np.int64)
    np.cumsum(sizes, out=indptr[1:])
    total = int(indptr[-1])
    innovations = np.fromiter(
        (i for g in genomes for i in g.connections), np.int64, total
    )  # fmt: skip
    weights = np.fromiter(
        (c.weight for g in genomes for c in g.connections.values()), np.float64, total
    )
    order = np.lexsort((innovations, np.repeat(np.arange(len(genomes)), sizes)))
    return indptr, innovations[order], weights[order]


@numba.njit(cache=True)
def distance_kernel(ia, wa, ib, wb, c1, c2, c3):
    """:func:`compatibility_distance` of two genomes given as sorted innovations and weights.

    The same operations in the same order (matching genes in increasing
    innovation), so the same value to the last bit.
    """
    na, nb = ia.shape[0], ib.shape[0]
    if na == 0 and nb == 0:
        return 0.0
    last = min(ia[na - 1] if na else -1, ib[nb - 1] if nb else -1)
    i = j = matching = unmatched = excess = 0
    total = 0.0
    while i < na and j < nb:
        if ia[i] == ib[j]:
            total += abs(wa[i] - wb[j])
            matching += 1
            i += 1
            j += 1
        elif ia[i] < ib[j]:
            unmatched += 1
            if ia[i] > last:
                excess += 1
            i += 1
        else:
            unmatched += 1
            if ib[j] > last:
                excess += 1
            j += 1
    for k in range(i, na):
        unmatched += 1
        if ia[k] > last:
            excess += 1
    for k in range(j, nb):
        unmatched += 1
        if ib[k] > last:
            excess += 1
    disjoint = unmatched - excess
    weight = total / matching if matching else 0.0
    size = max(na, nb)
    n = 1.0 if size < SMALL_GENOME else float(size)
    return c1 * excess / n + c2 * disjoint / n + c3 * weight
