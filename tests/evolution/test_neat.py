"""The NEAT-like algorithm: genome operators, species, the compiled evaluator, ask/tell."""

from __future__ import annotations

import io
import json
import math
import multiprocessing
import pickle
import random
from collections import defaultdict

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from amaze.agents.engine import BatchEngine
from amaze.evaluation.policy import run_episodes
from evolution import EvolutionConfigError
from evolution.neat import (
    Genome,
    GenomePopulation,
    InnovationTracker,
    NeatAlgorithm,
    NeatConfig,
    Species,
    allot_offspring,
    compatibility_distance,
    crossover,
    genome_to_arrays,
    mutate,
    mutate_add_connection,
    mutate_add_node,
    new_genome,
    policy_from_arrays,
    remove_stagnant,
    shared_fitness,
    speciate,
)
from evolution.neat_compile import robot_io


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


def grown_genomes(robot: str, count: int, steps: int, seed: int) -> list[Genome]:
    """Genomes after many mutations (structural ones included), from a shared tracker."""
    random.seed(seed)
    tracker = InnovationTracker(*robot_io(robot))
    genomes = []
    for _ in range(count):
        genome = new_genome(robot, tracker, GROWING)
        for _ in range(steps):
            mutate(genome, GROWING, tracker)
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
_TASK_INPUTS = np.random.default_rng(0).random((64, 8)).astype(np.float32)
_TASK_TARGET = np.argmax(_TASK_INPUTS[:, :4] - _TASK_INPUTS[:, 4:], axis=1)


def toy_fitness(algorithm: NeatAlgorithm, genomes: list[Genome]) -> np.ndarray:
    policy = algorithm.population_policy(genomes)
    actions = policy(np.tile(_TASK_INPUTS, (len(genomes), 1))).reshape(len(genomes), -1)
    return (actions == _TASK_TARGET).mean(axis=1)


def evolve(algorithm: NeatAlgorithm, generations: int) -> None:
    for _ in range(generations):
        genomes = algorithm.ask()
        algorithm.tell(genomes, toy_fitness(algorithm, genomes))


# -----------------------------------------------------------------------------
# Compiled evaluator


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


# -----------------------------------------------------------------------------
# Operators


def test_add_node_splits_a_connection():
    random.seed(5)
    config = NeatConfig(activation="identity")
    tracker = InnovationTracker(8, 4)
    genome = new_genome("DD", tracker, config)
    other = genome.copy()
    before = GenomePopulation.from_genomes([genome], "DD").outputs(_TASK_INPUTS)
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
    after = GenomePopulation.from_genomes([genome], "DD").outputs(_TASK_INPUTS)
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


# -----------------------------------------------------------------------------
# Species


def _cluster(center: Genome, size: int, spread: float) -> list[Genome]:
    genomes = []
    for _ in range(size):
        genome = center.copy()
        for gene in genome.connections.values():
            gene.weight += random.gauss(0.0, spread)
        genomes.append(genome)
    return genomes


def test_speciation_separates_distant_genomes():
    random.seed(8)
    config = NeatConfig()
    tracker = InnovationTracker(8, 4)
    a, b = new_genome("DD", tracker, config), new_genome("DD", tracker, config)
    for gene in b.connections.values():
        gene.weight += 3.0
    genomes = _cluster(a, 6, 0.05) + _cluster(b, 4, 0.05)
    species, next_id = speciate(genomes, [], 0.5, config, generation=0, next_id=0)
    assert next_id == 2
    assert [len(s.members) for s in species] == [6, 4]
    assert species[0].members == genomes[:6]
    # species persist into the next generation (an empty one dies), a new cluster founds one
    c = a.copy()
    for gene in c.connections.values():
        gene.weight -= 3.0
    later, next_id = speciate(_cluster(c, 2, 0.05) + genomes[:3], species, 0.5, config, 1, 2)
    assert [(s.id, len(s.members)) for s in later] == [(0, 3), (2, 2)]
    assert later[1].created == 1


