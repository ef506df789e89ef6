"""NEAT genomes compiled to a batched feed-forward evaluator (numba).

A genome (node and connection genes, see :mod:`evolution.neat.genome`) compiles to a
few flat arrays (:func:`genome_to_arrays`): the nodes that influence an output,
in topological order, each with its bias, its activation code and its incoming
enabled connections as a CSR list of (source, weight). Disabled connections
and hidden nodes from which no output can be reached are left out: they do not
change what the network computes.

:func:`genomes_to_arrays` gives the same arrays for a whole population in one
compiled call (the graph work in numba; only reading the genes is Python), as
compiling every generation of a run needs. A population of P genomes
concatenates those arrays with per-genome offsets into a
:class:`GenomePopulation`, the population policy of the run loop: one
numba kernel call evaluates every agent of a batch, agent ``k`` using genome
``k // M`` where ``M = n_agents // P``. The same arrays are what an agent file
stores (:func:`policy_from_arrays` reads them back, without pickle).

Inputs are the robot's observations: the 8 floats of a discrete-input robot,
or the ``v x v`` pixels of an image robot scaled to [0, 1] (gray level / 255),
row-major. Outputs: 4 values whose argmax (the first on ties) is the action
E, N, W, S for discrete outputs; 2 tanh values (accelerations in [-1, 1]) for
continuous outputs.

The kernel comes in a serial and a multi-threaded (``prange``) version, with
identical results. On 2 cores, 100 genomes x 72 agents, the serial kernel
evaluates 5 to 25 million agents per second (72 to 32 connections per genome)
and the threaded one 1.5 to 2 times as many on an idle machine; on a busy one a
thread can wait a scheduler time slice at each call, so the threaded kernel is
chosen by default only for large batches with idle cores.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from heapq import heapify, heappop, heappush
from typing import Any

import numba
import numpy as np
from numba import prange

from amaze.agents.engine import threads_pay_off
from amaze.agents.robot import Robot, as_robot
from amaze.validation import check_integer
from evolution import EvolutionConfigError
from evolution.networks import check_symmetry, rotation_index, turned_accelerations

__all__ = [
    "ACTIVATIONS",
    "ARRAY_KEYS",
    "GenomePopulation",
    "genome_to_arrays",
    "genomes_to_arrays",
    "policy_from_arrays",
    "robot_io",
]

#: Node activation functions, by code (the index in this tuple).
ACTIVATIONS: tuple[str, ...] = ("identity", "tanh", "sigmoid", "relu", "gauss", "sin")
_CODES = {name: code for code, name in enumerate(ACTIVATIONS)}

#: The arrays of one compiled genome (see :func:`genome_to_arrays`).
ARRAY_KEYS: tuple[str, ...] = (
    "node_ids",
    "bias",
    "activation",
    "indptr",
    "sources",
    "weights",
    "outputs",
)

#: Discrete outputs: 4 action values (E, N, W, S); continuous: 2 accelerations.
N_DISCRETE_OUTPUTS = 4
N_CONTINUOUS_OUTPUTS = 2
N_DISCRETE_INPUTS = 8

#: The multi-threaded kernel is the default from this many connection
#: evaluations per call (agents x mean connections per genome, some 40 µs of
#: serial work), on a machine with several numba threads and idle cores.
_PARALLEL_MIN_WORK = 20_000


def robot_io(robot: Robot | str, symmetry: str = "none") -> tuple[int, int]:
    """The number of network inputs and outputs of a robot.

    8 inputs for discrete-input robots, ``v * v`` pixels for image robots;
    4 outputs (argmax action) for discrete outputs, 2 (accelerations) for
    continuous ones; 1 with ``symmetry`` ``"rotations"`` (the score of the
    direction turned east).
    """
    robot = as_robot(robot)
    n_inputs = N_DISCRETE_INPUTS if robot.discrete_inputs else int(robot.vision) ** 2
    n_outputs = N_DISCRETE_OUTPUTS if robot.discrete_outputs else N_CONTINUOUS_OUTPUTS
    if check_symmetry(symmetry) == "rotations":
        n_outputs = 1
    return n_inputs, n_outputs


# -----------------------------------------------------------------------------
# One genome to arrays


def genome_to_arrays(genome: Any) -> tuple[dict[str, np.ndarray], dict]:
    """The arrays of a genome's feed-forward evaluator and a JSON-ready description.

    Arrays: ``node_ids`` (int64, the evaluated nodes in topological order:
    outputs and the hidden nodes that reach an output through enabled
    connections), ``bias`` (float64), ``activation`` (int64 codes into
    ``architecture["activations"]``), ``indptr`` (int64, node ``j``'s incoming
    connections are ``indptr[j]:indptr[j + 1]``), ``sources`` (int64: an input
    index below ``n_inputs``, else ``n_inputs`` + the index of an evaluated
    node), ``weights`` (float64) and ``outputs`` (int64, the evaluated-node
    index of each output). The architecture holds ``type`` ("neat"),
    ``n_inputs``, ``n_outputs``, ``activations`` and the sizes, and
    ``symmetry`` ``"rotations"`` for a genome of one output (the score of
    one direction; a genome for discrete actions otherwise has 4).
    """
    n_inputs, n_outputs = int(genome.n_inputs), int(genome.n_outputs)
    output_ids = [n_inputs + o for o in range(n_outputs)]
    incoming = _enabled_incoming(genome)
    required = _required_nodes(incoming, output_ids, n_inputs)
    order = _topological_order(required, incoming, n_inputs)
    arrays = _evaluator_arrays(genome, order, incoming, output_ids)
    architecture = {
        "type": "neat",
        "n_inputs": n_inputs,
        "n_outputs": n_outputs,
        "activations": list(ACTIVATIONS),
        "n_nodes": len(order),
        "n_connections": len(arrays["sources"]),
    }
    if n_outputs == 1:
        architecture["symmetry"] = "rotations"
    return arrays, architecture


def _enabled_incoming(genome: Any) -> dict[int, list[Any]]:
    """Each node's enabled incoming connection genes, by innovation number.

    Disabled connections do not change what the network computes: they are
    left out here, so that every later step sees the evaluated graph only.
    """
    incoming: dict[int, list[Any]] = {}
    for innovation in sorted(genome.connections):
        gene = genome.connections[innovation]
        if gene.enabled:
            incoming.setdefault(gene.out_node, []).append(gene)
    return incoming


def _required_nodes(
    incoming: Mapping[int, list[Any]], output_ids: list[int], n_inputs: int
) -> set[int]:
    """The non-input nodes that reach an output (walking enabled connections backwards).

    The outputs themselves are included; a hidden node from which no output
    can be reached does not change the outputs and is not evaluated.
    """
    required = set(output_ids)
    stack = list(output_ids)
    while stack:
        node = stack.pop()
        for gene in incoming.get(node, ()):
            source = gene.in_node
            if source >= n_inputs and source not in required:
                required.add(source)
                stack.append(source)
    return required


def _topological_order(
    required: set[int], incoming: Mapping[int, list[Any]], n_inputs: int
) -> list[int]:
    """Kahn's topological order among the required nodes, smallest ready id first.

    The order is the evaluation order (every node after its sources), the same
    one for equal genomes; a cycle of enabled connections has no such order and
    raises :class:`ValueError`.
    """
    pending = {node: 0 for node in required}
    children: dict[int, list[int]] = {}
    for node in required:
        for gene in incoming.get(node, ()):
            if gene.in_node >= n_inputs:
                pending[node] += 1
                children.setdefault(gene.in_node, []).append(node)
    ready = [node for node, count in pending.items() if count == 0]
    heapify(ready)
    order: list[int] = []
    while ready:
        node = heappop(ready)
        order.append(node)
        for child in children.get(node, ()):
            pending[child] -= 1
            if pending[child] == 0:
                heappush(ready, child)
    if len(order) != len(required):
        raise ValueError("the genome's enabled connections form a cycle")
    return order


def _evaluator_arrays(
    genome: Any, order: list[int], incoming: Mapping[int, list[Any]], output_ids: list[int]
) -> dict[str, np.ndarray]:
    """The arrays of :func:`genome_to_arrays`: nodes in ``order``, incoming connections as CSR.

    A connection's source becomes an input index (below ``n_inputs``) or
    ``n_inputs`` + the evaluated-node index of its source node.
    """
    n_inputs = int(genome.n_inputs)
    index = {node: j for j, node in enumerate(order)}
    bias = np.empty(len(order), dtype=np.float64)
    activation = np.empty(len(order), dtype=np.int64)
    indptr = np.zeros(len(order) + 1, dtype=np.int64)
    sources: list[int] = []
    weights: list[float] = []
    for j, node in enumerate(order):
        gene = genome.nodes[node]
        bias[j] = gene.bias
        activation[j] = _CODES[gene.activation]
        for connection in incoming.get(node, ()):
            source = connection.in_node
            sources.append(source if source < n_inputs else n_inputs + index[source])
            weights.append(connection.weight)
        indptr[j + 1] = len(sources)
    return {
        "node_ids": np.asarray(order, dtype=np.int64),
        "bias": bias,
        "activation": activation,
        "indptr": indptr,
        "sources": np.asarray(sources, dtype=np.int64),
        "weights": np.asarray(weights, dtype=np.float64),
        "outputs": np.asarray([index[node] for node in output_ids], dtype=np.int64),
    }


def genomes_to_arrays(genomes: Sequence[Any]) -> list[dict[str, np.ndarray]]:
    """:func:`genome_to_arrays`'s arrays of many genomes (all of one robot), in one compiled call.

    The same arrays, element for element; only the genes are read in Python
    (enabled connections and non-input nodes), the graph work (nodes that
    reach an output, topological order, CSR lists) is compiled. The arrays of
    genome ``g`` are views into arrays shared by the population.
    """
    if not genomes:
        return []
    n_inputs, n_outputs = int(genomes[0].n_inputs), int(genomes[0].n_outputs)
    nodes = [[n for n in g.nodes.values() if n.kind != "input"] for g in genomes]
    edges = [[c for c in g.connections.values() if c.enabled] for g in genomes]
    node_ptr = _offsets([len(n) for n in nodes])
    edge_ptr = _offsets([len(e) for e in edges])
    n_nodes, n_edges = int(node_ptr[-1]), int(edge_ptr[-1])
    node_ids = np.fromiter((n.id for ns in nodes for n in ns), np.int64, n_nodes)
    bias = np.fromiter((n.bias for ns in nodes for n in ns), np.float64, n_nodes)
    codes = np.fromiter((_CODES[n.activation] for ns in nodes for n in ns), np.int64, n_nodes)
    innovation = np.fromiter((c.innovation for es in edges for c in es), np.int64, n_edges)
    source = np.fromiter((c.in_node for es in edges for c in es), np.int64, n_edges)
    target = np.fromiter((c.out_node for es in edges for c in es), np.int64, n_edges)
    weight = np.fromiter((c.weight for es in edges for c in es), np.float64, n_edges)
    out = _compile_kernel(
        n_inputs, n_outputs, node_ptr, node_ids, bias, codes,
        edge_ptr, innovation, source, target, weight,
    )  # fmt: skip
    ok, sizes, counts, order, node_bias, node_act, indptr, sources, weights, outputs = out
    if not ok:
        raise ValueError("the genome's enabled connections form a cycle")
    networks = []
    n0 = e0 = 0
    for g in range(len(genomes)):
        n1, e1 = n0 + int(sizes[g]), e0 + int(counts[g])
        start = n0 + g  # each genome's indptr has one more entry than its nodes
        networks.append(
            {
                "node_ids": order[n0:n1],
                "bias": node_bias[n0:n1],
                "activation": node_act[n0:n1],
                "indptr": indptr[start : start + n1 - n0 + 1],
                "sources": sources[e0:e1],
                "weights": weights[e0:e1],
                "outputs": outputs[g],
            }
        )
        n0, e0 = n1, e1
    return networks


def _offsets(sizes: list[int]) -> np.ndarray:
    offsets = np.zeros(len(sizes) + 1, dtype=np.int64)
    np.cumsum(np.asarray(sizes, dtype=np.int64), out=offsets[1:])
    return offsets


@numba.njit(cache=True, inline="always")
def _node_index(by_id, sorted_ids, node_id):
    """The index in the genome's node list of node ``node_id`` (``sorted_ids = ids[by_id]``)."""
    return by_id[np.searchsorted(sorted_ids, node_id)]


