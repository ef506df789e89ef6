"""Oracle imitation: the torch network computes the spec's network; DAgger teaches a driver."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from evolution.config import EvolutionConfigError
from evolution.imitation import ImitationConfig, imitate, network_inputs, torch_network
from evolution.networks import NetworkSpec
from evolution.population import PopulationEvaluator

torch = pytest.importorskip("torch")

SPECS = [
    NetworkSpec(robot="CC7", hidden=(8,), pool=7, symmetry="rotations"),
    NetworkSpec(robot="CC9", hidden=(6, 5), pool=3, pooling="max", activation="relu"),
    NetworkSpec(robot="CC7", hidden=(), pool=5, symmetry="rotations", activation="sigmoid"),
    NetworkSpec(robot="H7", hidden=(8,), pool=5, symmetry="rotations"),
    NetworkSpec(robot="DD", hidden=(8,), symmetry="rotations"),
    NetworkSpec(robot="DD", hidden=(4,)),
    # convolutional: filters in their four turns, and unturned; strides 1 and 2
    NetworkSpec(robot="CC9", hidden=(6,), filters=3, stride=2, symmetry="rotations"),
    NetworkSpec(robot="CC7", hidden=(5,), filters=2, stride=1, activation="relu"),
    NetworkSpec(robot="H7", hidden=(), filters=2, stride=2, symmetry="rotations"),
]


def _observations(spec: NetworkSpec, n: int = 96) -> np.ndarray:
    """Observations of robots driven at random for a few steps in a 6x6 maze with signs."""
    engine = BatchEngine(["M3_6x6_C1_l.25_L.25_t.5_T.5"], spec.robot, n)
    rng = np.random.default_rng(0)
    observations = [engine.reset()]
    for _ in range(12):
        if spec.robot_info.discrete_outputs:
            actions = rng.integers(0, 4, n)
        else:
            actions = rng.uniform(-1, 1, (n, 2))
        observations.append(engine.step(actions).observations)
    return np.concatenate(observations)


@pytest.mark.parametrize(
    "spec", SPECS, ids=lambda s: f"{s.robot}-{s.symmetry}-{s.pool}-f{s.filters}"
)
def test_the_torch_network_acts_as_the_spec_network(spec: NetworkSpec) -> None:
    params = spec.initial_params(np.random.default_rng(1)) * 2.0
    params[-1] += 0.3  # a non-zero bias: the layout of biases is checked too
    network = torch_network(spec)
    network.load_params(params)
    np.testing.assert_allclose(network.flat_params(), params, atol=1e-6)  # float32 round trip
    observations = _observations(spec)
    with torch.no_grad():
        ours = network(torch.as_tensor(network_inputs(spec, observations))).numpy()
    population = spec.population(params[None, :])
    if spec.robot_info.discrete_outputs:
        scores = population.forward(observations)
        np.testing.assert_allclose(ours, scores, atol=2e-5)
    else:
        np.testing.assert_allclose(ours, population(observations), atol=2e-5)


def test_bad_counts_are_refused() -> None:
    with pytest.raises(EvolutionConfigError, match="max_samples"):
        ImitationConfig(max_samples=10**9)
    with pytest.raises(EvolutionConfigError, match="learning_rate"):
        ImitationConfig(learning_rate=0.0)
    for decay in (0.0, 1.5, float("nan"), "0.5"):
        with pytest.raises(EvolutionConfigError, match="learning_rate_decay"):
            ImitationConfig(learning_rate_decay=decay)


def test_the_learning_rate_decays_by_iteration() -> None:
    """Iteration i's Adam steps take learning_rate * decay ** i, and it changes the network."""
    spec = NetworkSpec(robot="DD", hidden=(), symmetry="rotations")
    mazes = ["M1_6x6_U", "M2_7x5_U"]
    config = ImitationConfig(iterations=3, agents=16, steps=30, updates=50, batch=64, seed=1)
    constant = imitate(spec, mazes, config)
    decayed = imitate(spec, mazes, dataclasses.replace(config, learning_rate_decay=0.5))
    assert [r["learning_rate"] for r in constant.history] == [3e-3] * 3
    assert [r["learning_rate"] for r in decayed.history] == [3e-3, 1.5e-3, 0.75e-3]
    assert not np.array_equal(constant.params, decayed.params)


