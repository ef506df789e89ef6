"""Population evaluation: P individuals x M episodes on one engine, scored per individual."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.evaluation.controllers import OracleController
from amaze.evaluation.policy import run_episodes
from amaze.evaluation.protocol import Evaluator
from amaze.maze import Maze, MazeSpec, rotations
from evolution import EvolutionConfigError
from evolution.networks import NetworkSpec
from evolution.population import (
    PopulationEvaluator,
    PopulationPolicy,
    PopulationResult,
    SplittablePopulation,
)

MAZES = ["M4_6x6_C1", "M7_8x8_C1_l.25_L.25", "M2_9x9_C1_l.2_L.25_t.4_T.5", "M3_5x5_U"]
CLUE_MAZES = ["M4_10x10_C1", "M11_12x12_C1", "M5_8x8_C1"]


class ReferenceMLP:
    """One tanh MLP in plain numpy (float64), the way a reader would write it."""

    def __init__(self, spec: NetworkSpec, vector: np.ndarray) -> None:
        self.layers = [(w.astype(np.float64), b.astype(np.float64))
                       for w, b in spec.unflatten(vector.astype(np.float32))]  # fmt: skip

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        x = observations.astype(np.float64)
        for k, (weights, bias) in enumerate(self.layers):
            x = x @ weights + bias
            if k < len(self.layers) - 1:
                x = np.tanh(x)
        return x.argmax(axis=1)


class Constant:
    def __init__(self, action: int) -> None:
        self.action = action

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        return np.full(len(observations), self.action, dtype=np.int64)


class ClueFollower:
    """Score each side 2 x its sign's lightness minus its wall slot; take the first best."""

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        actions = []
        for row in observations.tolist():
            scores = [2 * row[4 + d] - row[d] for d in range(4)]
            actions.append(scores.index(max(scores)))
        return np.array(actions, dtype=np.int64)


def linear_dd(weights: np.ndarray, biases: np.ndarray) -> np.ndarray:
    """The parameter vector of a linear DD network (weights (8, 4) then biases (4,))."""
    return np.concatenate([np.asarray(weights, float).ravel(), np.asarray(biases, float)])


@pytest.fixture(scope="module")
def evaluator() -> PopulationEvaluator:
    return PopulationEvaluator(MAZES, "DD", rotations=True)


def clue_follower_weights() -> np.ndarray:
    """Linear DD weights: logit = 2 x sign lightness - wall slot (1 wall, 0.5 arrival, 0 open)."""
    weights = np.zeros((8, 4))
    weights[:4, :4] = -np.eye(4)
    weights[4:, :4] = 2 * np.eye(4)
    return weights


def random_mlps(rng: np.random.Generator) -> tuple[NetworkSpec, np.ndarray]:
    spec = NetworkSpec("DD", (8,))
    return spec, spec.initial_params(rng, 6) * 2.5


def noisy_clue_followers(rng: np.random.Generator) -> tuple[NetworkSpec, np.ndarray]:
    base = linear_dd(clue_follower_weights(), np.zeros(4))
    noise = rng.normal(0.0, 1.0, (6, base.size)) * np.linspace(0.0, 1.5, 6)[:, None]
    return NetworkSpec("DD"), base + noise


@pytest.mark.parametrize("build", [random_mlps, noisy_clue_followers])
def test_population_scores_equal_separate_evaluations(evaluator, build):
    spec, params = build(np.random.default_rng(11))
    population = spec.population(params)
    assert isinstance(population, PopulationPolicy)
    assert isinstance(population, SplittablePopulation)
    result = evaluator.evaluate(population)
    assert len(result) == 6 and result.n_episodes == 16
    reference = Evaluator("DD", rotations(MAZES), inputs=False)
    total_steps = 0
    for p in range(6):
        report = reference.evaluate(ReferenceMLP(spec, params[p]))
        assert result.normalized_reward[p] == pytest.approx(report.normalized_reward, abs=1e-12)
        assert result.pretty_reward[p] == pytest.approx(report.pretty_reward, abs=1e-12)
        assert result.success_rate[p] == pytest.approx(report.success_rate, abs=1e-12)
        steps = [e.steps for e in report.episodes]
        np.testing.assert_array_equal(result.per_episode("steps")[p], steps)
        total_steps += sum(steps)
    np.testing.assert_array_equal(result.fitness, result.normalized_reward)
    assert result.env_steps == total_steps == result.episodes.steps.sum()
    assert result.seconds > 0
    # individuals differ, so that a mix-up between them would show
    assert len(np.unique(result.fitness)) >= 4
    if build is noisy_clue_followers:
        assert result.success_rate.max() > 0.5 > result.success_rate.min()