@numba.njit(cache=True)
def _incoming_csr(innovation, target, by_id, sorted_ids):
    """CSR adjacency of one genome: its enabled connections grouped by target node.

    ``innovation`` and ``target`` are the genome's enabled connections (their
    innovation numbers and target node ids), ``by_id`` sorts the genome's node
    ids into ``sorted_ids``. Node ``t``'s incoming connections (indices into
    ``target``) are ``incoming[incoming_ptr[t]:incoming_ptr[t + 1]]``, by
    innovation: the order in which :func:`genome_to_arrays` lists them.
    """
    m = by_id.shape[0]
    n_edges = target.shape[0]
    edges = np.argsort(innovation, kind="mergesort")
    incoming_ptr = np.zeros(m + 1, dtype=np.int64)
    targets = np.empty(n_edges, dtype=np.int64)
    for k in range(n_edges):
        t = _node_index(by_id, sorted_ids, target[edges[k]])
        targets[k] = t
        incoming_ptr[t + 1] += 1
    for t in range(m):
        incoming_ptr[t + 1] += incoming_ptr[t]
    fill = incoming_ptr[:-1].copy()
    incoming = np.empty(n_edges, dtype=np.int64)
    for k in range(n_edges):
        incoming[fill[targets[k]]] = edges[k]
        fill[targets[k]] += 1
    return incoming_ptr, incoming


