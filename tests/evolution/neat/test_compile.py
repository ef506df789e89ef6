"""Genomes compiled to the batched evaluator: outputs, actions, agent-file arrays."""

from __future__ import annotations

import io
import json
import pickle
import random

import numpy as np
import pytest

from evolution import EvolutionConfigError
from evolution.neat import (
    GenomePopulation,
    InnovationTracker,
    NeatConfig,
    genome_to_arrays,
    mutate_add_node,
    new_genome,
    policy_from_arrays,
)
from evolution.neat.compile import genomes_to_arrays
from evolution.networks import rotation_index
from tests.evolution.neat.conftest import grown_genomes, reference_outputs


@pytest.mark.parametrize("robot", ["DD", "H5", "CC5"])
@pytest.mark.parametrize("per_genome", [1, 3, 70])
@pytest.mark.parametrize("parallel", [False, True])
def test_compiled_population_matches_reference_evaluation(robot, per_genome, parallel):
    genomes = grown_genomes(robot, count=5, steps=25, seed=len(robot) + per_genome)
    assert max(g.n_hidden for g in genomes) >= 5
    assert any(not c.enabled for g in genomes for c in g.connections.values())
    policy = GenomePopulation.from_genomes(genomes, robot, parallel=parallel)
    n = len(genomes) * per_genome
    rng = np.random.default_rng(per_genome)
    if robot == "DD":
        obs = (rng.random((n, 8)) * 2 - 0.5).astype(np.float32)
        scaled = obs.astype(np.float64)
    else:
        obs = rng.integers(0, 256, (n, 1, 5, 5), dtype=np.uint8)
        scaled = obs.reshape(n, 25).astype(np.float64) / 255.0
    policy.reset(n)
    outputs = policy.outputs(obs)
    expected = np.asarray(
        [reference_outputs(genomes[k // per_genome], scaled[k]) for k in range(n)]
    )
    np.testing.assert_allclose(outputs, expected, rtol=1e-12, atol=1e-12)
    actions = policy(obs)
    if robot == "CC5":
        assert actions.dtype == np.float64 and actions.shape == (n, 2)
        assert np.all(np.abs(actions) <= 1.0)
        np.testing.assert_array_equal(actions, outputs)
    else:
        assert actions.dtype == np.int64 and actions.shape == (n,)
        ranked = np.sort(expected, axis=1)
        clear = ranked[:, -1] - ranked[:, -2] > 1e-9
        np.testing.assert_array_equal(actions[clear], np.argmax(expected, axis=1)[clear])


def test_argmax_takes_the_first_maximum_on_ties():
    tracker = InnovationTracker(8, 4)
    genome = new_genome("DD", tracker, NeatConfig())
    for gene in genome.connections.values():
        gene.weight = 0.0
    for o in range(8, 12):
        genome.nodes[o].bias = 1.0 if o in (9, 11) else 0.0
    actions = GenomePopulation.from_genomes([genome], "DD")(np.ones((3, 8), np.float32))
    np.testing.assert_array_equal(actions, [1, 1, 1])


def test_population_policy_checks_the_batch_size():
    genomes = grown_genomes("DD", count=3, steps=2, seed=0)
    policy = GenomePopulation.from_genomes(genomes, "DD")
    with pytest.raises(ValueError, match="multiple"):
        policy.reset(7)
    with pytest.raises(ValueError, match="observations"):
        policy(np.zeros((6, 5), np.float32))
    with pytest.raises(EvolutionConfigError, match="CD5"):
        GenomePopulation.from_genomes(genomes, "H5")


def test_arrays_round_trip_gives_identical_actions():
    genomes = grown_genomes("H5", count=3, steps=20, seed=4)
    arrays, architecture = genome_to_arrays(genomes[1])
    architecture = json.loads(json.dumps(architecture))
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    buffer.seek(0)
    loaded = dict(np.load(buffer))
    alone = policy_from_arrays(loaded, architecture, "H5")
    assert alone.n_policies == 1 and str(alone.robot) == "CD5"
    obs = np.random.default_rng(1).integers(0, 256, (12, 1, 5, 5), dtype=np.uint8)
    together = GenomePopulation.from_genomes(genomes, "H5")(np.concatenate([obs] * 3))
    np.testing.assert_array_equal(alone(obs), together[12:24])
    np.testing.assert_array_equal(alone(obs[:1]), together[12:13])
    np.testing.assert_array_equal(
        alone.outputs(obs), GenomePopulation.from_genomes([genomes[1]], "H5").outputs(obs)
    )
    with pytest.raises(EvolutionConfigError, match="robot DD"):
        policy_from_arrays(loaded, architecture, "DD")
    broken = dict(loaded, sources=loaded["sources"].copy())
    broken["sources"][-1] = 25 + len(loaded["bias"])  # a node not yet evaluated
    with pytest.raises(EvolutionConfigError, match="feed-forward"):
        policy_from_arrays(broken, architecture, "H5")
    with pytest.raises(EvolutionConfigError, match="weights"):
        policy_from_arrays({k: v for k, v in loaded.items() if k != "weights"}, architecture, "H5")


def test_unreachable_nodes_and_disabled_connections_are_left_out():
    random.seed(2)
    tracker = InnovationTracker(8, 4)
    genome = new_genome("DD", tracker, NeatConfig())
    mutate_add_node(genome, tracker, NeatConfig())
    hidden = max(genome.nodes)
    for gene in genome.connections.values():
        if gene.in_node == hidden:
            gene.enabled = False  # the hidden node no longer reaches an output
    arrays, architecture = genome_to_arrays(genome)
    assert hidden not in arrays["node_ids"]
    assert architecture["n_nodes"] == 4
    assert architecture["n_connections"] == 31  # 32 initial, one split and disabled


@pytest.mark.parametrize("robot", ["DD", "H5", "CC5"])
def test_population_compilation_gives_each_genomes_arrays(robot):
    genomes = grown_genomes(robot, 40, 25, seed=21)
    genomes[5].connections = {}  # outputs with bias only
    for gene in genomes[6].connections.values():
        gene.enabled = False
    batch = genomes_to_arrays(genomes)
    assert len(batch) == len(genomes)
    for genome, arrays in zip(genomes, batch, strict=True):
        expected = genome_to_arrays(genome)[0]
        assert arrays.keys() == expected.keys()
        for key, value in expected.items():
            assert arrays[key].dtype == value.dtype, key
            np.testing.assert_array_equal(arrays[key], value, err_msg=key)
    assert genomes_to_arrays([]) == []


def test_population_compilation_refuses_a_cycle():
    genome = grown_genomes("DD", 1, 0, seed=2)[0]
    tracker = InnovationTracker(8, 4)
    random.seed(1)
    mutate_add_node(genome, tracker, NeatConfig())
    hidden = max(genome.nodes)
    output = next(c.out_node for c in genome.connections.values() if c.in_node == hidden)
    back = tracker.connection(output, hidden)
    genome.connections[back] = type(genome.connections[0])(back, output, hidden, 0.5)
    with pytest.raises(ValueError, match="cycle"):
        genome_to_arrays(genome)
    with pytest.raises(ValueError, match="cycle"):
        genomes_to_arrays([grown_genomes("DD", 1, 3, seed=4)[0], genome])


@pytest.mark.parametrize("robot", ["DD", "H5"])
def test_rotations_score_each_direction_on_the_cell_turned_that_way(robot: str) -> None:
    genomes = grown_genomes(robot, count=3, steps=25, seed=5, symmetry="rotations")
    assert {g.n_outputs for g in genomes} == {1}
    policy = GenomePopulation.from_genomes(genomes, robot, symmetry="rotations")
    rng = np.random.default_rng(2)
    n = 3 * 40
    if robot == "DD":
        obs = rng.random((n, 8)).astype(np.float32)
        cells, scaled = obs, obs.astype(np.float64)
    else:
        obs = rng.integers(0, 256, (n, 1, 5, 5), dtype=np.uint8)
        cells, scaled = obs.reshape(n, 25), obs.reshape(n, 25).astype(np.float64) / 255.0
    turns = rotation_index(None if robot == "DD" else 5)
    outputs = policy.outputs(obs)
    assert outputs.shape == (n, 4)
    expected = [
        [reference_outputs(genomes[k // 40], scaled[k][turns[d]])[0] for d in range(4)]
        for k in range(n)
    ]
    np.testing.assert_allclose(outputs, expected, rtol=1e-12, atol=1e-12)
    # turn the cell: the action turns with it
    actions = policy(obs)
    for r in range(1, 4):
        turned = cells[:, turns[r]].reshape(obs.shape)
        np.testing.assert_array_equal(policy(turned), (actions - r) % 4)


def test_a_symmetric_agent_file_round_trips_and_pickles() -> None:
    genomes = grown_genomes("DD", count=2, steps=20, seed=6, symmetry="rotations")
    arrays, architecture = genome_to_arrays(genomes[1])
    assert architecture["symmetry"] == "rotations" and architecture["n_outputs"] == 1
    architecture = json.loads(json.dumps(architecture))
    alone = policy_from_arrays(arrays, architecture, "DD")
    obs = np.random.default_rng(3).random((20, 8)).astype(np.float32)
    together = GenomePopulation.from_genomes(genomes, "DD", symmetry="rotations")
    np.testing.assert_array_equal(alone(obs), together(np.concatenate([obs] * 2))[20:])
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(together))(obs[:2]), together(obs[:2]))
    np.testing.assert_array_equal(together.subset([1])(obs), alone(obs))
    with pytest.raises(EvolutionConfigError, match="'symmetry' 'sideways'"):
        policy_from_arrays(arrays, {**architecture, "symmetry": "sideways"}, "DD")
    with pytest.raises(EvolutionConfigError, match="1 outputs"):
        policy_from_arrays(arrays, {k: v for k, v in architecture.items() if k != "symmetry"}, "DD")


def test_a_symmetric_genome_accelerates_along_the_difference_of_its_scores() -> None:
    genomes = grown_genomes("CC5", count=2, steps=30, seed=4, symmetry="rotations")
    population = GenomePopulation.from_genomes(genomes, "CC5", symmetry="rotations")
    obs = np.random.default_rng(5).integers(0, 256, (40, 1, 5, 5)).astype(np.uint8)
    scores = population.outputs(obs)
    assert scores.shape == (40, 4)
    accelerations = population(obs)
    np.testing.assert_allclose(
        accelerations,
        np.tanh(np.stack([scores[:, 0] - scores[:, 2], scores[:, 1] - scores[:, 3]], 1)),
        atol=1e-6,
    )
    ax, ay = accelerations.T  # the image turned a quarter-turn counterclockwise: (-ay, ax)
    turned = np.ascontiguousarray(np.rot90(obs, 1, axes=(2, 3)))
    np.testing.assert_array_equal(population(turned), np.stack([-ay, ax], axis=1))
