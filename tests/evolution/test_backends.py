"""Evaluation backends: split populations, shared tables, and Ray actors with identical results."""

from __future__ import annotations

import json
import os
import pickle
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.agents.tables import compile_mazes
from amaze.errors import OptionError
from amaze.maze import as_mazes
from evolution import EvolutionConfigError
from evolution.agent_file import read_agent
from evolution.algorithms import make_algorithm
from evolution.backends import (
    LocalBackend,
    RayBackend,
    current_backend,
    make_backend,
    use_backend,
)
from evolution.cli import main
from evolution.learner import EvolutionLearner
from evolution.population import PopulationEvaluator, PopulationResult

MAZES = ["M0_5x5_U", "M1_6x6_C1", "M2_5x5_l.5_L.25"]
ROTATED = ["M0_5x5_U", "M0_5x5_U_R", "M1_6x6_C1", "M1_6x6_C1_R"]


def _population(algo: str, size: int, seed: int = 0):
    algorithm = make_algorithm(algo, {"population_size": size}, "DD", seed)
    return algorithm.population_policy(algorithm.ask())


def _assert_same(a: PopulationResult, b: PopulationResult) -> None:
    for name in ("fitness", "success_rate", "normalized_reward", "pretty_reward"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.env_steps == b.env_steps
    for name in ("steps", "normalized_reward", "pretty_reward", "success"):
        np.testing.assert_array_equal(a.per_episode(name), b.per_episode(name), err_msg=name)


# -- splitting, the principle every distributed backend rests on ----------------------


@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_parts_of_a_population_score_as_the_whole(algo: str) -> None:
    policy = _population(algo, 7)
    evaluator = PopulationEvaluator(MAZES, "DD", rotations=True)
    whole = evaluator.evaluate(policy)
    parts = [evaluator.evaluate(policy.subset(i)) for i in ([0, 1, 2], [3], [4, 5, 6])]
    _assert_same(whole, PopulationResult.concatenate(parts))
    assert len(set(whole.fitness.tolist())) > 1  # the individuals differ


def test_a_genome_population_splits_and_pickles() -> None:
    policy = _population("neat", 4, seed=3)
    again = pickle.loads(pickle.dumps(policy))
    observations = np.random.default_rng(0).random((8, 8)).astype(np.float32)
    np.testing.assert_array_equal(policy.outputs(observations), again.outputs(observations))
    part = policy.subset([2, 0])
    assert part.n_policies == 2 and len(part) == 2
    evaluator = PopulationEvaluator(MAZES, "DD")
    whole = evaluator.evaluate(policy)
    np.testing.assert_array_equal(evaluator.evaluate(part).fitness, whole.fitness[[2, 0]])
    for bad in ([], [4], [-1]):
        with pytest.raises(EvolutionConfigError, match="subset"):
            policy.subset(bad)


def test_engines_share_compiled_tables_and_refuse_foreign_ones() -> None:
    mazes = as_mazes(MAZES)
    tables = compile_mazes(mazes, "DD")
    shared = BatchEngine(mazes, "DD", 6, tables=tables)
    assert shared.tables is tables
    own = BatchEngine(mazes, "DD", 6)
    np.testing.assert_array_equal(shared.reset(), own.reset())
    actions = np.array([0, 1, 2, 3, 0, 1])
    a, b = shared.step(actions), own.step(actions)
    np.testing.assert_array_equal(a.rewards, b.rewards)
    np.testing.assert_array_equal(a.observations, b.observations)
    for robot, factor, count in (("CD5", 4.0, 3), ("DD", 2.0, 3), ("DD", 4.0, 2)):
        with pytest.raises(OptionError, match="tables"):
            BatchEngine(mazes[:count], robot, 4, deadline_factor=factor, tables=tables)


# -- choosing a backend -------------------------------------------------------------------


def test_the_local_backend_is_the_default_and_contexts_nest() -> None:
    assert isinstance(current_backend(), LocalBackend)
    outer, inner = LocalBackend(), LocalBackend()
    with use_backend(outer):
        assert current_backend() is outer
        with use_backend(inner):
            assert current_backend() is inner
        assert current_backend() is outer
    assert isinstance(current_backend(), LocalBackend) and current_backend() is not outer
    evaluator = make_backend("local").evaluator(MAZES, "DD", rotations=True)
    assert isinstance(evaluator, PopulationEvaluator) and evaluator.n_episodes == 12


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--actors", "2"], "--actors 2 needs --backend ray"),
        (["--backend", "ray", "--actors", "0"], "--actors 0"),
        (["--address", "auto"], "--address 'auto' needs --backend ray"),
        (["--backend", "dask"], "invalid choice: 'dask'"),
    ],
)
def test_bad_backend_options_are_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    assert main(["--max-generations", "1", "--out", str(tmp_path / "run"), *argv]) == 2
    error = capsys.readouterr().err
    assert error.startswith("error: ") and message in error and "Traceback" not in error
    assert not (tmp_path / "run").exists()