@numba.njit(cache=True)
def _reachability(n_inputs, n_outputs, incoming_ptr, incoming, source, by_id, sorted_ids):
    """The nodes of one genome that reach an output, walking enabled connections backwards.

    Returns ``required`` (bool per node: an output, or a hidden node with a
    path to one) and ``local`` (per connection, the node index of its source
    when that source is a node reached by the walk; -1 for an input or a
    connection that the walk does not take). Only required nodes are evaluated.
    """
    m = by_id.shape[0]
    local = np.full(source.shape[0], -1, dtype=np.int64)
    required = np.zeros(m, dtype=np.bool_)
    stack = np.empty(m, dtype=np.int64)
    top = 0
    for o in range(n_outputs):
        t = _node_index(by_id, sorted_ids, n_inputs + o)
        required[t] = True
        stack[top] = t
        top += 1
    while top:
        top -= 1
        t = stack[top]
        for k in range(incoming_ptr[t], incoming_ptr[t + 1]):
            src = source[incoming[k]]
            if src >= n_inputs:
                u = _node_index(by_id, sorted_ids, src)
                local[incoming[k]] = u
                if not required[u]:
                    required[u] = True
                    stack[top] = u
                    top += 1
    return required, local


@numba.njit(cache=True)
def _kahn_order(n_inputs, required, incoming_ptr, incoming, source, local, by_id):
    """Kahn's topological order among the required nodes, smallest ready id first.

    Returns ``ok`` (False: the required nodes' enabled connections form a
    cycle), ``order`` (the node indices in evaluation order) and ``position``
    (each node's place in ``order``, -1 for a node left out).
    """
    m = by_id.shape[0]
    pending = np.zeros(m, dtype=np.int64)
    n_required = 0
    for t in range(m):
        if required[t]:
            n_required += 1
            for k in range(incoming_ptr[t], incoming_ptr[t + 1]):
                if source[incoming[k]] >= n_inputs:
                    pending[t] += 1
    position = np.full(m, -1, dtype=np.int64)
    order = np.empty(n_required, dtype=np.int64)
    done = 0
    while done < n_required:
        best = -1
        for r in range(m):  # the ready node of smallest id (ids sorted by by_id)
            t = by_id[r]
            if required[t] and position[t] < 0 and pending[t] == 0:
                best = t
                break
        if best < 0:
            return False, order, position
        position[best] = done
        order[done] = best
        done += 1
        for t in range(m):
            if required[t] and position[t] < 0:
                for k in range(incoming_ptr[t], incoming_ptr[t + 1]):
                    if local[incoming[k]] == best:
                        pending[t] -= 1
    return True, order, position