def test_hand_built_networks_act_like_amaze_controllers(evaluator):
    spec = NetworkSpec("DD")
    vectors = [linear_dd(np.zeros((8, 4)), np.eye(4)[a]) for a in range(4)]
    vectors.append(linear_dd(clue_follower_weights(), np.zeros(4)))
    population = spec.population(np.stack(vectors))
    result = evaluator.evaluate(population)
    reference = Evaluator("DD", rotations(MAZES), inputs=False)
    controllers = [Constant(a) for a in range(4)] + [ClueFollower()]
    for p, controller in enumerate(controllers):
        report = reference.evaluate(controller)
        np.testing.assert_array_equal(
            result.per_episode("normalized_reward")[p],
            [e.normalized_reward for e in report.episodes],
        )
        np.testing.assert_array_equal(
            result.per_episode("collisions")[p], [e.collisions for e in report.episodes]
        )
    assert result.success_rate[4] > result.success_rate[:4].max()


def test_clue_following_network_scores_like_the_oracle():
    clue_evaluator = PopulationEvaluator(CLUE_MAZES, "DD", rotations=True)
    policy = NetworkSpec("DD").population(linear_dd(clue_follower_weights(), np.zeros(4))[None])
    result = clue_evaluator.evaluate(policy)
    oracle = Evaluator("DD", rotations(CLUE_MAZES), inputs=False).evaluate(OracleController("DD"))
    assert result.success_rate[0] == 1.0 and oracle.success_rate == 1.0
    assert (
        result.normalized_reward[0] == pytest.approx(oracle.normalized_reward) == pytest.approx(1.0)
    )
    assert result.env_steps == sum(e.steps for e in oracle.episodes)


@pytest.mark.parametrize(("p_count", "mazes"), [(5, MAZES), (40, MAZES[::3])])
def test_skipping_retired_agents_changes_nothing(p_count, mazes):
    rng = np.random.default_rng(2)
    base = linear_dd(clue_follower_weights(), np.zeros(4))
    noise = rng.normal(0.0, 1.0, (p_count, base.size)) * np.linspace(0.0, 1.5, p_count)[:, None]
    population = NetworkSpec("DD").population(base + noise)
    mazes = rotations(mazes)
    engine = BatchEngine(mazes, "DD", p_count * len(mazes))
    with_skipping = run_episodes(engine, population)

    def without_retire(observations):
        return population(observations)

    plain = run_episodes(engine, without_retire)
    for name in (
        "success",
        "steps",
        "collisions",
        "backsteps",
        "normalized_reward",
        "pretty_reward",
    ):
        np.testing.assert_array_equal(getattr(with_skipping, name), getattr(plain, name))
    assert len(np.unique(plain.steps)) > 2 and 0 < plain.success.mean() < 1


def test_results_are_deterministic_and_split_populations_join(evaluator):
    rng = np.random.default_rng(8)
    spec = NetworkSpec("DD", (5,))
    population = spec.population(spec.initial_params(rng, 5) * 2)
    first = evaluator.evaluate(population)
    again = PopulationEvaluator(MAZES, "DD", rotations=True).evaluate(
        pickle.loads(pickle.dumps(population))
    )
    for name in ("fitness", "success_rate", "normalized_reward", "pretty_reward"):
        np.testing.assert_array_equal(getattr(first, name), getattr(again, name))
    assert first.env_steps == again.env_steps
    parts = [evaluator.evaluate(population.subset(i)) for i in ([0, 1], [2], [3, 4])]
    joined = PopulationResult.concatenate(parts)
    np.testing.assert_array_equal(joined.fitness, first.fitness)
    np.testing.assert_array_equal(joined.per_episode("steps"), first.per_episode("steps"))
    assert joined.env_steps == first.env_steps
    assert joined.seconds == pytest.approx(sum(p.seconds for p in parts))