def test_ray_missing_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    assert main(["--backend", "ray", "--out", str(tmp_path / "run")]) == 2
    error = capsys.readouterr().err
    assert "needs Ray, which is not installed" in error and "pip install" in error


# -- Ray ------------------------------------------------------------------------------------


def ray_tests(test):
    """A Ray test: in the xdist worker of the session's cluster, and in the slow tier."""
    return pytest.mark.slow(pytest.mark.xdist_group("ray")(test))


@pytest.fixture
def ray_backend(ray_cluster):
    """Two actors on the session's cluster (all its CPUs: closed after each test)."""
    with RayBackend(actors=2) as backend:
        yield backend


@ray_tests
def test_actors_beyond_the_free_cpus_are_refused(
    ray_backend: RayBackend, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("evolution.backends.FREEING_SECONDS", 0.2)
    with pytest.raises(EvolutionConfigError, match="--actors 1: the Ray cluster has 0 free CPUs"):
        RayBackend(actors=1)


@ray_tests
@pytest.mark.parametrize(("algo", "size"), [("cmaes", 5), ("neat", 6), ("cmaes", 1)])
def test_ray_scores_are_the_local_scores(ray_backend: RayBackend, algo: str, size: int) -> None:
    policy = _population(algo, max(size, 2), seed=size)
    if size == 1:  # one individual is played by the driver
        policy = policy.subset([1])
    local = PopulationEvaluator(MAZES, "DD", rotations=True).evaluate(policy)
    evaluator = ray_backend.evaluator(MAZES, "DD", rotations=True)
    assert evaluator.n_episodes == 12
    _assert_same(evaluator.evaluate(policy), local)
    _assert_same(evaluator.evaluate(policy), local)  # again, from the actors' engines
    other = ray_backend.evaluator(ROTATED, "DD", fitness="success_rate")  # a new maze set
    _assert_same(
        other.evaluate(policy),
        PopulationEvaluator(ROTATED, "DD", fitness="success_rate").evaluate(policy),
    )


@ray_tests
def test_ray_refuses_a_population_of_another_robot(ray_backend: RayBackend) -> None:
    evaluator = ray_backend.evaluator(MAZES, "CD5")
    with pytest.raises(EvolutionConfigError, match="drives DD robots, the evaluator CD5"):
        evaluator.evaluate(_population("cmaes", 4))


def _evolve(out: Path, *extra: str, regime: dict | None = None) -> None:
    config = {
        "algo": "cmaes",
        "budget_steps": None,
        "max_generations": 5,
        "checkpoint_seconds": 0,
        "algorithm": {"population_size": 10},
        **(regime or {"mazes": MAZES[:2]}),
    }
    path = out.parent / f"{out.name}.json"
    path.write_text(json.dumps(config))
    assert main(["--config", str(path), "--out", str(out), "--no-progress", *extra]) == 0


def _progress(out: Path) -> list[list[str]]:
    lines = (out / "progress.csv").read_text().splitlines()
    header = lines[0].split(",")
    timed = {header.index(name) for name in ("seconds", "eval_seconds")}
    return [[v for i, v in enumerate(line.split(",")) if i not in timed] for line in lines]


@ray_tests
@pytest.mark.parametrize(
    "regime",
    [
        None,
        {
            "regime": "coevolution",
            "coevolution": {"capacity": 6, "batch": 3, "validation": 4, "validation_every": 2},
        },
    ],
    ids=["direct", "coevolution"],
)
def test_a_run_on_ray_reaches_the_local_champion(
    ray_cluster, tmp_path: Path, regime: dict | None
) -> None:
    address = ray_cluster.get_runtime_context().gcs_address
    _evolve(tmp_path / "local", regime=regime)
    _evolve(
        tmp_path / "ray", "--backend", "ray", "--address", address, "--actors", "2", regime=regime
    )
    local, ray_champion = (
        read_agent(tmp_path / "local" / "agent.npz"),
        read_agent(tmp_path / "ray" / "agent.npz"),
    )
    assert local[0].keys() == ray_champion[0].keys()
    for name in local[0]:
        np.testing.assert_array_equal(local[0][name], ray_champion[0][name])
    assert _progress(tmp_path / "local") == _progress(tmp_path / "ray")
    summaries = [json.loads((tmp_path / k / "summary.json").read_text()) for k in ("local", "ray")]
    for key in ("env_steps", "success_rate", "normalized_reward", "champion_fitness"):
        assert summaries[0][key] == summaries[1][key], key


@ray_tests
def test_a_learner_trains_on_ray_as_locally(ray_backend: RayBackend) -> None:
    def trained(backend) -> EvolutionLearner:
        learner = EvolutionLearner.new("neat", {"population_size": 8}, "DD", seed=4)
        with use_backend(backend):
            learner.train(ROTATED, budget_steps=6_000)
        return learner

    local, distributed = trained(LocalBackend()), trained(ray_backend)
    assert local.env_steps == distributed.env_steps and local.generations > 1
    assert local.champion.fitness == distributed.champion.fitness
    for name, array in local.champion.arrays.items():
        np.testing.assert_array_equal(array, distributed.champion.arrays[name])


@ray_tests
def test_a_killed_actor_is_restarted_and_the_generation_unchanged(ray_cluster) -> None:
    mazes = [f"M{seed}_12x12_C1_l.25_L.25" for seed in range(6)]
    policy = _population("cmaes", 256, seed=1)
    local = PopulationEvaluator(mazes, "DD", rotations=True).evaluate(policy)
    with RayBackend(actors=2) as backend:
        evaluator = backend.evaluator(mazes, "DD", rotations=True)
        _assert_same(evaluator.evaluate(policy), local)  # the actors hold the mazes now
        started = time.perf_counter()
        evaluator.evaluate(policy)
        generation = time.perf_counter() - started
        victim = backend.actor_pids()[0]
        # a third of the way into the generation (as long again after the kill, once restarted)
        killer = threading.Timer(generation / 3, os.kill, (victim, signal.SIGKILL))
        killer.start()
        result = evaluator.evaluate(policy)
        killer.join()
        _assert_same(result, local)
        assert backend.actor_pids()[0] != victim  # restarted, and it plays on
        _assert_same(evaluator.evaluate(policy), local)


@ray_tests
def test_a_run_whose_actor_is_killed_ends_as_the_local_run(ray_cluster, tmp_path: Path) -> None:
    from evolution.run import evolve

    config = {
        "algo": "cmaes",
        "mazes": ["M3_10x10_C1_l.25_L.25", "M4_9x9_U"],
        "budget_steps": None,
        "max_generations": 25,
        "checkpoint_seconds": 0,
        "algorithm": {"population_size": 64, "network": {"hidden": [8]}},
    }
    evolve(config, tmp_path / "local")
    with RayBackend(actors=2) as backend, use_backend(backend):
        victim = backend.actor_pids()[1]
        progress = tmp_path / "ray" / "progress.csv"

        def kill_midway() -> None:  # once a few generations are logged
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline:
                if progress.exists() and len(progress.read_text().splitlines()) > 5:
                    os.kill(victim, signal.SIGKILL)
                    return
                time.sleep(0.01)

        killer = threading.Thread(target=kill_midway)
        killer.start()
        evolve(config, tmp_path / "ray")
        killer.join()
        assert backend.actor_pids()[1] != victim  # it was killed mid-run, and restarted
    assert _progress(tmp_path / "local") == _progress(tmp_path / "ray")
    local = read_agent(tmp_path / "local" / "agent.npz")[0]
    distributed = read_agent(tmp_path / "ray" / "agent.npz")[0]
    for name in local:
        np.testing.assert_array_equal(local[name], distributed[name])