def test_dagger_teaches_a_discrete_robot_to_follow_unseen_corridors() -> None:
    """A linear network shared by the four directions can follow a corridor (go to the open
    side the robot did not come from); taught on two unicursive mazes, it solves others."""
    spec = NetworkSpec(robot="DD", hidden=(), symmetry="rotations")
    config = ImitationConfig(iterations=3, agents=32, steps=60, updates=300, batch=256, seed=3)
    records = []
    result = imitate(
        spec, ["M1_6x6_U", "M2_7x5_U"], config,
        on_iteration=lambda record, params: records.append(record),
    )  # fmt: skip
    assert [r["iteration"] for r in records] == [0.0, 1.0, 2.0]
    assert [r["beta"] for r in records] == [1.0, 0.5, 0.25]
    assert result.history == records
    unseen = ["M11_8x8_U", "M12_5x9_U", "M13_10x10_U"]
    evaluator = PopulationEvaluator(unseen, "DD", rotations=True)
    assert evaluator.evaluate(spec.population(result.params[None, :])).success_rate[0] == 1.0
    untaught = spec.initial_params(np.random.default_rng(3))
    assert evaluator.evaluate(spec.population(untaught[None, :])).success_rate[0] < 1.0
    again = imitate(spec, ["M1_6x6_U", "M2_7x5_U"], config)
    np.testing.assert_array_equal(again.params, result.params)  # same seed, same network


def test_another_teacher_is_bound_to_the_engine_and_imitated() -> None:
    """``teacher`` replaces the oracle: bound to the engine, its actions are the labels."""

    class North:
        def __init__(self) -> None:
            self.engines: list[BatchEngine] = []

        def bind(self, engine: BatchEngine) -> None:
            self.engines.append(engine)

        def __call__(self, observations: np.ndarray) -> np.ndarray:
            return np.full(len(observations), 1, dtype=np.int64)

    spec = NetworkSpec(robot="DD", hidden=(4,))
    config = ImitationConfig(iterations=2, agents=16, steps=20, updates=200, batch=64, seed=2)
    teacher = North()
    result = imitate(spec, ["M1_6x6_U", "M2_7x5_U"], config, teacher=teacher)
    assert len(teacher.engines) == 1 and teacher.engines[0].n_agents == 16
    observations = _observations(spec)
    actions = spec.population(result.params[None, :])(observations)
    assert (actions == 1).all()  # north everywhere, as taught; the oracle goes its own way
    with pytest.raises(EvolutionConfigError, match="bind"):
        imitate(spec, ["M1_6x6_U"], config, teacher=lambda observations: observations)
    oracle_taught = imitate(spec, ["M1_6x6_U", "M2_7x5_U"], config)
    assert (spec.population(oracle_taught.params[None, :])(observations) != 1).any()


