"""Slipping robots (evolution.slip): slips shared by an episode's players, seeded, training only."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from amaze.agents.robot import as_robot
from evolution import EvolutionConfigError
from evolution.agent_file import load_agent, read_agent
from evolution.algorithms import make_algorithm
from evolution.cli import main
from evolution.networks import NetworkPopulation, NetworkSpec
from evolution.population import PopulationEvaluator
from evolution.run import EvolveConfig
from evolution.slip import SlippingPopulation
from tests.evolution.test_coevolution_run import CONFIG, ROOT
from tests.processes import kill_after_rows
from tests.run_folders import timeless_progress, write_config

SPEC = NetworkSpec("DD", hidden=(6,))
P, M, STEPS = 5, 12, 400


def _population(seed: int = 0) -> NetworkPopulation:
    rng = np.random.default_rng(seed)
    return NetworkPopulation(SPEC, rng.normal(size=(P, SPEC.n_params)))


def _observations(steps: int = STEPS, seed: int = 1) -> np.ndarray:
    """Random DD inputs, (steps, P * M, 8): walls 0 / 0.5 / 1, signs 0 / 0.25 / 0.5 / 1."""
    rng = np.random.default_rng(seed)
    walls = rng.choice([0.0, 0.5, 1.0], size=(steps, P * M, 4))
    signs = rng.choice([0.0, 0.25, 0.5, 1.0], size=(steps, P * M, 4))
    return np.concatenate([walls, signs], axis=2).astype(np.float32)


def _play(policy: object, observations: np.ndarray) -> np.ndarray:
    policy.reset(observations.shape[1])
    return np.stack([policy(step) for step in observations])


def test_without_slips_a_population_plays_as_itself() -> None:
    observations = _observations()
    ours = _play(SlippingPopulation(_population(), 0.0, 3), observations)
    assert np.array_equal(ours, _play(_population(), observations))


def test_slips_replace_the_asked_share_of_actions_at_random() -> None:
    observations = _observations()
    asked = _play(_population(), observations)
    slipped = _play(SlippingPopulation(_population(), 0.3, 3), observations)
    changed = (slipped != asked).mean()
    # a slip draws one of 4 actions: 3 in 4 change it; 24 000 agent-steps, 60 of them shared
    assert 0.3 * 0.75 - 0.03 < changed < 0.3 * 0.75 + 0.03
    counts = np.bincount(_play(SlippingPopulation(_population(), 0.999, 3), observations).ravel())
    assert counts.shape == (4,) and counts.min() > 0.2 * counts.sum()


def test_the_players_of_an_episode_slip_alike() -> None:
    """Common random numbers: every individual slips at the same steps, to the same action."""
    observations = _observations()
    asked = _play(_population(), observations).reshape(STEPS, P, M)
    slipped = _play(SlippingPopulation(_population(), 0.3, 3), observations).reshape(STEPS, P, M)
    changed = slipped != asked
    # where one individual's action changed, every individual took that same action
    steps, _, episodes = np.nonzero(changed)
    assert len(steps) > 1000
    assert np.all(slipped[steps, :, episodes] == slipped[steps, 0, episodes][:, None])


def test_the_slips_follow_the_seed_and_start_again_at_each_reset() -> None:
    observations = _observations()
    policy = SlippingPopulation(_population(), 0.3, [7, 2])
    first = _play(policy, observations)
    assert np.array_equal(_play(policy, observations), first)
    again = SlippingPopulation(_population(), 0.3, [7, 2])
    assert np.array_equal(_play(again, observations), first)
    other = SlippingPopulation(_population(), 0.3, [7, 3])
    assert not np.array_equal(_play(other, observations), first)


@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_a_population_in_parts_slips_as_the_whole(algo: str) -> None:
    """What the Ray backend does: parts from ``subset``, played apart, joined."""
    algorithm = make_algorithm(algo, {"population_size": P}, "DD", 0)
    population = algorithm.population_policy(algorithm.ask())
    mazes = ["M4_6x6_C1", "M7_8x8_C1_l.25_L.25", "M2_9x9_C1_l.2_L.25_t.4_T.5"]
    evaluator = PopulationEvaluator(mazes, "DD", rotations=True, n_policies=P)
    whole = SlippingPopulation(population, 0.2, 5)
    result = evaluator.evaluate(whole)
    parts = [evaluator.evaluate(whole.subset(i)) for i in ([0, 1], [2, 3, 4])]
    assert np.array_equal(np.concatenate([p.fitness for p in parts]), result.fitness)
    assert np.array_equal(
        np.concatenate([p.per_episode("steps") for p in parts]), result.per_episode("steps")
    )
    assert not np.array_equal(evaluator.evaluate(population).fitness, result.fitness)


def test_slips_need_discrete_actions_and_a_probability_below_one() -> None:
    spec = NetworkSpec("CC7", hidden=())
    continuous = NetworkPopulation(spec, np.zeros((1, spec.n_params)))
    with pytest.raises(EvolutionConfigError, match="discrete actions"):
        SlippingPopulation(continuous, 0.1, 0)
    bad_values = ((1, "below 1"), (-0.1, "slip -0.1"), ("x", "slip 'x'"), (float("nan"), "nan"))
    for bad, message in bad_values:
        with pytest.raises(EvolutionConfigError, match=message):
            SlippingPopulation(_population(), bad, 0)
        with pytest.raises(EvolutionConfigError, match=message):
            EvolveConfig.from_dict({**CONFIG, "slip": bad})
    with pytest.raises(EvolutionConfigError, match=r"slip 0\.1 needs a robot with discrete"):
        EvolveConfig.from_dict({**CONFIG, "robot": "CC7", "slip": 0.1})
    assert as_robot("CD7").discrete_outputs
    EvolveConfig.from_dict({**CONFIG, "robot": "CD7", "slip": 0.1})  # continuous inputs are fine


@pytest.fixture(scope="module")
def slipping(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("slip")
    out = folder / "run"
    config = write_config(folder, CONFIG, slip=0.2, max_generations=16)
    assert main(["--config", str(config), "--out", str(out), "--no-progress"]) == 0
    return out


def test_a_slipping_run_trains_on_slips_and_validates_without(
    slipping: Path, tmp_path: Path
) -> None:
    plain = tmp_path / "plain"
    config = write_config(tmp_path, CONFIG, max_generations=16)
    assert main(["--config", str(config), "--out", str(plain), "--no-progress"]) == 0
    assert json.loads((slipping / "config.json").read_text())["slip"] == 0.2
    ours, theirs = timeless_progress(slipping), timeless_progress(plain)
    assert [r["mean"] for r in ours] != [r["mean"] for r in theirs]  # the batches slipped
    # the champion's validation fitness is its slip-free fitness on the validation mazes
    summary = json.loads((slipping / "summary.json").read_text())
    validation = read_agent(slipping / "agent.npz")[1]["validation_mazes"]
    evaluator = PopulationEvaluator(validation, "DD", rotations=True)
    fitness = evaluator.evaluate(load_agent(slipping / "agent.npz")).fitness[0]
    assert fitness == pytest.approx(summary["champion_fitness"], abs=1e-12)


@pytest.mark.slow
def test_a_slipping_run_resumed_after_a_kill_is_bit_identical(
    slipping: Path, tmp_path: Path
) -> None:
    out = tmp_path / "killed"
    config = write_config(tmp_path, CONFIG, slip=0.2, max_generations=16)
    argv = [sys.executable, "-m", "evolution.cli", "--config", str(config), "--out", str(out),
            "--no-progress"]  # fmt: skip
    kill_after_rows(argv, out / "progress.csv", 7, ROOT)
    assert not (out / "summary.json").exists()
    assert main(["--resume", str(out), "--no-progress"]) == 0
    assert timeless_progress(out) == timeless_progress(slipping)
    ours, theirs = read_agent(out / "agent.npz")[0], read_agent(slipping / "agent.npz")[0]
    assert all(np.array_equal(ours[k], theirs[k]) for k in theirs)
