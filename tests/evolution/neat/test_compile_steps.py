"""The steps of the compiled population compilation, each alone on a small hand-made graph.

One genome with inputs 0 and 1, output 2 and hidden nodes 5, 3 and 7, listed
in that order (node indices 0: node 2, 1: node 5, 2: node 3, 3: node 7), and
seven enabled connections (index: innovation, source -> target)::

    c0: 4, 0 -> 3      c1: 3, 3 -> 2      c2: 1, 5 -> 2      c3: 0, 1 -> 5
    c4: 2, 3 -> 5      c5: 5, 0 -> 7      c6: 6, 1 -> 2

Node 7 reaches no output. The expected answers below are worked out by hand.
"""

from __future__ import annotations

import numpy as np

from evolution.neat.compile import (
    _connection_lists,
    _incoming_csr,
    _kahn_order,
    _reachability,
)

N_INPUTS, N_OUTPUTS = 2, 1
IDS = np.array([2, 5, 3, 7], dtype=np.int64)
BY_ID = np.argsort(IDS)  # [0, 2, 1, 3]
SORTED_IDS = IDS[BY_ID]  # [2, 3, 5, 7]
INNOVATION = np.array([4, 3, 1, 0, 2, 5, 6], dtype=np.int64)
SOURCE = np.array([0, 3, 5, 1, 3, 0, 1], dtype=np.int64)
TARGET = np.array([3, 2, 2, 5, 5, 7, 2], dtype=np.int64)

# node 2: c2, c1, c6; node 5: c3, c4; node 3: c0; node 7: c5 (each by innovation)
INCOMING_PTR = np.array([0, 3, 5, 6, 7], dtype=np.int64)
INCOMING = np.array([2, 1, 6, 3, 4, 0, 5], dtype=np.int64)
# nodes 2, 5 and 3 reach the output; c1 and c4 come from node 3 (index 2), c2 from node 5 (1)
REQUIRED = np.array([True, True, True, False])
LOCAL = np.array([-1, 2, 1, -1, 2, -1, -1], dtype=np.int64)
# node 3 first (its sources are inputs), then node 5, then the output
ORDER = np.array([2, 1, 0], dtype=np.int64)
POSITION = np.array([2, 1, 0, -1], dtype=np.int64)


def test_incoming_csr_groups_connections_by_target_in_innovation_order():
    incoming_ptr, incoming = _incoming_csr(INNOVATION, TARGET, BY_ID, SORTED_IDS)
    np.testing.assert_array_equal(incoming_ptr, INCOMING_PTR)
    np.testing.assert_array_equal(incoming, INCOMING)


def test_reachability_marks_the_nodes_that_reach_an_output():
    required, local = _reachability(
        N_INPUTS, N_OUTPUTS, INCOMING_PTR, INCOMING, SOURCE, BY_ID, SORTED_IDS
    )
    np.testing.assert_array_equal(required, REQUIRED)
    np.testing.assert_array_equal(local, LOCAL)


def test_kahn_order_puts_every_node_after_its_sources():
    ok, order, position = _kahn_order(
        N_INPUTS, REQUIRED, INCOMING_PTR, INCOMING, SOURCE, LOCAL, BY_ID
    )
    assert ok
    np.testing.assert_array_equal(order, ORDER)
    np.testing.assert_array_equal(position, POSITION)


def test_kahn_order_takes_the_smallest_ready_id_first():
    # output 2 <- 6 (c0) and 4 (c1); 6 <- input 0 (c2), 4 <- input 1 (c3): 4 and 6 are
    # ready together, and node 4 (index 2) comes before node 6 (index 1)
    ids = np.array([2, 6, 4], dtype=np.int64)
    ok, order, position = _kahn_order(
        2,
        np.ones(3, dtype=np.bool_),
        np.array([0, 2, 3, 4], dtype=np.int64),
        np.array([0, 1, 2, 3], dtype=np.int64),
        np.array([6, 4, 0, 1], dtype=np.int64),
        np.array([1, 2, -1, -1], dtype=np.int64),
        np.argsort(ids),
    )
    assert ok
    np.testing.assert_array_equal(order, [2, 1, 0])
    np.testing.assert_array_equal(position, [2, 1, 0])


def test_kahn_order_reports_a_cycle():
    # output 2 <- 5 (c0), 5 <- 6 (c1), 6 <- 5 (c2): no node of the cycle is ever ready
    ids = np.array([2, 5, 6], dtype=np.int64)
    ok, _, _ = _kahn_order(
        2,
        np.ones(3, dtype=np.bool_),
        np.array([0, 1, 2, 3], dtype=np.int64),
        np.array([0, 1, 2], dtype=np.int64),
        np.array([5, 6, 5], dtype=np.int64),
        np.array([1, 2, 1], dtype=np.int64),
        np.argsort(ids),
    )
    assert not ok


def test_connection_lists_write_the_evaluated_connections_in_order():
    weight = np.array([0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5])
    indptr = np.full(4, -1, dtype=np.int64)
    sources = np.full(8, -1, dtype=np.int64)
    weights = np.full(8, -1.0)
    count = _connection_lists(
        N_INPUTS, ORDER, POSITION, LOCAL, INCOMING_PTR, INCOMING, SOURCE, weight,
        indptr, sources, weights,
    )  # fmt: skip
    assert count == 6
    # node 3: input 0; node 5: input 1, node 3 (2 + 0); output: node 5 (2 + 1), node 3, input 1
    np.testing.assert_array_equal(indptr, [-1, 1, 3, 6])
    np.testing.assert_array_equal(sources, [0, 1, 2, 3, 2, 1, -1, -1])
    np.testing.assert_array_equal(weights, [0.5, 3.5, 4.5, 2.5, 1.5, 6.5, -1.0, -1.0])
