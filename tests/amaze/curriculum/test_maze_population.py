"""The co-evolved maze population: its sampling and scoring rules against hand-computed cases."""

from __future__ import annotations

import dataclasses
import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

import amaze.curriculum
import amaze.curriculum.maze_population
from amaze.curriculum.maze_population import (
    BatchMaze,
    CoevolutionError,
    MazePopulation,
    MazePopulationConfig,
    MazeResult,
    rank_weights,
    replay_distribution,
    staleness_weights,
)
from amaze.curriculum.validation import reserved_seeds
from amaze.maze.arrow_styles import write_sign_styles
from amaze.maze.signs import clear_custom_signs, register_custom_signs
from amaze.maze.spec import MazeSpec
from amaze.runs.checkpoint import StateCodec, curriculum_classes, read_checkpoint, write_checkpoint
from tests.run_folders import retagged_checkpoint

TARGET = "M2000007_20x20_C1_l.25_L.25_t.5_T.5"


def _population(**options: object) -> MazePopulation:
    config = MazePopulationConfig(**{"capacity": 4, "batch": 2, **options})
    return MazePopulation(TARGET, config, seed=3, reserved=reserved_seeds())


def _result(p: float, agents: int = 8) -> MazeResult:
    """A result where a fraction ``p`` of 8 agents x 4 rotations reached the goal."""
    success = np.zeros(agents * 4)
    success[: round(p * agents * 4)] = 1
    success = success.reshape(agents, 4)
    return MazeResult.of(success, np.where(success > 0, 0.5, -1.0))


def _family(side: int, seed: int) -> str:
    return dataclasses.replace(
        MazeSpec.from_string(TARGET), width=side, height=side, seed=seed
    ).to_string()


# -- the sampling rules -------------------------------------------------------------------


def test_rank_weights_raise_ranks_to_the_power_minus_one_over_the_temperature() -> None:
    weights = rank_weights([0.1, 0.3, 0.2], temperature=0.3)
    h = np.array([3.0 ** (-1 / 0.3), 1.0, 2.0 ** (-1 / 0.3)])  # ranks 3, 1, 2
    np.testing.assert_allclose(weights, h / h.sum(), rtol=1e-12)
    # the same with temperature 1: 1/rank
    np.testing.assert_allclose(rank_weights([0.1, 0.3, 0.2], 1.0), [2 / 11, 6 / 11, 3 / 11])


def test_rank_weights_flatten_their_scores_and_rank_ties_in_order() -> None:
    flat = rank_weights([0.1, 0.4, 0.3, 0.2], 0.5)
    np.testing.assert_array_equal(rank_weights([[0.1, 0.4], [0.3, 0.2]], 0.5), flat)
    np.testing.assert_allclose(rank_weights([0.5, 0.5], 1.0), [2 / 3, 1 / 3])
    with pytest.raises(CoevolutionError, match="temperature"):
        rank_weights([0.1], 0.0)


def test_staleness_weights() -> None:
    np.testing.assert_allclose(staleness_weights([0, 2, 5], now=5), [5 / 8, 3 / 8, 0])
    np.testing.assert_allclose(staleness_weights([5, 5], now=5), [0.5, 0.5])
    with pytest.raises(CoevolutionError, match="after generation"):
        staleness_weights([6], now=5)


def test_the_replay_distribution_mixes_rank_and_staleness() -> None:
    got = replay_distribution([0.2, 0.1], [3, 1], now=4, temperature=1.0, staleness=0.3)
    # ranks 1, 2 -> (2/3, 1/3); ages 1, 3 -> (1/4, 3/4)
    np.testing.assert_allclose(got, [0.7 * 2 / 3 + 0.3 / 4, 0.7 / 3 + 0.3 * 3 / 4])
    assert got.sum() == pytest.approx(1.0)