def test_fitness_sharing_and_offspring_allotment():
    random.seed(9)
    tracker = InnovationTracker(8, 4)
    genomes = [new_genome("DD", tracker, NeatConfig()) for _ in range(11)]
    for genome, value in zip(genomes, [2.0] * 8 + [2.0, 0.0, 4.0], strict=True):
        genome.fitness.values = (value,)
    big = Species(0, genomes[0], 0, genomes[:8])
    small = Species(1, genomes[8], 0, genomes[8:9])
    other = Species(2, genomes[9], 0, genomes[9:])
    # adjusted fitness: (fitness - worst) / species size, summed per species
    assert shared_fitness([big, small, other]) == pytest.approx([2.0, 2.0, 2.0])
    assert allot_offspring([2.0, 2.0, 2.0], 30, minimum=2) == [10, 10, 10]
    assert allot_offspring([3.0, 1.0], 100, minimum=2) == [74, 26]
    assert allot_offspring([1.0, 1.0, 1.0], 10, minimum=1) == [4, 3, 3]
    assert allot_offspring([0.0, 0.0], 9, minimum=2) == [5, 4]
    assert allot_offspring([0.0, 5.0, 1.0], 4, minimum=2) == [0, 2, 2]


def test_stagnant_species_are_removed_but_the_best():
    random.seed(10)
    tracker = InnovationTracker(8, 4)
    genomes = [new_genome("DD", tracker, NeatConfig()) for _ in range(3)]
    for genome, value in zip(genomes, [1.0, 5.0, 2.0], strict=True):
        genome.fitness.values = (value,)
    species = [
        Species(i, g, 0, [g], best_fitness=g.fitness.values[0], last_improved=last)
        for i, (g, last) in enumerate(zip(genomes, [2, 0, 10], strict=True))
    ]
    kept = remove_stagnant(species, generation=17, stagnation=15)
    assert [s.id for s in kept] == [1, 2]  # species 0 stagnated; 1 stagnated but is the best
    assert [s.id for s in remove_stagnant(species, 40, 15)] == [1]


def test_constant_fitness_leaves_at_most_one_stagnant_species():
    config = NeatConfig(population_size=30, stagnation=3, compatibility_threshold=0.3)
    algorithm = NeatAlgorithm(config, "DD", seed=2)
    counts = []
    for _ in range(8):
        genomes = algorithm.ask()
        algorithm.tell(genomes, np.ones(len(genomes)))
        generation = algorithm.generation - 1
        stale = [s for s in algorithm.species if generation - s.last_improved >= 3]
        assert len(stale) <= 1
        counts.append(algorithm.stats()["n_species"])
    assert max(counts) > 1


# -----------------------------------------------------------------------------
# The algorithm


def test_ask_tell_interface():
    algorithm = NeatAlgorithm(NeatConfig(population_size=20), "DD", seed=0)
    assert algorithm.generation == 0 and algorithm.champion is None and algorithm.stats() == {}
    with pytest.raises(RuntimeError, match="champion"):
        algorithm.champion_arrays()
    genomes = algorithm.ask()
    assert len(genomes) == 20 and all(len(g.connections) == 32 for g in genomes)
    with pytest.raises(ValueError, match="fitness values"):
        algorithm.tell(genomes, np.ones(19))
    with pytest.raises(ValueError, match="finite"):
        algorithm.tell(genomes, np.full(20, np.nan))
    with pytest.raises(ValueError, match="ask"):
        algorithm.tell(genomes[::-1], np.ones(20))
    fitness = np.arange(20.0)
    algorithm.tell(genomes, fitness)
    assert algorithm.generation == 1
    champion, value = algorithm.champion
    assert value == 19.0 and fingerprint([champion]) == fingerprint([genomes[19]])
    stats = algorithm.stats()
    assert stats["best"] == 19.0 and stats["mean"] == 9.5 and stats["n_species"] >= 1
    arrays, architecture = algorithm.champion_arrays()
    assert architecture["n_inputs"] == 8 and set(arrays) >= {"weights", "sources"}
    assert len(algorithm.ask()) == 20