@numba.njit(cache=True)
def _connection_lists(
    n_inputs, order, position, local, incoming_ptr, incoming, source, weight, indptr_out,
    sources_out, weights_out,
):  # fmt: skip
    """Write one genome's evaluated connections as CSR lists, in evaluation order.

    Node ``order[j]``'s incoming connections (by innovation) fill
    ``sources_out`` and ``weights_out`` from ``indptr_out[j]`` on
    (``indptr_out[0]`` is not written: the caller's buffer holds 0 there); a
    source is an input index, or ``n_inputs`` + the position of its node in
    ``order``. Returns the number of connections written.
    """
    e = 0
    for j in range(order.shape[0]):
        t = order[j]
        for k in range(incoming_ptr[t], incoming_ptr[t + 1]):
            c = incoming[k]
            src = source[c]
            sources_out[e] = src if src < n_inputs else n_inputs + position[local[c]]
            weights_out[e] = weight[c]
            e += 1
        indptr_out[j + 1] = e
    return e


@numba.njit(cache=True)
def _compile_kernel(
    n_inputs, n_outputs, node_ptr, node_ids, bias, codes, edge_ptr, innovation, source, target,
    weight,
):  # fmt: skip
    """:func:`genome_to_arrays` of every genome (see :func:`genomes_to_arrays`).

    Returns ``ok`` (False: a genome has a cycle), per genome its number of
    evaluated nodes and connections, then the concatenated ``node_ids``,
    ``bias``, ``activation``, ``indptr`` (one per genome, each starting at 0),
    ``sources``, ``weights`` and the ``outputs`` ``(n_genomes, n_outputs)``.
    """
    n_genomes = node_ptr.shape[0] - 1
    sizes = np.zeros(n_genomes, dtype=np.int64)
    counts = np.zeros(n_genomes, dtype=np.int64)
    order_all = np.empty(node_ids.shape[0], dtype=np.int64)
    bias_all = np.empty(node_ids.shape[0], dtype=np.float64)
    act_all = np.empty(node_ids.shape[0], dtype=np.int64)
    indptr_all = np.zeros(node_ids.shape[0] + n_genomes, dtype=np.int64)
    sources_all = np.empty(innovation.shape[0], dtype=np.int64)
    weights_all = np.empty(innovation.shape[0], dtype=np.float64)
    outputs_all = np.empty((n_genomes, n_outputs), dtype=np.int64)
    n_out = e_out = 0
    for g in range(n_genomes):
        n0, n1, e0, e1 = node_ptr[g], node_ptr[g + 1], edge_ptr[g], edge_ptr[g + 1]
        ids = node_ids[n0:n1]
        by_id = np.argsort(ids)
        sorted_ids = ids[by_id]
        incoming_ptr, incoming = _incoming_csr(innovation[e0:e1], target[e0:e1], by_id, sorted_ids)
        required, local = _reachability(
            n_inputs, n_outputs, incoming_ptr, incoming, source[e0:e1], by_id, sorted_ids
        )
        ok, order, position = _kahn_order(
            n_inputs, required, incoming_ptr, incoming, source[e0:e1], local, by_id
        )
        if not ok:
            return (
                False, sizes, counts, order_all, bias_all, act_all, indptr_all,
                sources_all, weights_all, outputs_all,
            )  # fmt: skip
        n = order.shape[0]
        for j in range(n):
            order_all[n_out + j] = ids[order[j]]
            bias_all[n_out + j] = bias[n0 + order[j]]
            act_all[n_out + j] = codes[n0 + order[j]]
        counts[g] = _connection_lists(
            n_inputs, order, position, local, incoming_ptr, incoming, source[e0:e1],
            weight[e0:e1], indptr_all[n_out + g :], sources_all[e_out:], weights_all[e_out:],
        )  # fmt: skip
        for o in range(n_outputs):
            outputs_all[g, o] = position[_node_index(by_id, sorted_ids, n_inputs + o)]
        sizes[g] = n
        n_out += n
        e_out += counts[g]
    return (
        True, sizes, counts, order_all, bias_all, act_all, indptr_all, sources_all, weights_all,
        outputs_all,
    )  # fmt: skip