def test_fitness_choices(evaluator):
    rng = np.random.default_rng(1)
    spec = NetworkSpec("DD", (4,))
    population = spec.population(spec.initial_params(rng, 3) * 3)
    by_reward = evaluator.evaluate(population)
    success = PopulationEvaluator(MAZES, "DD", rotations=True, fitness="success_rate")
    pretty = PopulationEvaluator(MAZES, "DD", rotations=True, fitness="pretty_reward")
    np.testing.assert_array_equal(success.evaluate(population).fitness, by_reward.success_rate)
    np.testing.assert_array_equal(pretty.evaluate(population).fitness, by_reward.pretty_reward)
    assert by_reward.best == int(np.argmax(by_reward.normalized_reward))


def test_path_progress_fitness(evaluator):
    rng = np.random.default_rng(2)
    spec = NetworkSpec("DD", (4,))
    population = spec.population(spec.initial_params(rng, 4) * 3)
    progress = PopulationEvaluator(MAZES, "DD", rotations=True, fitness="path_progress")
    result = progress.evaluate(population)
    per_episode = result.per_episode("path_progress")
    np.testing.assert_array_equal(result.fitness, per_episode.mean(axis=1))
    assert ((per_episode >= 0) & (per_episode <= 1)).all()
    np.testing.assert_array_equal(per_episode == 1, result.per_episode("success"))
    by_reward = evaluator.evaluate(population)  # the same episodes, progress not looked up
    np.testing.assert_array_equal(result.normalized_reward, by_reward.normalized_reward)
    with pytest.raises(EvolutionConfigError, match="did not record 'path_progress'"):
        by_reward.per_episode("path_progress")
    parts = [progress.evaluate(population.subset(i)) for i in ([0, 1], [2, 3])]
    joined = PopulationResult.concatenate(parts)
    np.testing.assert_array_equal(joined.per_episode("path_progress"), per_episode)
    assert PopulationResult.concatenate([parts[0], by_reward]).episodes.path_progress is None


def test_image_robot_populations(evaluator):
    rng = np.random.default_rng(6)
    spec = NetworkSpec("H7", (6,))
    params = spec.initial_params(rng, 3) * 2
    images = PopulationEvaluator(MAZES[:2], "H7")
    result = images.evaluate(spec.population(params))
    assert images.n_episodes == 2 and len(result) == 3
    for p in range(3):
        alone = images.evaluate(spec.population(params[p : p + 1]))
        np.testing.assert_array_equal(alone.per_episode("steps")[0], result.per_episode("steps")[p])
        assert alone.fitness[0] == result.fitness[p]


def test_maze_sets_and_plain_policies():
    assert len(rotations(MAZES)) == 16
    # Mazes, specs and strings give the same maze set, rotated or not.
    forms = [Maze.from_string(MAZES[0]), MazeSpec.from_string(MAZES[1]), *MAZES[2:]]
    assert PopulationEvaluator(forms, "DD", rotations=True).maze_strings == rotations(MAZES)
    assert (
        PopulationEvaluator(forms, "DD").maze_strings
        == PopulationEvaluator(MAZES, "DD").maze_strings
    )
    single = PopulationEvaluator(MAZES[0], "DD")
    assert single.n_episodes == 1
    assert PopulationEvaluator(MAZES, "DD").n_episodes == 4
    result = single.evaluate(Constant(0))  # any policy is a population of one
    assert len(result) == 1 and result.env_steps == result.episodes.steps[0]


def test_bad_arguments_are_refused(evaluator):
    with pytest.raises(EvolutionConfigError, match="'reward'"):
        PopulationEvaluator(MAZES, "DD", fitness="reward")
    with pytest.raises(EvolutionConfigError, match="Q"):
        PopulationEvaluator(["M4_6x6_Q"], "DD")
    with pytest.raises(EvolutionConfigError, match="XX"):
        PopulationEvaluator(MAZES, "XX")
    with pytest.raises(EvolutionConfigError, match="at least one"):
        PopulationEvaluator([], "DD")
    hybrid = NetworkSpec("H7").population(np.zeros((2, NetworkSpec("H7").n_params)))
    with pytest.raises(EvolutionConfigError, match="CD7 robots"):
        evaluator.evaluate(hybrid)
    with pytest.raises(EvolutionConfigError, match="this result does not hold"):
        PopulationResult(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), 0, 0.0).per_episode(
            "steps"
        )
