"""The evolution learner of curricula, and the algorithms' reseed and forget_champion."""

from __future__ import annotations

import copy
import pickle
import random
from pathlib import Path

import numpy as np
import pytest

from amaze.curriculum.learner import Learner
from amaze.maze import rotations
from amaze.runs.checkpoint import write_checkpoint
from evolution import EvolutionConfigError
from evolution.agent_file import load_agent, read_agent
from evolution.algorithms import make_algorithm
from evolution.checkpoint import evolution_codec
from evolution.learner import LEARNER_FILE, EvolutionLearner, load_learner
from evolution.neat.compile import genome_to_arrays
from evolution.population import PopulationEvaluator

TRIVIAL = rotations("M0_5x5_U")
SMALL = rotations("M3_6x6_C1")
OPTIONS = {"cmaes": {"population_size": 8}, "neat": {"population_size": 10}}


def _learner(algo: str = "cmaes", seed: int = 1, **kwargs: object) -> EvolutionLearner:
    return EvolutionLearner.new(algo, OPTIONS[algo], "DD", seed, **kwargs)  # type: ignore[arg-type]


def _arrays(learner: EvolutionLearner) -> dict[str, np.ndarray]:
    assert learner.champion is not None
    return learner.champion.arrays


def _same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


def _candidates(algo: str, algorithm: object) -> list[np.ndarray]:
    """The next candidates as arrays (NEAT genomes compiled), to compare two states."""
    asked = algorithm.ask()  # type: ignore[attr-defined]
    if algo == "neat":
        return [np.concatenate([v.ravel() for v in genome_to_arrays(g)[0].values()]) for g in asked]
    return [np.asarray(x) for x in asked]


def _fingerprint(algo: str, algorithm: object) -> list[np.ndarray]:
    """What the algorithm draws next: its candidates, and those after a (synthetic) tell.

    Two algorithms with the same fingerprint have the same strategy or
    population and the same random state.
    """
    twin = copy.deepcopy(algorithm)
    now = _candidates(algo, twin)
    _tell(twin, np.arange(len(now), dtype=float))
    return [*now, *_candidates(algo, twin)]


def _same_fingerprint(algo: str, a: object, b: object) -> bool:
    x, y = _fingerprint(algo, a), _fingerprint(algo, b)
    return len(x) == len(y) and all(np.array_equal(u, v) for u, v in zip(x, y, strict=True))


def _act(policy: object, observations: np.ndarray) -> np.ndarray:
    policy.reset(len(observations))  # type: ignore[attr-defined]
    return np.asarray(policy(observations))  # type: ignore[operator]


def _tell(algorithm: object, fitness: np.ndarray) -> None:
    algorithm.tell(algorithm.ask(), fitness)  # type: ignore[attr-defined]


# -- the algorithms -------------------------------------------------------------------


@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_reseed_gives_independent_streams(algo: str) -> None:
    algorithm = make_algorithm(algo, OPTIONS[algo], "DD", 0)
    size = len(algorithm.ask())
    _tell(algorithm, np.arange(size, dtype=float))
    outer_np, outer_random = np.random.get_state(), random.getstate()  # noqa: NPY002
    first, second, again = (copy.deepcopy(algorithm) for _ in range(3))
    first.reseed(1)
    second.reseed(2)
    again.reseed(1)
    for twin in (first, second, again):  # NEAT draws when it breeds: one more generation
        _tell(twin, np.arange(len(twin.ask()), dtype=float))
    a, b, c = (_candidates(algo, twin) for twin in (first, second, again))
    assert all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))
    assert len(a) != len(b) or not all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert first.seed == 1 and second.seed == 2
    # the caller's random states are left alone
    assert np.array_equal(np.random.get_state()[1], outer_np[1])  # noqa: NPY002
    assert random.getstate() == outer_random


@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_forget_champion_starts_a_new_one_at_the_next_tell(algo: str) -> None:
    algorithm = make_algorithm(algo, OPTIONS[algo], "DD", 0)
    size = len(algorithm.ask())
    _tell(algorithm, np.full(size, 10.0))
    kept = copy.deepcopy(algorithm)
    algorithm.forget_champion()
    assert algorithm.champion is None
    for a in (algorithm, kept):
        _tell(a, np.linspace(0.0, 1.0, len(a.ask())))
    assert algorithm.champion[1] == 1.0  # the best of the new fitness
    assert kept.champion[1] == 10.0  # without forgetting, the old one stays
    if algo == "neat":  # species progress is counted afresh too
        assert all(s.best_fitness <= 1.0 for s in algorithm.species)