def test_maze_results() -> None:
    success = np.array([[1, 0, 0, 0], [1, 1, 1, 1]])
    reward = np.array([[0.5, -1, -1, -1], [0.9, 0.7, 0.9, 0.7]])
    result = MazeResult.of(success, reward)
    assert result.success_rate == pytest.approx(5 / 8)
    assert result.normalized_reward == pytest.approx(reward.mean())
    assert result.best_normalized_reward == pytest.approx(0.8) and result.solved
    assert not MazeResult.of(np.zeros((2, 4)), np.zeros((2, 4))).solved
    with pytest.raises(CoevolutionError, match="shapes"):
        MazeResult.of(np.zeros(4), np.zeros(4))


# -- scores and admission -----------------------------------------------------------------


def test_learnability_scores_and_the_minimal_criterion() -> None:
    population = _population()
    mazes = [BatchMaze(_family(6, 11), origin="family"), BatchMaze(_family(7, 12), origin="family")]
    report = population.update(mazes, [_result(0.25), _result(0.0)])
    assert (report.new, report.admitted) == (2, 1)  # nobody solved the second one
    (record,) = population.member_records()
    assert record.maze == mazes[0].maze and record.birth == 1 and record.origin == "family"
    assert record.score == pytest.approx(0.25 * 0.75)
    # solved by every agent: learnability 0, not admitted either
    report = population.update([BatchMaze(_family(8, 13), origin="family")], [_result(1.0)])
    assert report.admitted == 0 and len(population.members) == 1


def test_regret_is_the_best_reward_ever_minus_the_mean_reward_now() -> None:
    population = _population(score="regret")
    maze = BatchMaze(_family(6, 11), origin="family")
    population.update([maze], [_result(0.5)])
    record = population.member_records()[0]
    assert record.score == pytest.approx(0.5 - (0.5 * 0.5 - 0.5))  # best 0.5, mean -0.25
    population.update([BatchMaze(record.maze, member=record.id)], [_result(0.25)])
    assert record.best_normalized_reward == pytest.approx(0.5)  # the best ever is kept
    assert record.score == pytest.approx(0.5 - (0.25 * 0.5 - 0.75))
    assert record.plays == 2 and record.last_played == 2


def test_a_full_population_replaces_its_lowest_score_only_by_a_higher_one() -> None:
    population = _population(capacity=2, batch=1)
    population.update([BatchMaze(_family(6, 1), origin="family")], [_result(0.5)])  # 0.25
    population.update([BatchMaze(_family(6, 2), origin="family")], [_result(0.25)])  # 0.1875
    report = population.update([BatchMaze(_family(6, 3), origin="family")], [_result(0.125)])
    assert report.admitted == 0  # 0.109 < 0.1875
    report = population.update([BatchMaze(_family(6, 4), origin="family")], [_result(0.375)])
    assert (report.admitted, report.retired) == (1, 1)  # 0.234 > 0.1875
    assert [r.maze for r in population.member_records()] == [_family(6, 1), _family(6, 4)]
    retired = [r for r in population.records if r.retired is not None]
    assert [(r.maze, r.retired) for r in retired] == [(_family(6, 2), 4)]


def test_among_tied_lowest_members_the_nearest_one_goes() -> None:
    population = _population(capacity=2, batch=1)
    small, large = _family(5, 1), _family(20, 2)
    population.update([BatchMaze(small, origin="family")], [_result(0.5)])
    population.update([BatchMaze(large, origin="family")], [_result(0.5)])
    for record in population.member_records():  # everyone solves both now: both score 0
        population.update([BatchMaze(record.maze, member=record.id)], [_result(1.0)])
    population.update([BatchMaze(_family(19, 3), origin="family")], [_result(0.5)])
    assert [r.maze for r in population.member_records()] == [small, _family(19, 3)]


# -- proposals ----------------------------------------------------------------------------


def _fill(population: MazePopulation, **options: object) -> None:
    """Admit new mazes until the population is full (every one half solved), then set options."""
    config = population.config
    population.config = dataclasses.replace(config, replay_probability=0.0)
    while len(population.members) < population.config.capacity:
        batch = population.propose()
        population.update(batch, [_result(0.5) for _ in batch])
    population.config = dataclasses.replace(config, **options)