def test_image_robots_start_sparse():
    algorithm = NeatAlgorithm(NeatConfig(population_size=10), "H15", seed=0)
    for genome in algorithm.ask():
        assert genome.n_inputs == 225 and genome.n_outputs == 4
        assert 15 <= len(genome.connections) <= 90
        assert {c.out_node for c in genome.connections.values()} == set(range(225, 229))
    continuous = NeatAlgorithm(NeatConfig(population_size=10), "CC11", seed=0).ask()[0]
    assert continuous.n_outputs == 2 and continuous.nodes[121].activation == "tanh"


def test_evolution_is_deterministic_and_isolated_from_global_random():
    runs = []
    for seed in (4, 4, 5):
        random.seed(123)
        algorithm = NeatAlgorithm(NeatConfig(population_size=30), "DD", seed=seed)
        state = random.getstate()
        evolve(algorithm, 4)
        assert random.getstate() == state
        runs.append((fingerprint(algorithm.ask()), list(algorithm.logbook)))
    assert runs[0] == runs[1]
    assert runs[0][0] != runs[2][0]


def test_checkpoint_resumes_bit_identically():
    config = NeatConfig(population_size=30, add_node_rate=0.2, add_connection_rate=0.3)
    straight = NeatAlgorithm(config, "DD", seed=6)
    evolve(straight, 5)
    resumed = NeatAlgorithm(config, "DD", seed=6)
    evolve(resumed, 2)
    blob = pickle.dumps(resumed)
    random.seed(0)
    random.random()
    resumed = pickle.loads(blob)
    evolve(resumed, 3)
    assert resumed.generation == straight.generation == 5
    assert fingerprint(resumed.ask()) == fingerprint(straight.ask())
    assert list(resumed.logbook) == list(straight.logbook)
    assert fingerprint([resumed.champion[0]]) == fingerprint([straight.champion[0]])
    assert resumed.threshold == straight.threshold
    assert [s.id for s in resumed.species] == [s.id for s in straight.species]
    assert resumed.tracker.n_innovations == straight.tracker.n_innovations


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


def test_tiny_evolution_improves_fitness():
    algorithm = NeatAlgorithm(NeatConfig(population_size=50), "DD", seed=0)
    evolve(algorithm, 20)
    first, last = algorithm.logbook[0], algorithm.logbook[-1]
    assert last["champion"] >= first["best"] + 0.1
    assert last["mean"] > first["mean"] + 0.1


def test_population_plays_mazes_on_the_batch_engine():
    for robot in ("DD", "H5", "CC5"):
        algorithm = NeatAlgorithm(NeatConfig(population_size=3), robot, seed=0)
        policy = algorithm.population_policy(algorithm.ask())
        engine = BatchEngine(["M0_5x5_U", "M1_5x5_U"], robot, n_agents=6)
        results = run_episodes(engine, policy)
        assert len(results) == 6 and np.all(results.steps > 0)


# -----------------------------------------------------------------------------
# Configuration


def test_config_round_trip_and_validation():
    config = NeatConfig(population_size=40, activation="relu")
    assert NeatConfig.from_dict(json.loads(json.dumps(config.to_dict()))) == config
    assert NeatConfig.from_dict({}) == NeatConfig()
    with pytest.raises(EvolutionConfigError, match="'speciess'"):
        NeatConfig.from_dict({"speciess": 3})
    for key, value in [
        ("population_size", 1),
        ("population_size", "10"),
        ("crossover_rate", 1.5),
        ("activation", "softmax"),
        ("compatibility_threshold", 0.0),
        ("weight_mutate_power", float("nan")),
        ("stagnation", True),
    ]:
        with pytest.raises(EvolutionConfigError, match=f"'{key}'"):
            NeatConfig.from_dict({key: value})