# -- the learner ----------------------------------------------------------------------


def test_a_session_spends_its_budget_in_whole_generations_and_checkpoints() -> None:
    learner = _learner(checkpoint_seconds=0)
    assert isinstance(learner, Learner)
    calls: list[int] = []
    outcome = learner.train(TRIVIAL, 6000, checkpoint=lambda: calls.append(learner.generations))
    assert learner.session is None and learner.last_session is not None
    generations = learner.last_session.generations
    per_generation = outcome.env_steps / generations
    assert 6000 <= outcome.env_steps < 6000 + 2 * per_generation
    assert not outcome.converged and outcome.seconds > 0
    assert calls == [*range(1, generations), generations]  # every generation, and the end
    rare = _learner(checkpoint_seconds=1e9)
    calls = []
    rare.train(TRIVIAL, 6000, checkpoint=lambda: calls.append(rare.generations))
    assert calls == [1, generations]  # after the first generation, and the end


def test_a_session_stops_once_converged(monkeypatch: pytest.MonkeyPatch) -> None:
    learner = _learner()
    monkeypatch.setattr(EvolutionLearner, "_converged", lambda self, result: True)
    outcome = learner.train(TRIVIAL, 10**6)
    assert outcome.converged and learner.generations == 1


def test_converged_means_every_episode_optimal() -> None:
    learner = _learner()
    learner.train(TRIVIAL, 1)  # one generation
    result = learner._evaluator(tuple(TRIVIAL)).evaluate(
        learner.algorithm.population_policy(learner.algorithm.ask())
    )
    assert not learner._converged(result)  # random linear policies are not optimal
    from amaze.evaluation.controllers import OracleController

    cheater = learner._evaluator(tuple(TRIVIAL)).evaluate(OracleController("DD"))
    assert learner._converged(cheater)


def test_a_new_session_has_its_own_champion() -> None:
    learner = _learner()
    learner.train(TRIVIAL, 3000)
    first = learner.champion
    params, _ = learner.algorithm.champion
    learner.algorithm._champion = (params, 100.0)  # unbeatable on any maze
    learner.train(SMALL, 3000)
    second = learner.champion
    assert second is not None and second.fitness < 100.0
    # the champion is the best of the new session, scored on the new mazes
    played = PopulationEvaluator(list(SMALL), "DD").evaluate(learner.agent())
    assert played.fitness[0] == second.fitness
    assert first is not None and second is not None
    assert first.mazes == tuple(TRIVIAL) and second.mazes == tuple(SMALL)
    assert second.fitness == learner.last_session.champion_fitness
    assert learner.algorithm.champion[1] == second.fitness  # not the trivial maze's
    assert learner.generations == learner.algorithm.generation


@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_branches_draw_independently(algo: str) -> None:
    parent = _learner(algo)
    parent.train(TRIVIAL, 3000)
    untouched = copy.deepcopy(parent)
    one, two, one_again = parent.branch(11), parent.branch(12), parent.branch(11)
    assert _same_fingerprint(algo, parent.algorithm, untouched.algorithm)  # parent left alone
    for twin in (one, two, one_again):
        assert twin.session is None and twin.seed in (11, 12)
        twin.train(SMALL, 4000)
    assert _same(_arrays(one), _arrays(one_again))
    assert _same_fingerprint(algo, one.algorithm, one_again.algorithm)
    assert not _same_fingerprint(algo, one.algorithm, two.algorithm)
    if algo == "cmaes":  # (NEAT's first generation is the parent's bred population)
        found = [twin.algorithm.champion_arrays()[0] for twin in (one, two)]
        assert not _same(*found)  # what each branch's own search found


@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_a_session_starts_from_the_inherited_champion_played_on_its_mazes(algo: str) -> None:
    parent = _learner(algo)
    parent.train(SMALL, 30_000)
    replay = PopulationEvaluator(list(SMALL), "DD").evaluate(parent.agent())
    child = parent.branch(5)
    # the replay, then one generation, which starts only if the steps left pay its least cost
    least = child.generation_steps(SMALL)
    child.train(SMALL, replay.env_steps + least)
    assert child.last_session.generations == 1
    # That generation's best is no better than the parent's champion, which stays.
    assert child.algorithm.champion[1] <= replay.fitness[0]  # (NEAT keeps its elite)
    assert child.champion.fitness == replay.fitness[0]
    assert _same(_arrays(child), _arrays(parent))
    assert child.champion.mazes == tuple(SMALL)
    # The replay is paid from the session's steps.
    assert child.last_session.steps == child.env_steps - parent.env_steps > replay.env_steps