def test_replay_never_falls_back_to_new_mazes_once_the_population_is_full_enough() -> None:
    population = _population(capacity=4, batch=2, replay_probability=1.0)
    first = population.propose()
    assert all(b.member is None for b in first)  # nothing to replay yet
    population.update(first, [_result(0.5) for _ in first])
    assert len(population.members) == 2
    for _ in range(20):
        batch = population.propose()
        assert all(b.member is not None for b in batch)
        assert len({b.member for b in batch}) == len(batch)  # drawn without replacement
        population.update(batch, [_result(0.5) for _ in batch])
    population = _population(capacity=4, batch=2, replay_probability=0.0)
    _fill(population)
    assert all(b.member is None for b in population.propose())


def test_replayed_members_follow_the_replay_distribution() -> None:
    population = _population(capacity=4, batch=1, temperature=1.0)
    _fill(population, replay_probability=1.0)
    for record, p in zip(population.member_records(), (0.5, 0.25, 0.125, 0.0625), strict=True):
        population.update([BatchMaze(record.maze, member=record.id)], [_result(p)])
    expected = population.replay_distribution()
    draws = [population.propose()[0].member for _ in range(4000)]
    counts = np.bincount([population.members.index(d) for d in draws], minlength=4)
    np.testing.assert_allclose(counts / 4000, expected, atol=0.03)


def test_new_mazes_are_family_mazes_or_mutants_of_members() -> None:
    population = _population(capacity=16, batch=4, mutation_probability=0.5)
    _fill(population)
    members = {r.id: r.maze for r in population.member_records()}
    target = MazeSpec.from_string(TARGET)
    origins = set()
    for _ in range(30):
        batch = population.propose()
        for item in batch:
            spec = MazeSpec.from_string(item.maze)
            assert 5 <= spec.width <= 20 and 5 <= spec.height <= 20
            if item.origin == "family":
                assert (spec.clue, spec.lure, spec.trap) == (target.clue, target.lure, target.trap)
                assert spec.seed not in reserved_seeds()
            elif item.origin == "mutant":
                assert item.maze != members[item.parent]
            origins.add(item.origin)
        population.update(batch, [_result(0.5) for _ in batch])
        members = {r.id: r.maze for r in population.records}
    assert origins == {"replay", "family", "mutant"}


def test_family_mazes_draw_their_sign_shape_from_the_shapes_option(tmp_path: Path) -> None:
    population = _population(capacity=16, batch=4, shapes=["star", "point"])
    target = MazeSpec.from_string(TARGET)
    seen = set()
    for k in range(12):
        batch = population.propose()
        for item in batch:
            spec = MazeSpec.from_string(item.maze)
            if item.origin != "family":
                continue
            shapes = {sign.shape for sign in (*spec.clue, *spec.lure, *spec.trap)}
            assert len(shapes) == 1 and shapes <= {"star", "point"}, item.maze
            seen |= shapes
            values = [[sign.value for sign in getattr(x, kind)] for x in (spec, target)
                      for kind in ("clue", "lure", "trap")]  # fmt: skip
            assert values[:3] == values[3:]  # the target's kinds and lightnesses
        population.update(batch, [_result((k + i) % 5 / 4) for i in range(len(batch))])
    assert seen == {"star", "point"}
    codec = StateCodec(curriculum_classes())
    path = write_checkpoint(tmp_path / "state.npz", population, codec)
    copy = read_checkpoint(path, codec, ValueError, MazePopulation)
    assert copy.config.shapes == ("star", "point")
    assert [b.maze for b in copy.propose()] == [b.maze for b in population.propose()]
    # without the option, nothing is drawn for it: the target's arrows, the same stream
    assert _population().config.to_dict()["shapes"] is None


