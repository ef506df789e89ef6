"""EDEnS over maze populations: the selector's options, controller mutations, the pick, branches."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from amaze.curriculum.maze_population import (
    CoevolutionError,
    MazePopulation,
    MazePopulationConfig,
    MazeResult,
)
from amaze.curriculum.population_selector import (
    CONTROLLER_FIELDS,
    CRITERIA,
    Outcome,
    SelectorConfig,
    choose,
    criteria_values,
    difficulty_reached,
    mutate_controller,
    selector_rng,
)
from amaze.curriculum.validation import reserved_seeds

TARGET = "M2000007_20x20_C1_l.25_L.25_t.5_T.5"


def _population(**options: object) -> MazePopulation:
    config = MazePopulationConfig(**{"capacity": 4, "batch": 2, **options})
    return MazePopulation(TARGET, config, seed=3, reserved=reserved_seeds())


def _result(p: float) -> MazeResult:
    success = np.zeros(32)
    success[: round(p * 32)] = 1
    success = success.reshape(8, 4)
    return MazeResult.of(success, np.where(success > 0, 0.5, -1.0))


def _step(population: MazePopulation, k: int) -> list[str]:
    batch = population.propose()
    population.update(batch, [_result((k + i) % 5 / 4) for i in range(len(batch))])
    return [b.maze for b in batch]


def _outcome(index: int, *values: float, solved: bool = True) -> Outcome:
    criteria = dict(zip(CRITERIA, (*values, 0.0, 0.0, 0.0, 0.0)[:4], strict=True))
    return Outcome(index, MazePopulationConfig(), (), criteria, solved)


def test_controller_mutations_change_only_the_fields_they_name() -> None:
    parent = MazePopulationConfig()
    rng = np.random.default_rng(0)
    seen: set[str] = set()
    for _ in range(200):
        child, names = mutate_controller(parent, TARGET, rng, 3)
        assert 1 <= len(names) <= 3 and set(names) <= set(CONTROLLER_FIELDS)
        seen.update(names)
        before, after = parent.to_dict(), child.to_dict()
        before["max_size"] = 20  # the target's side, made explicit
        changed = {k for k in before if before[k] != after[k]}
        assert changed <= set(names)
        assert (child.batch, child.capacity) == (parent.batch, parent.capacity)
        assert 5 <= child.min_size <= child.max_size <= 20
        assert 0.05 <= child.temperature <= 1 and 1 <= child.edits <= 8
        assert all(0 <= getattr(child, k) <= 1 for k in ("staleness", "replay_probability"))
    assert seen == set(CONTROLLER_FIELDS)
    flipped = [mutate_controller(parent, TARGET, np.random.default_rng(s), 8)[0] for s in range(9)]
    assert {c.score for c in flipped} == {"learnability", "regret"}


def test_controller_mutations_are_seeded() -> None:
    def draw(seed: int) -> list:
        rng = selector_rng(seed, 3, "controllers")
        return [mutate_controller(MazePopulationConfig(), TARGET, rng, 2) for _ in range(4)]

    assert draw(7) == draw(7) != draw(8)
    assert selector_rng(7, 3, "a").random() != selector_rng(7, 4, "a").random()


def test_extinct_alternatives_are_rejected_and_the_pick_is_on_the_front() -> None:
    strong = _outcome(0, 1.0, 0.9, 1.0)
    dominated = _outcome(1, 0.5, 0.1, 0.5)
    other = _outcome(2, 0.8, 0.95, 0.2)
    extinct = _outcome(3, 0.0, 5.0, 9.0, solved=False)  # would be on the front if alive
    criteria = CRITERIA[:3]
    picks = set()
    for seed in range(40):
        chosen, front, alive = choose(
            [strong, dominated, other, extinct], criteria, np.random.default_rng(seed)
        )
        assert front == [strong, other] and extinct not in alive
        picks.add(chosen.index)
    assert picks == {0, 2}
    # on two criteria, the one that beats the other on both is the only one on the front
    chosen, front, _ = choose([strong, dominated, other], CRITERIA[:1], np.random.default_rng(0))
    assert front == [strong] and chosen is strong
    # all extinct: all are judged
    dead = [dataclasses.replace(o, solved=False) for o in (strong, dominated)]
    assert choose(dead, criteria, np.random.default_rng(0))[1] == [dead[0]]


def test_criteria_of_a_population() -> None:
    population = _population()
    assert difficulty_reached(population) == 0.0
    for k in range(6):
        _step(population, k)
    members = population.member_records()
    expected = np.mean([r.difficulty * r.success_rate for r in members])
    values = criteria_values(population, 0.5, -0.25)
    assert values == {
        "validation_success_rate": 0.5,
        "validation_fitness": -0.25,
        "difficulty_reached": pytest.approx(expected),
        "diversity": pytest.approx(population.diversity()),
    }
    assert values["difficulty_reached"] > 0


def test_a_branch_goes_on_apart_and_shares_the_generated_mazes() -> None:
    parent = _population()
    for k in range(5):
        _step(parent, k)
    records = [r.to_row() for r in parent.records]
    twin = parent.branch()
    steered = parent.branch(dataclasses.replace(parent.config, max_size=8, min_size=6), seed=11)
    assert steered.genome.max_size == 8 and steered.max_size == 8
    assert twin.generated(parent.records[0].maze) is parent.generated(parent.records[0].maze)
    # the unsteered copy draws what the parent would have drawn
    ahead = [_step(twin, k) for k in range(5, 12)]
    assert [_step(parent, k) for k in range(5, 12)] == ahead
    fresh = [_step(steered, k) for k in range(5, 12)]
    assert fresh != ahead
    assert all(
        max(int(s) for s in maze.split("_")[1].split("x")) <= 8
        for batch in fresh for maze in batch if maze not in {r["maze"] for r in records}
    )  # fmt: skip
    # the parent's records were not touched by its branches
    steered.records[0].score = 99.0
    assert parent.records[0].score != 99.0


@pytest.mark.parametrize(
    ("options", "bad"),
    [
        ({"alternatives": 0}, "selector alternatives 0"),
        ({"epoch": 1.5}, "selector epoch 1.5"),
        ({"mutations": 9}, "selector mutations 9"),
        ({"criteria": []}, "non-empty list"),
        ({"criteria": ["diversity", "diversity"]}, "distinct"),
        ({"criteria": ["speed"]}, "speed"),
        ({"alpha": 1}, "unknown selector option"),
    ],
)
def test_selector_options_are_checked(options: dict, bad: str) -> None:
    with pytest.raises(CoevolutionError, match=bad):
        SelectorConfig.from_dict(options)
    assert SelectorConfig.from_dict({}).to_dict()["criteria"] == list(SelectorConfig().criteria)