def _checked_architecture(architecture: Any) -> tuple[int, int, list[str]]:
    """``n_inputs``, ``n_outputs`` and ``activations`` of a NEAT architecture, type-checked.

    ``symmetry`` (:func:`architecture_symmetry`) is checked by its own reader.

    The architecture comes from a file's JSON metadata: every field is checked
    (positive integers, a list of names; ``n_nodes`` and ``n_connections``, when
    present, non-negative integers) and a bad one raises
    :class:`~evolution.EvolutionConfigError` naming it.
    """
    if not isinstance(architecture, Mapping):
        raise EvolutionConfigError(
            f"NEAT agent architecture must be a JSON object, not {type(architecture).__name__}"
        )
    for key in ("n_inputs", "n_outputs", "activations"):
        if key not in architecture:
            raise EvolutionConfigError(f"NEAT agent architecture lacks '{key}'")
    n_inputs, n_outputs = (
        check_integer(
            f"NEAT agent architecture '{key}'",
            architecture[key],
            minimum=1,
            error=EvolutionConfigError,
        )
        for key in ("n_inputs", "n_outputs")
    )
    for key in ("n_nodes", "n_connections"):
        if key in architecture:
            check_integer(
                f"NEAT agent architecture '{key}'",
                architecture[key],
                minimum=0,
                error=EvolutionConfigError,
            )
    names = architecture["activations"]
    if not (isinstance(names, list) and names and all(isinstance(n, str) for n in names)):
        raise EvolutionConfigError(
            f"NEAT agent architecture 'activations' {names!r} is not a list of activation names"
        )
    return n_inputs, n_outputs, list(names)


def architecture_symmetry(architecture: Mapping[str, Any]) -> str:
    """The ``symmetry`` of a NEAT architecture: ``"none"`` when absent (older files)."""
    return check_symmetry(
        architecture.get("symmetry", "none"), name="NEAT agent architecture 'symmetry'"
    )


def _checked_arrays(
    arrays: Mapping[str, np.ndarray], architecture: Mapping[str, Any]
) -> dict[str, np.ndarray]:
    """``arrays`` validated against ``architecture`` (user input: an agent file).

    Every array must have its dtype kind (integers, or finite floats), be 1-d,
    and agree with the others and with the architecture (sizes, CSR offsets,
    feed-forward sources, output and activation indices); any fault raises
    :class:`~evolution.EvolutionConfigError` naming the array or field.
    """
    n_inputs, n_outputs, names = _checked_architecture(architecture)
    missing = [key for key in ARRAY_KEYS if key not in arrays]
    if missing:
        raise EvolutionConfigError(f"NEAT agent arrays lack {', '.join(missing)}")
    out = {key: np.asarray(arrays[key]) for key in ARRAY_KEYS}
    for key in ("node_ids", "activation", "indptr", "sources", "outputs"):
        if out[key].ndim != 1 or not np.issubdtype(out[key].dtype, np.integer):
            raise EvolutionConfigError(f"NEAT agent array '{key}' must be a 1-d integer array")
        if out[key].dtype == np.uint64 and np.any(out[key] > np.iinfo(np.int64).max):
            raise EvolutionConfigError(f"NEAT agent array '{key}' holds values out of range")
        out[key] = out[key].astype(np.int64)
    for key in ("bias", "weights"):
        if out[key].ndim != 1 or not np.issubdtype(out[key].dtype, np.floating):
            raise EvolutionConfigError(f"NEAT agent array '{key}' must be a 1-d float array")
        out[key] = out[key].astype(np.float64)
        if not np.all(np.isfinite(out[key])):
            raise EvolutionConfigError(f"NEAT agent array '{key}' holds non-finite values")
    n_nodes, n_edges = out["bias"].shape[0], out["weights"].shape[0]
    for key, count in (("n_nodes", n_nodes), ("n_connections", n_edges)):
        if key in architecture and architecture[key] != count:
            raise EvolutionConfigError(
                f"NEAT agent architecture '{key}' {architecture[key]} does not match the"
                f" arrays ({count})"
            )
    indptr = out["indptr"]
    if (
        out["activation"].shape[0] != n_nodes
        or out["node_ids"].shape[0] != n_nodes
        or indptr.shape[0] != n_nodes + 1
        or out["sources"].shape[0] != n_edges
        or indptr[0] != 0
        or indptr[-1] != n_edges
        or np.any(np.diff(indptr) < 0)
    ):
        raise EvolutionConfigError("NEAT agent arrays have inconsistent sizes")
    if out["outputs"].shape[0] != n_outputs or np.any(
        (out["outputs"] < 0) | (out["outputs"] >= n_nodes)
    ):
        raise EvolutionConfigError(f"NEAT agent 'outputs' must be {n_outputs} node indices")
    # a source must be an input or an earlier node (feed-forward)
    target = np.repeat(np.arange(n_nodes), np.diff(indptr))
    sources = out["sources"]
    if np.any((sources < 0) | ((sources >= n_inputs) & (sources - n_inputs >= target))):
        raise EvolutionConfigError("NEAT agent 'sources' are not in feed-forward order")
    codes = out["activation"]
    if np.any((codes < 0) | (codes >= len(names))):
        raise EvolutionConfigError("NEAT agent 'activation' codes out of range")
    unknown = sorted({names[c] for c in codes.tolist()} - set(_CODES))
    if unknown:
        raise EvolutionConfigError(f"unknown NEAT activation {unknown[0]!r}")
    remap = np.asarray([_CODES.get(name, -1) for name in names], dtype=np.int64)
    out["activation"] = remap[codes] if len(codes) else codes
    return out