def test_same_seed_same_population_and_a_checkpoint_goes_on_identically(tmp_path: Path) -> None:
    def step(population: MazePopulation, k: int) -> list[str]:
        batch = population.propose()
        population.update(batch, [_result((k + i) % 5 / 4) for i in range(len(batch))])
        return [b.maze for b in batch]

    a, b = _population(), _population()
    history = [step(a, k) for k in range(12)]
    assert history == [step(b, k) for k in range(12)]
    codec = StateCodec(curriculum_classes())
    path = write_checkpoint(tmp_path / "state.npz", a, codec)
    copy = read_checkpoint(path, codec, ValueError, MazePopulation)
    assert [step(copy, k) for k in range(12, 30)] == [step(a, k) for k in range(12, 30)]
    assert [r.to_row() for r in copy.records] == [r.to_row() for r in a.records]
    other = MazePopulation(TARGET, a.config, seed=4)
    assert [step(other, k) for k in range(12)] != history


def test_a_checkpoint_naming_the_old_module_is_read(tmp_path: Path) -> None:
    """A run folder written before the rename names ``amaze.curriculum.coevolution:...``."""
    population = _population()
    for k in range(6):
        batch = population.propose()
        population.update(batch, [_result((k + i) % 5 / 4) for i in range(len(batch))])
    codec = StateCodec(curriculum_classes())
    path = write_checkpoint(tmp_path / "state.npz", population, codec)
    new = "amaze.curriculum.maze_population"
    old = retagged_checkpoint(path, new, "amaze.curriculum.coevolution", tmp_path / "old.npz")
    copy = read_checkpoint(old, codec, ValueError, MazePopulation)
    assert type(copy) is MazePopulation
    assert [r.to_row() for r in copy.records] == [r.to_row() for r in population.records]
    assert [b.maze for b in copy.propose()] == [b.maze for b in population.propose()]
    # an old tag of another module is still refused
    other = retagged_checkpoint(path, new, "amaze.curriculum.elsewhere", tmp_path / "other.npz")
    with pytest.raises(ValueError, match="elsewhere:MazePopulation"):
        read_checkpoint(other, codec, ValueError, MazePopulation)


def test_the_old_module_name_warns_and_gives_the_new_modules_names() -> None:
    """``amaze.curriculum.coevolution``, deprecated for one release: the only test importing it."""
    name = "amaze.curriculum.coevolution"
    saved = sys.modules.pop(name, None)
    try:
        with pytest.warns(DeprecationWarning, match=r"renamed amaze\.curriculum\.maze_population"):
            old = importlib.import_module(name)
        new = amaze.curriculum.maze_population
        assert set(new.__all__) <= set(old.__all__)
        for public in old.__all__:
            assert getattr(old, public) is getattr(new, public), public
    finally:
        sys.modules.pop(name, None)
        if saved is not None:
            sys.modules[name] = saved
        elif hasattr(amaze.curriculum, "coevolution"):
            delattr(amaze.curriculum, "coevolution")


@pytest.mark.parametrize(
    ("options", "bad"),
    [
        ({"score": "fun"}, "score 'fun'"),
        ({"capacity": 2, "batch": 4}, "capacity 2"),
        ({"temperature": 0}, "temperature"),
        ({"replay_probability": 1.5}, "replay_probability"),
        ({"min_size": 1}, "min_size"),
        ({"max_size": 4}, "max_size"),
        ({"batchsize": 4}, "unknown coevolution option"),
        ({"shapes": ["arrow", "blob"]}, "unknown sign shape 'blob'"),
        ({"shapes": "star"}, "non-empty list"),
        ({"shapes": []}, "non-empty list"),
        ({"shapes": ["star", "star"]}, "twice"),
    ],
)
def test_bad_options_are_named(options: dict, bad: str) -> None:
    with pytest.raises(CoevolutionError, match=bad):
        MazePopulationConfig.from_dict(options)


