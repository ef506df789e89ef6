"""CMA-ES over fixed networks: configuration, determinism, checkpoints, restarts, learning."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from amaze.runs.checkpoint import read_checkpoint, write_checkpoint
from evolution import EvolutionConfigError
from evolution.agent_file import load_agent, save_agent
from evolution.checkpoint import evolution_codec
from evolution.cmaes import CMAESAlgorithm, CMAESConfig, default_popsize
from evolution.networks import NetworkPopulation, NetworkSpec
from evolution.population import PopulationEvaluator

SMALL_MAZES = ["M0_5x5_U", "M1_5x5_C1", "M2_6x6_C1"]


def sphere_fitness(candidates: list[np.ndarray]) -> np.ndarray:
    """A smooth fitness (maximised at all parameters 0.3), for the mechanics tests."""
    return np.array([-float(np.sum((c - 0.3) ** 2)) for c in candidates])


def run(algorithm: CMAESAlgorithm, generations: int, fitness=sphere_fitness) -> list:
    """Ask / tell ``generations`` times; the candidates, stats and champions seen."""
    trace = []
    for _ in range(generations):
        candidates = algorithm.ask()
        algorithm.tell(candidates, fitness(candidates))
        champion = algorithm.champion
        trace.append((np.stack(candidates), algorithm.stats(), champion[0], champion[1]))
    return trace


def assert_same_trace(first: list, second: list) -> None:
    assert len(first) == len(second)
    for (c1, s1, p1, f1), (c2, s2, p2, f2) in zip(first, second, strict=True):
        assert c1.shape == c2.shape
        assert np.array_equal(c1, c2)
        assert s1 == s2
        assert np.array_equal(p1, p2)
        assert f1 == f2


# -- configuration -----------------------------------------------------------------


def test_config_defaults_round_trip_through_json() -> None:
    config = CMAESConfig()
    assert config.network == {
        "hidden": [],
        "activation": "tanh",
        "pool": None,
        "symmetry": "none",
        "filters": 0,
        "stride": None,
        "pooling": "mean",
    }
    data = json.loads(json.dumps(config.to_dict()))
    assert CMAESConfig.from_dict(data) == config
    custom = CMAESConfig.from_dict(
        {
            "network": {"type": "mlp", "hidden": [8, 4], "activation": "relu"},
            "population_size": 12,
            "sigma0": 0.25,
            "separable": True,
            "restarts": 2,
            "cma_options": {"tolfun": 1e-9},
        }
    )
    assert custom.network == {
        "hidden": [8, 4],
        "activation": "relu",
        "pool": None,
        "symmetry": "none",
        "filters": 0,
        "stride": None,
        "pooling": "mean",
    }
    again = CMAESConfig.from_dict(json.loads(json.dumps(custom.to_dict())))
    assert again == custom
    assert again.to_dict() == custom.to_dict()
    assert CMAESConfig.from_dict({"sigma0": 2}).sigma0 == 2.0


@pytest.mark.parametrize(
    ("data", "named"),
    [
        ({"popsize": 10}, "popsize"),
        ({"population_size": 1}, "population_size"),
        ({"population_size": 2.5}, "population_size"),
        ({"population_size": True}, "population_size"),
        ({"sigma0": 0}, "sigma0"),
        ({"sigma0": float("nan")}, "sigma0"),
        ({"sigma0": "big"}, "sigma0"),
        ({"separable": "yes"}, "separable"),
        ({"restarts": -1}, "restarts"),
        ({"restarts": 1.0}, "restarts"),
        ({"network": {"hidden": [0]}}, "hidden"),
        ({"network": {"activation": "softmax"}}, "softmax"),
        ({"network": {"robot": "DD"}}, "robot"),
        ({"network": {"type": "neat"}}, "neat"),
        ({"network": {"pool": 0}}, "pool"),
        ({"network": {"symmetry": "mirror"}}, "mirror"),
        ({"network": [8]}, "network"),
        ({"cma_options": {"no_such_option": 1}}, "no_such_option"),
        ({"cma_options": {"popsize": 10}}, "popsize"),
        ({"cma_options": {"seed": 3}}, "seed"),
        ({"cma_options": {"tolfun": float("inf")}}, "tolfun"),
    ],
)
def test_config_rejects_bad_values_naming_them(data: dict, named: str) -> None:
    with pytest.raises(EvolutionConfigError, match=named):
        CMAESConfig.from_dict(data)


def test_config_validate_catches_later_edits() -> None:
    config = CMAESConfig()
    config.sigma0 = -1.0
    with pytest.raises(EvolutionConfigError, match="sigma0"):
        config.validate()
    with pytest.raises(EvolutionConfigError, match="sigma0"):
        CMAESAlgorithm(config, "DD", 0)


def test_algorithm_builds_the_network_for_the_run_robot() -> None:
    algorithm = CMAESAlgorithm({"network": {"hidden": [5]}}, "DD", 0)
    assert algorithm.spec == NetworkSpec("DD", (5,), "tanh")
    image = CMAESAlgorithm({"network": {"pool": 3}}, "CD15", 0)
    assert image.spec.pool == 3
    assert image.spec.n_params == 9 * 4 + 4
    with pytest.raises(EvolutionConfigError, match="pool"):
        CMAESAlgorithm({"network": {"pool": 3}}, "DD", 0)
    shared = CMAESAlgorithm({"network": {"hidden": [5], "symmetry": "rotations"}}, "H11", 0)
    assert shared.spec == NetworkSpec("CD11", (5,), symmetry="rotations")
    assert shared.spec.n_params == 25 * 5 + 5 + 5 + 1
    turned = CMAESAlgorithm({"network": {"hidden": [5], "symmetry": "rotations"}}, "CC15", 0)
    assert turned.spec.n_params == shared.spec.n_params  # one score per direction, as for H
    with pytest.raises(EvolutionConfigError, match="seed"):
        CMAESAlgorithm({}, "DD", "zero")


def test_population_size_default_and_given() -> None:
    algorithm = CMAESAlgorithm({}, "DD", 0)
    assert algorithm.spec.n_params == 36
    assert default_popsize(36) == 14
    assert algorithm.popsize == 14
    assert len(algorithm.ask()) == 14
    given = CMAESAlgorithm({"population_size": 10}, "DD", 0)
    candidates = given.ask()
    assert len(candidates) == 10 and given.es.popsize == 10
    assert all(c.shape == (36,) and c.dtype == np.float64 for c in candidates)
    assert "popsize 10" in given.describe() and "36 params" in given.describe()


def test_separable_sets_diagonal_covariance() -> None:
    full = CMAESAlgorithm({"separable": False}, "DD", 0)
    separable = CMAESAlgorithm({"separable": True}, "DD", 0)
    assert full.es.opts["CMA_diagonal"] is False
    assert separable.es.opts["CMA_diagonal"] is True
    assert separable.es.sm.__class__.__name__ != full.es.sm.__class__.__name__
    trace = run(separable, 5)
    # The covariance stays diagonal: the sampler keeps one variance per parameter.
    variances = np.asarray(separable.es.sm.variances)
    assert variances.shape == (36,)
    assert trace[-1][1]["popsize"] == 14
    assert "sep-CMA-ES" in separable.describe()


# -- ask / tell ----------------------------------------------------------------------


def test_population_policy_plays_the_candidates() -> None:
    algorithm = CMAESAlgorithm({"network": {"hidden": [3]}}, "DD", 0)
    candidates = algorithm.ask()
    policy = algorithm.population_policy(candidates)
    assert isinstance(policy, NetworkPopulation)
    assert len(policy) == len(candidates)
    assert np.array_equal(policy.params, np.stack(candidates).astype(np.float32))


def test_tell_checks_its_arguments() -> None:
    algorithm = CMAESAlgorithm({}, "DD", 0)
    with pytest.raises(ValueError, match="last ask"):
        algorithm.tell([], np.zeros(0))
    candidates = algorithm.ask()
    assert np.array_equal(np.stack(algorithm.ask()), np.stack(candidates))  # asked twice: same
    with pytest.raises(ValueError, match="fitness values"):
        algorithm.tell(candidates, np.zeros(len(candidates) - 1))
    with pytest.raises(ValueError, match="finite"):
        algorithm.tell(candidates, np.full(len(candidates), np.nan))
    with pytest.raises(ValueError, match="same order"):
        algorithm.tell(candidates[::-1], np.zeros(len(candidates)))
    assert algorithm.generation == 0 and algorithm.champion is None and algorithm.stats() == {}
    with pytest.raises(RuntimeError, match="champion"):
        algorithm.champion_arrays()
    algorithm.tell(candidates, sphere_fitness(candidates))
    assert algorithm.generation == 1


def test_tell_maximises_fitness_and_keeps_the_best_ever() -> None:
    algorithm = CMAESAlgorithm({"sigma0": 0.3}, "DD", 4)
    first = run(algorithm, 1)[0]
    trace = run(algorithm, 60)
    assert trace[-1][1]["mean"] > first[1]["mean"] + 1.0  # climbed towards the optimum
    champion, fitness = algorithm.champion
    assert fitness == max(stats["best"] for _, stats, _, _ in [first, *trace])
    assert fitness == pytest.approx(float(sphere_fitness([champion])[0]))
    stats = algorithm.stats()
    assert set(stats) == {"best", "mean", "std", "min", "sigma", "popsize", "restarts", "champion"}
    assert stats["champion"] == fitness and stats["sigma"] == algorithm.es.sigma
    assert stats["best"] >= stats["mean"] >= stats["min"]
    assert algorithm.generation == 61


# -- determinism and checkpoints ----------------------------------------------------


def test_same_seed_same_run_and_caller_rng_untouched() -> None:
    np.random.seed(123)  # noqa: NPY002
    before = np.random.get_state()  # noqa: NPY002
    first = run(CMAESAlgorithm({}, "DD", 7), 5)
    after = np.random.get_state()  # noqa: NPY002
    assert after[0] == before[0] and np.array_equal(after[1], before[1])
    assert after[2:] == before[2:]
    # Whatever the caller does with np.random in between, the run is the same.
    algorithm = CMAESAlgorithm({}, "DD", 7)
    second = []
    for _ in range(5):
        np.random.standard_normal(17)  # noqa: NPY002
        second.extend(run(algorithm, 1))
    assert_same_trace(first, second)
    other = run(CMAESAlgorithm({}, "DD", 8), 1)
    assert not np.array_equal(first[0][0], other[0][0])


@pytest.mark.parametrize("threads", [2, 4])
def test_the_candidates_do_not_depend_on_the_blas_threads(threads: int) -> None:
    # OpenBLAS sums a product in another order on more threads; a run of 433 parameters
    # (CC7's shared 16-unit network) diverged between a study's workers
    # (OMP_NUM_THREADS=1) and the same command run alone
    config = {"network": {"hidden": [16], "symmetry": "rotations"}}
    with threadpool_limits(limits=1, user_api="blas"):
        alone = run(CMAESAlgorithm(config, "CC7", 3), 8)
    with threadpool_limits(limits=threads, user_api="blas"):
        threaded = run(CMAESAlgorithm(config, "CC7", 3), 8)
    assert alone[0][0].shape[1] == 433
    assert_same_trace(alone, threaded)


def constant_fitness(candidates: list[np.ndarray]) -> np.ndarray:
    return np.zeros(len(candidates))


@pytest.mark.parametrize(
    ("config", "fitness"),
    [
        ({"network": {"hidden": [4]}}, sphere_fitness),
        ({"separable": True, "population_size": 6}, sphere_fitness),
        ({"restarts": 9}, constant_fitness),  # flat fitness: restarts within the window
    ],
)
def test_checkpoint_resume_is_bit_identical(config: dict, fitness, tmp_path: Path) -> None:
    straight = run(CMAESAlgorithm(config, "DD", 3), 6, fitness)
    algorithm = CMAESAlgorithm(config, "DD", 3)
    first = run(algorithm, 3, fitness)
    np.random.seed(99)  # noqa: NPY002
    path = write_checkpoint(tmp_path / "state.npz", algorithm, evolution_codec())
    restored = read_checkpoint(path, evolution_codec(), ValueError, CMAESAlgorithm)
    np.random.standard_normal(5)  # noqa: NPY002
    second = run(restored, 3, fitness)
    assert_same_trace(straight, first + second)
    assert restored.generation == 6
    if fitness is constant_fitness:
        assert restored.restarts >= 1


def test_restarts_double_the_population_then_stop() -> None:
    algorithm = CMAESAlgorithm({"restarts": 2, "population_size": 6}, "DD", 0)
    sizes = []
    while not algorithm.stopped:
        assert algorithm.generation < 100, "cma never stopped on a flat fitness"
        candidates = algorithm.ask()
        sizes.append(len(candidates))
        algorithm.tell(candidates, constant_fitness(candidates))
    assert algorithm.restarts == 2
    assert sorted(set(sizes)) == [6, 12, 24]
    assert sizes == sorted(sizes) and algorithm.generation == len(sizes)
    assert algorithm.stats()["restarts"] == 2 and algorithm.stats()["popsize"] == 24
    assert set(algorithm.stop_reasons) & {"tolfun", "tolflatfitness"}
    with pytest.raises(RuntimeError, match="stopped"):
        algorithm.ask()


def test_restart_starts_from_a_new_mean_and_honours_cma_options() -> None:
    algorithm = CMAESAlgorithm({"restarts": 1, "cma_options": {"tolfun": 1e3}}, "DD", 0)
    mean = np.array(algorithm.es.mean)
    run(algorithm, 1, sphere_fitness)  # fitness range << tolfun: stops after one generation
    assert algorithm.restarts == 1 and not algorithm.stopped
    assert algorithm.popsize == 28
    assert not np.allclose(algorithm.es.mean, mean)
    assert "IPOP restarts 1/1" in algorithm.describe()
    run(algorithm, 1, sphere_fitness)
    assert algorithm.stopped and "tolfun" in algorithm.stop_reasons
    without = CMAESAlgorithm({"restarts": 0, "cma_options": {"tolfun": 1e3}}, "DD", 0)
    run(without, 1, sphere_fitness)
    assert without.stopped and without.restarts == 0


# -- on mazes ----------------------------------------------------------------------


def test_learns_to_solve_small_mazes_and_saves_the_champion(tmp_path) -> None:
    evaluator = PopulationEvaluator(SMALL_MAZES, "DD", rotations=True)
    algorithm = CMAESAlgorithm({}, "DD", 1)
    first_best = None
    while algorithm.generation < 200:
        candidates = algorithm.ask()
        result = evaluator.evaluate(algorithm.population_policy(candidates))
        algorithm.tell(candidates, result.fitness)
        first_best = result.fitness.max() if first_best is None else first_best
        if result.success_rate.max() >= 1.0:
            break
    champion, fitness = algorithm.champion
    assert fitness > first_best
    arrays, architecture = algorithm.champion_arrays()
    assert arrays["params"].dtype == np.float64 and np.array_equal(arrays["params"], champion)
    assert architecture == {"type": "mlp", **algorithm.spec.to_dict()}
    replay = evaluator.evaluate(algorithm.population_policy([champion]))
    assert replay.fitness[0] == fitness
    assert replay.success_rate[0] == 1.0

    path = save_agent(tmp_path / "champion", arrays, {"architecture": architecture, "robot": "DD"})
    loaded = load_agent(path)
    again = evaluator.evaluate(loaded)
    assert np.array_equal(again.episodes.steps, replay.episodes.steps)
    assert again.fitness[0] == fitness
    observations = np.random.default_rng(0).random((256, 8)).astype(np.float32)
    expected = algorithm.spec.population(champion[None])(observations)
    assert np.array_equal(loaded(observations), expected)