# -----------------------------------------------------------------------------
# Kernels
#
# The agents of a genome are evaluated in blocks of at most _BLOCK: node by
# node, each connection is applied to the whole block (an inner loop over
# agents, independent iterations the compiler vectorises) instead of one agent
# after another (a chain of dependent additions and activations). On a
# population of 100 genomes x 72 agents this is 2 to 5 times faster.

_BLOCK = 64


@numba.njit(cache=True, inline="always")
def _activate(code, x):
    """Activation ``code`` of one value, as :func:`_activate_row`."""
    if code == 1:
        return 1.0 - 2.0 / (np.exp(2.0 * x) + 1.0)
    if code == 2:
        return 1.0 / (1.0 + np.exp(-x))
    if code == 3:
        return x if x > 0.0 else 0.0
    if code == 4:
        return np.exp(-x * x)
    if code == 5:
        return np.sin(x)
    return x


@numba.njit(cache=True, inline="always")
def _activate_row(code, buf, i, width):
    """Apply activation ``code`` to ``buf[i, :width]`` (tanh through exp: faster than libm's)."""
    if code == 1:
        for a in range(width):
            buf[i, a] = 1.0 - 2.0 / (np.exp(2.0 * buf[i, a]) + 1.0)
    elif code == 2:
        for a in range(width):
            buf[i, a] = 1.0 / (1.0 + np.exp(-buf[i, a]))
    elif code == 3:
        for a in range(width):
            if buf[i, a] < 0.0:
                buf[i, a] = 0.0
    elif code == 4:
        for a in range(width):
            buf[i, a] = np.exp(-buf[i, a] * buf[i, a])
    elif code == 5:
        for a in range(width):
            buf[i, a] = np.sin(buf[i, a])


@numba.njit(cache=True, inline="always")
def _forward_block(g, k0, width, x, node_start, bias, act, indptr, mid, src, w, out_pos, buf, out):
    """Agents ``k0 .. k0 + width - 1``, all of genome ``g``: node values in ``buf``, outputs."""
    start = node_start[g]
    if width == 1:  # one agent: accumulate in a register
        for j in range(start, node_start[g + 1]):
            total = bias[j]
            for e in range(indptr[j], mid[j]):
                total += w[e] * x[k0, src[e]]
            for e in range(mid[j], indptr[j + 1]):
                total += w[e] * buf[src[e], 0]
            buf[j - start, 0] = _activate(act[j], total)
        for o in range(out.shape[1]):
            out[k0, o] = buf[out_pos[g, o], 0]
        return
    for j in range(start, node_start[g + 1]):
        i = j - start
        b = bias[j]
        for a in range(width):
            buf[i, a] = b
        for e in range(indptr[j], mid[j]):
            q = src[e]
            weight = w[e]
            for a in range(width):
                buf[i, a] += weight * x[k0 + a, q]
        for e in range(mid[j], indptr[j + 1]):
            q = src[e]
            weight = w[e]
            for a in range(width):
                buf[i, a] += weight * buf[q, a]
        _activate_row(act[j], buf, i, width)
    for o in range(out.shape[1]):
        q = out_pos[g, o]
        for a in range(width):
            out[k0 + a, o] = buf[q, a]


@numba.njit(cache=True, inline="always")
def _task(t, per_genome, n_blocks):
    """Genome, first agent and width of block task ``t`` (blocks of a genome split evenly)."""
    g = t // n_blocks
    b = t - g * n_blocks
    size = (per_genome + n_blocks - 1) // n_blocks
    first = b * size
    width = min(size, per_genome - first)
    return g, g * per_genome + first, width


@numba.njit(cache=True, nogil=True)
def _forward_serial(x, per_genome, node_start, bias, act, indptr, mid, src, w, out_pos, out):
    n_blocks = (per_genome + _BLOCK - 1) // _BLOCK
    n_genomes = node_start.shape[0] - 1
    max_nodes = 1
    for g in range(n_genomes):
        max_nodes = max(max_nodes, node_start[g + 1] - node_start[g])
    buf = np.empty((max_nodes, _BLOCK))
    for t in range(n_genomes * n_blocks):
        g, k0, width = _task(t, per_genome, n_blocks)
        _forward_block(
            g, k0, width, x, node_start, bias, act, indptr, mid, src, w, out_pos, buf, out
        )