def test_new_mazes_are_never_taken_even_when_mutants_run_out() -> None:
    # a 5x5 target whose genome can only change the seed, size and start: a crowded space
    population = MazePopulation(
        "M1_5x5_U", MazePopulationConfig(capacity=64, batch=8, max_size=5), seed=0
    )
    for _ in range(40):
        batch = population.propose()
        strings = [b.maze for b in batch]
        members = {r.maze for r in population.member_records()}
        assert len(set(strings)) == len(strings)
        assert not {b.maze for b in batch if b.member is None} & members
        population.update(batch, [_result(0.5) for _ in batch])
    assert len({r.maze for r in population.records}) == len(population.records)


def test_replay_copes_with_weights_that_underflow() -> None:
    population = _population(capacity=8, batch=8, temperature=0.001, staleness=0.0)
    _fill(population, replay_probability=1.0)
    assert np.count_nonzero(population.replay_distribution()) < 8
    batch = population.propose()
    assert len(batch) == 8 and len({b.maze for b in batch}) == 8


def test_sign_styles_join_the_shapes_family_mazes_are_drawn_in(tmp_path: Path) -> None:
    clear_custom_signs()
    try:
        # the option's names need no registered image to be checked: the run draws them
        population = _population(capacity=16, batch=4, shapes=["star"], sign_styles=2)
        assert population.config.drawn_shapes == ("star", "arrowv0", "arrowv1")
        assert _population(sign_styles=1).config.drawn_shapes == ("arrowv0",)
        assert _population().config.drawn_shapes is None
        write_sign_styles(tmp_path, 2, 0)
        register_custom_signs(tmp_path / "training")
        seen = set()
        for k in range(12):
            batch = population.propose()
            for item in batch:
                spec = MazeSpec.from_string(item.maze)
                if item.origin == "family":
                    seen |= {sign.shape for sign in (*spec.clue, *spec.lure, *spec.trap)}
            population.update(batch, [_result((k + i) % 5 / 4) for i in range(len(batch))])
        assert seen == {"star", "arrowv0", "arrowv1"}
        with pytest.raises(CoevolutionError, match=r"\['arrowv1'\] are among the 2 sign_styles"):
            _population(shapes=["arrowv1"], sign_styles=2)
    finally:
        clear_custom_signs()
    for bad in (-1, 257, 1.5):
        with pytest.raises(CoevolutionError, match="sign_styles"):
            _population(sign_styles=bad)
    heads = MazePopulationConfig(sign_styles=2, sign_styles_heads=["open", "hollow"])
    assert heads.sign_styles_heads == ("open", "hollow")
    assert heads.to_dict()["sign_styles_heads"] == ["open", "hollow"]
    assert MazePopulationConfig().to_dict()["sign_styles_heads"] == ["filled", "open"]
    with pytest.raises(CoevolutionError, match=r"sign_styles_heads \['hollow'\] needs sign_styles"):
        MazePopulationConfig(sign_styles_heads=["hollow"])
    for bad, named in ((["round"], "'round'"), ([], r"\[\]"), ("hollow", "'hollow'")):
        with pytest.raises(CoevolutionError, match=f"sign_styles_heads: .*{named}"):
            MazePopulationConfig(sign_styles=2, sign_styles_heads=bad)
    wide = MazePopulationConfig(sign_styles=2, sign_styles_shaft_width=[0.1, 0.3])
    assert wide.sign_styles_shaft_width == (0.1, 0.3)
    assert wide.to_dict()["sign_styles_shaft_width"] == [0.1, 0.3]
    assert MazePopulationConfig().to_dict()["sign_styles_shaft_width"] == [0.05, 0.16]
    with pytest.raises(CoevolutionError, match=r"shaft_width \[0.1, 0.3\] needs sign_styles"):
        MazePopulationConfig(sign_styles_shaft_width=[0.1, 0.3])
    for bad, named in (([0.1], r"\[0.1\]"), ([0.1, 0.4], "0.4"), ([0.2, 0.1], "low end")):
        with pytest.raises(CoevolutionError, match=f"sign_styles_shaft_width: .*{named}"):
            MazePopulationConfig(sign_styles=2, sign_styles_shaft_width=bad)