def test_same_seed_same_mazes_same_learner() -> None:
    a, b = _learner(seed=3), _learner(seed=3)
    for learner in (a, b):
        learner.train(SMALL, 5000)
    assert _same(_arrays(a), _arrays(b))
    assert a.last_session.steps == b.last_session.steps
    assert _same_fingerprint("cmaes", a.algorithm, b.algorithm)


@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_save_and_load(algo: str, tmp_path: Path) -> None:
    learner = _learner(algo)
    learner.save(tmp_path / "fresh")  # no champion yet: the learner alone
    assert not (tmp_path / "fresh" / "champion.npz").exists()
    assert load_learner(tmp_path / "fresh").champion is None
    learner.train(TRIVIAL, 3000)
    learner.save(tmp_path / "agent")
    loaded = load_learner(tmp_path / "agent")
    assert _same(_arrays(loaded), _arrays(learner))
    assert _same_fingerprint(algo, loaded.algorithm, learner.algorithm)
    arrays, metadata = read_agent(tmp_path / "agent" / "champion.npz")
    assert _same(arrays, _arrays(learner)) and metadata["algorithm"] == algo
    assert metadata["mazes"] == list(TRIVIAL)
    # the saved agent and the learner's agent act alike
    observations = np.random.default_rng(0).random((5, 8)).astype(np.float32)
    actions = [
        _act(policy, observations)
        for policy in (learner.agent(), loaded.agent(), load_agent(tmp_path / "agent/champion.npz"))
    ]
    assert np.array_equal(actions[0], actions[1]) and np.array_equal(actions[0], actions[2])
    # both continue alike
    loaded.train(SMALL, 3000)
    learner.train(SMALL, 3000)
    assert _same(_arrays(loaded), _arrays(learner))


def test_a_damaged_or_foreign_learner_file_is_refused_by_name(tmp_path: Path) -> None:
    learner = _learner()
    learner.train(TRIVIAL, 1)
    learner.save(tmp_path)
    path = tmp_path / LEARNER_FILE
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(EvolutionConfigError, match=str(path)):
        load_learner(tmp_path)
    learner.version = 99
    learner.save(tmp_path)
    with pytest.raises(EvolutionConfigError, match="version 99"):
        load_learner(tmp_path)
    write_checkpoint(path, {"not": "a learner"}, evolution_codec())
    with pytest.raises(EvolutionConfigError, match="does not hold"):
        load_learner(tmp_path)
    path.write_bytes(pickle.dumps(learner))
    with pytest.raises(EvolutionConfigError, match="is a pickle"):
        load_learner(tmp_path)
    path.unlink()
    with pytest.raises(EvolutionConfigError, match="does not exist"):
        load_learner(tmp_path)


class _Killed(Exception):
    pass


@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_a_session_saved_mid_way_resumes_bit_identically(algo: str, tmp_path: Path) -> None:
    whole = _learner(algo, checkpoint_seconds=0)
    whole.train(TRIVIAL, 2000)
    branch = whole.branch(5)
    expected = branch.train(SMALL, 12_000)

    interrupted = whole.branch(5)
    saves = []

    def checkpoint() -> None:
        interrupted.save(tmp_path)
        saves.append(interrupted.generations)
        if len(saves) == 3:
            raise _Killed

    with pytest.raises(_Killed):
        interrupted.train(SMALL, 12_000, checkpoint=checkpoint)
    resumed = load_learner(tmp_path)
    assert resumed.session is not None and resumed.session.generations == 3
    outcome = resumed.train(SMALL, 12_000, checkpoint=lambda: resumed.save(tmp_path))
    assert outcome.env_steps == expected.env_steps and outcome.converged == expected.converged
    assert _same(_arrays(resumed), _arrays(branch))
    assert resumed.generations == branch.generations
    assert _same_fingerprint(algo, resumed.algorithm, branch.algorithm)
    # a learner saved at the end of its session ends it at once when resumed
    finished = load_learner(tmp_path)
    assert finished.session is not None
    again = finished.train(SMALL, 12_000)
    assert again.env_steps == expected.env_steps and finished.generations == branch.generations
