"""The NEAT-like algorithm: ask / tell, determinism, checkpoints, progress on tasks."""

from __future__ import annotations

import hashlib
import random
from pathlib import Path

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.evaluation.policy import run_episodes
from amaze.runs.checkpoint import read_checkpoint, write_checkpoint
from evolution.checkpoint import evolution_codec
from evolution.neat import NeatAlgorithm, NeatConfig
from tests.evolution.neat.conftest import evolve, fingerprint


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


def test_checkpoint_resumes_bit_identically(tmp_path: Path):
    config = NeatConfig(population_size=30, add_node_rate=0.2, add_connection_rate=0.3)
    straight = NeatAlgorithm(config, "DD", seed=6)
    evolve(straight, 5)
    resumed = NeatAlgorithm(config, "DD", seed=6)
    evolve(resumed, 2)
    path = write_checkpoint(tmp_path / "state.npz", resumed, evolution_codec())
    random.seed(0)
    random.random()
    resumed = read_checkpoint(path, evolution_codec(), ValueError, NeatAlgorithm)
    evolve(resumed, 3)
    assert resumed.generation == straight.generation == 5
    assert fingerprint(resumed.ask()) == fingerprint(straight.ask())
    assert list(resumed.logbook) == list(straight.logbook)
    assert fingerprint([resumed.champion[0]]) == fingerprint([straight.champion[0]])
    assert resumed.threshold == straight.threshold
    assert [s.id for s in resumed.species] == [s.id for s in straight.species]
    assert resumed.tracker.n_innovations == straight.tracker.n_innovations


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


def test_neat_never_stops_by_itself():
    config = NeatConfig(population_size=10, stagnation=1)
    algorithm = NeatAlgorithm(config, "DD", seed=0)
    assert algorithm.stopped is False
    for _ in range(4):
        genomes = algorithm.ask()
        algorithm.tell(genomes, np.zeros(len(genomes)))  # flat fitness: every species stagnates
        assert algorithm.stopped is False and len(algorithm.ask()) == 10


#: Digest of :func:`test_a_seeded_run_reproduces_its_recorded_genomes`'s run, recorded
#: with the genome-by-genome operators, speciation and compilation that the
#: compiled ones replaced: a change of any draw, distance or compiled network shows here.
RECORDED_RUN = "fa53e4d76de24e0dfbdfb0fc06e2df93e69b59f1a056bc4b8ebc00d041604b48"


def test_a_seeded_run_reproduces_its_recorded_genomes():
    config = NeatConfig(
        population_size=40,
        add_node_rate=0.3,
        add_connection_rate=0.5,
        toggle_enable_rate=0.1,
        activation_mutate_rate=0.2,
        target_species=4,
    )
    algorithm = NeatAlgorithm(config, "DD", seed=7)
    evolve(algorithm, 25)
    record = [(r["n_species"], r["threshold"], r["best"], r["mean"]) for r in algorithm.logbook]
    species = [(s.id, s.created) for s in algorithm.species]
    text = repr((fingerprint(algorithm.ask()), record, species))
    assert hashlib.sha256(text.encode()).hexdigest() == RECORDED_RUN