@numba.njit(cache=True, nogil=True, parallel=True)
def _forward_parallel(x, per_genome, node_start, bias, act, indptr, mid, src, w, out_pos, out):
    n_blocks = (per_genome + _BLOCK - 1) // _BLOCK
    n_genomes = node_start.shape[0] - 1
    max_nodes = 1
    for g in range(n_genomes):
        max_nodes = max(max_nodes, node_start[g + 1] - node_start[g])
    for t in prange(n_genomes * n_blocks):
        buf = np.empty((max_nodes, _BLOCK))
        g, k0, width = _task(t, per_genome, n_blocks)
        _forward_block(
            g, k0, width, x, node_start, bias, act, indptr, mid, src, w, out_pos, buf, out
        )


# -----------------------------------------------------------------------------
# The population policy


class GenomePopulation:
    """P compiled genomes playing together: the NEAT population policy.

    A batch of ``n`` observations (``n`` a multiple of P) is split in P
    consecutive blocks of ``M = n // P`` agents: agent ``k`` uses genome
    ``k // M``. ``reset(n_agents)`` (called by :func:`amaze.evaluation.policy.run_episodes`)
    checks the batch size. ``parallel`` picks the multi-threaded kernel (both
    give identical results); ``None`` decides from the batch size and the
    machine's load. Build it with :meth:`from_genomes` or
    :func:`policy_from_arrays`; ``networks`` are arrays of :func:`genome_to_arrays`.

    With ``symmetry`` ``"rotations"`` each genome has one output, the score
    of the direction that lies east: an observation is played as four rows,
    the cell turned so that each side in turn lies east
    (:func:`~evolution.networks.rotation_index`: the 8 inputs of DD robots
    shifted, the image of H and CC robots turned), and the action is the
    first best of the four scores, or for continuous robots the acceleration
    :func:`~evolution.networks.turned_accelerations` of them, as with
    :class:`~evolution.networks.NetworkSpec`'s.
    """

    def __init__(
        self,
        networks: Sequence[Mapping[str, np.ndarray]],
        robot: Robot | str,
        *,
        symmetry: str = "none",
        parallel: bool | None = None,
    ) -> None:
        self.robot = as_robot(robot)
        self.symmetry = symmetry
        self.n_inputs, self.n_outputs = robot_io(self.robot, symmetry)
        self._turns = (
            rotation_index(None if self.robot.discrete_inputs else int(self.robot.vision))
            if symmetry == "rotations"
            else None
        )
        if not networks:
            raise ValueError("a genome population needs at least one genome")
        self.n_policies = len(networks)
        self.parallel = parallel
        #: The genomes' arrays, for :meth:`subset` and pickling (the rest derives from them).
        self.networks = [dict(arrays) for arrays in networks]
        n_inputs = self.n_inputs
        sizes = np.asarray([len(a["bias"]) for a in networks], dtype=np.int64)
        edges = np.asarray([len(a["weights"]) for a in networks], dtype=np.int64)
        self._node_start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self._bias = np.concatenate([a["bias"] for a in networks]).astype(np.float64)
        self._act = np.concatenate([a["activation"] for a in networks]).astype(np.int64)
        counts = np.concatenate([np.diff(a["indptr"]) for a in networks]).astype(np.int64)
        sources = np.concatenate([a["sources"] for a in networks]).astype(np.int64)
        weights = np.concatenate([a["weights"] for a in networks]).astype(np.float64)
        for arrays in networks:
            if len(arrays["outputs"]) != self.n_outputs:
                raise EvolutionConfigError(
                    f"a genome has {len(arrays['outputs'])} outputs, "
                    f"robot {self.robot} needs {self.n_outputs}"
                )
        self._out_pos = np.stack([a["outputs"] for a in networks]).astype(np.int64)
        # each node's incoming connections: from inputs first (up to ``mid``), then from
        # nodes (sources as node indices); input weights take the input scaling (1/255
        # for gray levels)
        target = np.repeat(np.arange(len(counts)), counts)
        from_input = sources < n_inputs
        order = np.lexsort((~from_input, target))
        self._indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self._mid = self._indptr[:-1] + np.bincount(
            target[from_input], minlength=len(counts)
        ).astype(np.int64)
        divisor = 1.0 if self.robot.discrete_inputs else 255.0
        self._src = np.where(from_input, sources, sources - n_inputs)[order].astype(np.int64)
        self._w = np.where(from_input, weights / divisor, weights)[order]
        self._mean_edges = float(edges.mean())

    @classmethod
    def from_genomes(
        cls,
        genomes: Sequence[Any],
        robot: Robot | str,
        *,
        symmetry: str = "none",
        parallel: bool | None = None,
    ) -> GenomePopulation:
        """Compile NEAT genomes (all for ``robot`` and ``symmetry``) into one population policy."""
        robot = as_robot(robot)
        n_inputs, n_outputs = robot_io(robot, symmetry)
        for genome in genomes:
            if (genome.n_inputs, genome.n_outputs) != (n_inputs, n_outputs):
                raise EvolutionConfigError(
                    f"a genome with {genome.n_inputs} inputs and {genome.n_outputs} outputs "
                    f"does not fit robot {robot} ({n_inputs} inputs, {n_outputs} outputs)"
                )
        return cls(genomes_to_arrays(genomes), robot, symmetry=symmetry, parallel=parallel)

    def __reduce__(self) -> tuple[Any, ...]:
        return (
            _rebuild_population,
            (self.networks, self.robot, self.symmetry),
            {"parallel": self.parallel},
        )

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.parallel = state.get("parallel")

    def __len__(self) -> int:
        return self.n_policies

    def subset(self, indices: Sequence[int] | np.ndarray) -> GenomePopulation:
        """The population of the genomes ``indices`` (in that order), for distributed evaluation."""
        indices = np.asarray(indices, dtype=np.int64).reshape(-1)
        if indices.size == 0 or indices.min() < 0 or indices.max() >= self.n_policies:
            raise EvolutionConfigError(
                f"subset: give at least one index, each in [0, {self.n_policies})"
            )
        return GenomePopulation(
            [self.networks[i] for i in indices.tolist()],
            self.robot,
            symmetry=self.symmetry,
            parallel=self.parallel,
        )

    def reset(self, n_agents: int) -> None:
        """Check that batches of ``n_agents`` observations can be shared by the P genomes."""
        self._agents_per_genome(int(n_agents))

    def _agents_per_genome(self, n: int) -> int:
        if n < self.n_policies or n % self.n_policies:
            raise ValueError(
                f"{n} agents cannot be shared equally by {self.n_policies} genomes "
                "(n_agents must be a positive multiple of the number of genomes)"
            )
        return n // self.n_policies

    def _inputs(self, observations: np.ndarray) -> np.ndarray:
        obs = np.asarray(observations)
        if self.robot.discrete_inputs:
            if obs.ndim != 2 or obs.shape[1] != self.n_inputs:
                raise ValueError(f"expected observations (n, {self.n_inputs}), got {obs.shape}")
            return np.ascontiguousarray(obs)
        v = int(self.robot.vision)
        if obs.shape[1:] not in ((1, v, v), (v, v)):
            raise ValueError(f"expected images (n, 1, {v}, {v}), got {obs.shape}")
        return np.ascontiguousarray(obs).reshape(obs.shape[0], v * v)

    def outputs(self, observations: np.ndarray) -> np.ndarray:
        """The output node values, float64 ``(n, n_outputs)``; with rotations ``(n, 4)``.

        With rotations, column ``d`` is the genome's output on the cell turned
        so that side ``d`` (E, N, W, S) lies east.
        """
        x = self._inputs(observations)
        n = x.shape[0]
        per_genome = self._agents_per_genome(n)
        if self._turns is not None:  # each agent as 4 consecutive rows, one per direction
            x = np.ascontiguousarray(x[:, self._turns].reshape(4 * n, -1))
            per_genome, n = 4 * per_genome, 4 * n
        out = np.empty((n, self.n_outputs), dtype=np.float64)
        parallel = self.parallel
        if parallel is None:
            parallel = threads_pay_off(int(n * max(self._mean_edges, 1.0)), _PARALLEL_MIN_WORK)
        kernel = _forward_parallel if parallel else _forward_serial
        kernel(
            x,
            per_genome,
            self._node_start,
            self._bias,
            self._act,
            self._indptr,
            self._mid,
            self._src,
            self._w,
            self._out_pos,
            out,
        )
        return out if self._turns is None else out.reshape(n // 4, 4)

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """Actions: int64 argmax (E, N, W, S) or float64 accelerations ``(n, 2)``
        (with rotations, :func:`~evolution.networks.turned_accelerations` of the scores)."""
        out = self.outputs(observations)
        if self.robot.discrete_outputs:
            return np.argmax(out, axis=1).astype(np.int64)
        if self._turns is not None:  # the four directions' scores
            return turned_accelerations(out)
        return out


def _rebuild_population(
    networks: Sequence[Mapping[str, np.ndarray]], robot: Robot | str, symmetry: str
) -> GenomePopulation:
    """A pickled :class:`GenomePopulation` rebuilt (its ``symmetry`` is keyword-only)."""
    return GenomePopulation(networks, robot, symmetry=symmetry)


def policy_from_arrays(
    arrays: Mapping[str, np.ndarray], architecture: Mapping[str, Any], robot: Robot | str
) -> GenomePopulation:
    """A population of one compiled genome (from :func:`genome_to_arrays`) for ``robot``.

    It plays any number of agents, all with that genome. The architecture and
    the arrays are checked (they may come from an agent file): a field of the
    wrong type, missing keys, wrong dtypes, non-finite values, inconsistent
    sizes, connections that are not feed-forward or a robot that does not fit
    raise :class:`~evolution.EvolutionConfigError`.
    """
    robot = as_robot(robot)
    stored_inputs, stored_outputs, _ = _checked_architecture(architecture)
    symmetry = architecture_symmetry(architecture)
    n_inputs, n_outputs = robot_io(robot, symmetry)
    if (stored_inputs, stored_outputs) != (n_inputs, n_outputs):
        raise EvolutionConfigError(
            f"a NEAT agent with {stored_inputs} inputs and {stored_outputs} outputs does not"
            f" fit robot {robot} ({n_inputs} inputs, {n_outputs} outputs)"
        )
    return GenomePopulation([_checked_arrays(arrays, architecture)], robot, symmetry=symmetry)