def test_keep_best_hands_over_the_best_network_on_the_validation_mazes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Each iteration is scored on the validation mazes; "best" keeps the highest success,
    then path progress (the first of equals), "last" the last iteration's network."""
    scripted = iter([(0.25, 0.4), (0.5, 0.6), (0.5, 0.7), (0.5, 0.7), (0.125, 0.9)] * 2)

    class Scripted:
        def __init__(self, mazes: list[str], robot: str, *, fitness: str) -> None:
            assert mazes == ["M11_8x8_U"] and fitness == "path_progress"

        def evaluate(self, population: object) -> SimpleNamespace:
            success, progress = next(scripted)
            return SimpleNamespace(success_rate=np.array([success]), fitness=np.array([progress]))

    monkeypatch.setattr("evolution.imitation.PopulationEvaluator", Scripted)
    spec = NetworkSpec(robot="DD", hidden=(), symmetry="rotations")
    config = ImitationConfig(iterations=5, agents=16, steps=20, updates=20, batch=64, keep="best")
    seen: list[np.ndarray] = []
    best = imitate(
        spec, ["M1_6x6_U"], config, validation=["M11_8x8_U"],
        on_iteration=lambda record, params: seen.append(params),
    )  # fmt: skip
    assert best.kept_iteration == 2
    np.testing.assert_array_equal(best.params, seen[2])
    assert [r["validation_success"] for r in best.history] == [0.25, 0.5, 0.5, 0.5, 0.125]
    assert [r["validation_progress"] for r in best.history] == [0.4, 0.6, 0.7, 0.7, 0.9]
    last = imitate(
        spec, ["M1_6x6_U"], dataclasses.replace(config, keep="last"), validation=["M11_8x8_U"]
    )
    assert last.kept_iteration == 4
    np.testing.assert_array_equal(last.params, seen[4])  # same seed: the same iterations
    assert not np.array_equal(best.params, last.params)


def test_keep_best_needs_validation_mazes_and_keep_is_checked() -> None:
    spec = NetworkSpec(robot="DD", hidden=(), symmetry="rotations")
    with pytest.raises(EvolutionConfigError, match="validation mazes"):
        imitate(spec, ["M1_6x6_U"], ImitationConfig(iterations=1, keep="best"))
    with pytest.raises(EvolutionConfigError, match="keep 'first'"):
        ImitationConfig(keep="first")


def test_keep_average_hands_over_the_mean_of_the_late_iterations() -> None:
    """``keep="average"`` hands over the mean of the parameters of iterations ``average_from`` on
    (by default the second half), and scores the running mean on the validation mazes."""
    spec = NetworkSpec(robot="DD", hidden=(), symmetry="rotations")
    config = ImitationConfig(iterations=4, agents=16, steps=20, updates=30, batch=64, seed=5)
    seen: list[np.ndarray] = []
    average = imitate(
        spec, ["M1_6x6_U"], dataclasses.replace(config, keep="average", average_from=1),
        validation=["M11_8x8_U"], on_iteration=lambda record, params: seen.append(params),
    )  # fmt: skip
    assert (average.kept_iteration, average.averaged_from) == (3, 1)
    np.testing.assert_allclose(average.params, np.mean(seen[1:], axis=0), rtol=1e-12)
    assert not np.allclose(average.params, seen[-1])
    assert ["average_validation_success" in r for r in average.history] == [False, *[True] * 3]
    evaluator = PopulationEvaluator(["M11_8x8_U"], "DD", fitness="path_progress")
    scores = evaluator.evaluate(spec.population(average.params[None, :]))
    assert average.history[-1]["average_validation_progress"] == scores.fitness[0]
    halves = imitate(spec, ["M1_6x6_U"], dataclasses.replace(config, keep="average"))
    assert halves.averaged_from == 2  # iterations // 2 by default
    np.testing.assert_allclose(halves.params, np.mean(seen[2:], axis=0), rtol=1e-12)
    last = imitate(spec, ["M1_6x6_U"], config)
    assert last.averaged_from == -1
    np.testing.assert_array_equal(last.params, seen[-1])  # same seed: the same iterations


def test_average_from_is_checked() -> None:
    with pytest.raises(EvolutionConfigError, match='average_from 2 chooses what keep "average"'):
        ImitationConfig(iterations=4, keep="best", average_from=2)
    for first in (4, -1, 1.5):
        with pytest.raises(EvolutionConfigError, match="average_from"):
            ImitationConfig(iterations=4, keep="average", average_from=first)
    assert ImitationConfig(iterations=5, keep="average").first_averaged == 2
