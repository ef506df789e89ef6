"""The scripted curators (careful, moderate, risky, random, interpolation) and the registry."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from amaze.curriculum.curators import (
    BUILTIN_CURATORS,
    Candidate,
    CuratorContext,
    CuratorError,
    History,
    MazeResults,
    curator_class,
    curator_names,
    make_curator,
)
from amaze.curriculum.difficulty import difficulty
from amaze.curriculum.strategies import (
    CHALLENGES,
    CarefulCurator,
    ModerateCurator,
    RiskyCurator,
    challenges,
)
from amaze.errors import MazeStringWarning
from amaze.evaluation.suite import PAPER_TRAINING_MAZE
from amaze.maze import Maze, MazeSpec, Sign, StartLocation

FAST = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
FIELDS = [f.name for f in dataclasses.fields(MazeSpec)]
STRATEGIES = ("careful", "moderate", "risky")

lightness = st.sampled_from([1.0, 0.75, 0.5, 0.25])
probability = st.sampled_from([0.1, 0.25, 0.5, 1.0])


@st.composite
def targets(draw, high: int = 100) -> MazeSpec:
    """Targets of every kind: sizes up to 100, with or without each kind of sign."""
    unicursive = draw(st.booleans())
    lure = draw(st.booleans())
    trap = draw(st.booleans()) and not unicursive
    return MazeSpec(
        width=draw(st.integers(5, high)),
        height=draw(st.integers(5, high)),
        seed=draw(st.integers(0, 2**31 - 1)),
        start=draw(st.sampled_from(list(StartLocation))),
        unicursive=unicursive,
        clue=() if unicursive else (Sign("arrow", draw(lightness)),),
        lure=(Sign("arrow", draw(lightness)),) if lure else (),
        p_lure=draw(probability) if lure else None,
        trap=(Sign("arrow", draw(lightness)),) if trap else (),
        p_trap=draw(probability) if trap else None,
    )


def context(target: MazeSpec | str, seed: int = 0, branches: int = 3, **options) -> CuratorContext:
    return CuratorContext(
        target=str(target), seed=seed, stages=10, branches=branches, options=options
    )


def results(maze: str, reached: int, reward: float = 0.0) -> MazeResults:
    return MazeResults(
        maze=maze,
        success=tuple(i < reached for i in range(4)),
        normalized_reward=(reward,) * 4,
        steps=(10,) * 4,
    )


def candidate(
    maze: str, branch: int = 0, reached: int = 4, reward: float = 1.0, others=(), stage: int = 1
) -> Candidate:
    return Candidate(
        stage=stage,
        branch=branch,
        mazes=(maze,),
        own=(results(maze, reached, reward),),
        others=tuple(others),
        lineage=(0, branch),
        env_steps=100,
        seconds=1.0,
        converged=False,
        lineage_steps=200,
    )


def history(parent: Candidate, stage: int = 1) -> History:
    return History(stage=stage, parent=parent, stages=())


def changed(a: str | MazeSpec, b: str | MazeSpec) -> set[str]:
    x, y = MazeSpec.from_string(str(a)), MazeSpec.from_string(str(b))
    return {name for name in FIELDS if getattr(x, name) != getattr(y, name)} - {"seed"}


def groups(fields: set[str]) -> list[str]:
    """The challenges whose fields cover ``fields`` exactly."""
    return [name for name, own in CHALLENGES.items() if fields and fields <= own]


def assert_canonical(maze: str) -> MazeSpec:
    with warnings.catch_warnings():
        warnings.simplefilter("error", MazeStringWarning)
        spec = MazeSpec.from_string(maze)
    assert spec.to_string() == maze
    assert 2 <= spec.width <= 100 and 2 <= spec.height <= 100
    return spec


def parents_of(target: MazeSpec, data) -> MazeSpec:
    """A parent on the way to ``target``: the trivial start with some challenges taken."""
    spec = MazeSpec.from_string(context(target).trivial_maze())
    curator = CarefulCurator(context(target))
    rng = np.random.default_rng(data.draw(st.integers(0, 100)))
    for _ in range(data.draw(st.integers(0, 8))):
        names = challenges(spec, target)
        if not names:
            break
        spec = curator.challenge(data.draw(st.sampled_from(names)), spec, rng)
    return spec


# -- the registry ------------------------------------------------------------------------


def test_every_builtin_curator_is_a_class_with_its_name() -> None:
    for name in BUILTIN_CURATORS:
        advised = dataclasses.replace(context(PAPER_TRAINING_MAZE), advisor="edens")
        curator = make_curator(name, advised if name == "follow" else context(PAPER_TRAINING_MAZE))
        assert curator.name == name
    assert curator_names()[: len(BUILTIN_CURATORS)] == list(BUILTIN_CURATORS)


def test_an_unknown_curator_is_refused_naming_the_choices() -> None:
    with pytest.raises(CuratorError, match=r"unknown curator 'nope'.*careful.*moderate.*risky"):
        curator_class("nope")
    with pytest.raises(CuratorError, match="not a string"):
        curator_class(3)  # type: ignore[arg-type]


def test_unknown_or_bad_options_are_refused() -> None:
    with pytest.raises(CuratorError, match=r"unknown option.*speed"):
        CarefulCurator(context(PAPER_TRAINING_MAZE, speed=2))
    with pytest.raises(CuratorError, match="threshold"):
        CarefulCurator(context(PAPER_TRAINING_MAZE, threshold=2))
    with pytest.raises(CuratorError, match="unfair"):
        ModerateCurator(context(PAPER_TRAINING_MAZE, unfair=0.5))
    with pytest.raises(CuratorError, match="max_size"):
        RiskyCurator(context(PAPER_TRAINING_MAZE, max_size=101))


# -- challenges --------------------------------------------------------------------------


def test_the_challenges_lead_from_the_trivial_maze_to_the_paper_target() -> None:
    target = MazeSpec.from_string(PAPER_TRAINING_MAZE)
    curator = CarefulCurator(context(target))
    spec = MazeSpec.from_string(context(target).trivial_maze())
    rng = np.random.default_rng(0)
    taken = []
    while names := challenges(spec, target):
        taken.append(names[-1])
        new = curator.challenge(names[-1], spec, rng)
        assert groups(changed(spec, new)), (spec, new)
        spec = new
    assert spec == target
    # 5 -> 10 -> 15 -> 20, intersections (with clues), lures, traps at .25, then .5
    assert sorted(taken) == sorted(["size"] * 3 + ["intersections", "lure", "trap", "p_trap"])


@FAST
@given(target=targets(), data=st.data())
def test_challenges_never_go_past_the_target(target, data) -> None:
    spec = parents_of(target, data)
    assert spec.width <= max(target.width, 5) and spec.height <= max(target.height, 5)
    for name in ("p_lure", "p_trap"):
        if getattr(spec, name) is not None:
            assert getattr(spec, name) <= getattr(target, name)
    assert_canonical(spec.to_string())


# -- careful, moderate, risky: properties --------------------------------------------


@FAST
@given(
    name=st.sampled_from(STRATEGIES),
    target=targets(),
    seed=st.integers(0, 2**20),
    k=st.integers(1, 5),
    stage=st.integers(1, 9),
    reached=st.integers(0, 4),
    data=st.data(),
)
def test_strategies_generate_k_valid_canonical_mazes_deterministically(
    name, target, seed, k, stage, reached, data
) -> None:
    parent = candidate(parents_of(target, data).to_string(), reached=reached)
    curator = make_curator(name, context(target, seed, k))
    mazes = curator.generate(k, history(parent, stage))
    assert len(mazes) == k and all(isinstance(m, str) for m in mazes)
    for maze in mazes:
        spec = assert_canonical(maze)
        if spec.width * spec.height <= 400:
            Maze.generate(spec)
    # the same question gets the same answer, from a fresh curator too
    assert make_curator(name, context(target, seed, k)).generate(k, history(parent, stage)) == mazes
    assert curator.generate(k, history(parent, stage)) == mazes


@FAST
@given(target=targets(), seed=st.integers(0, 2**20), k=st.integers(1, 5), data=st.data())
def test_careful_takes_one_challenge_when_solved_and_none_otherwise(target, seed, k, data) -> None:
    spec = parents_of(target, data)
    curator = CarefulCurator(context(target, seed, k))
    solved = curator.generate(k, history(candidate(spec.to_string(), reached=4)))
    unsolved = curator.generate(k, history(candidate(spec.to_string(), reached=3)))
    open_ = challenges(spec, target)
    for maze in solved:
        fields = changed(spec, maze)
        if open_:
            assert len(groups(fields)) >= 1, (spec, maze)
        else:
            assert fields == set()
        assert MazeSpec.from_string(maze).seed != spec.seed
    for maze in unsolved:
        assert changed(spec, maze) == set()
        assert MazeSpec.from_string(maze).seed != spec.seed
    # a different challenge per branch where possible
    if open_:
        taken = {tuple(sorted(changed(spec, m))) for m in solved}
        assert len(taken) == min(k, len(open_))


def test_careful_threshold_is_an_option() -> None:
    target = MazeSpec.from_string(PAPER_TRAINING_MAZE)
    parent = candidate(context(target).trivial_maze(), reached=3)
    strict = CarefulCurator(context(target)).generate(3, history(parent))
    lenient = CarefulCurator(context(target, threshold=0.75)).generate(3, history(parent))
    assert all(changed(parent.mazes[0], m) == set() for m in strict)
    assert all(groups(changed(parent.mazes[0], m)) for m in lenient)


@FAST
@given(target=targets(), seed=st.integers(0, 2**20), reached=st.integers(0, 4), data=st.data())
def test_moderate_takes_one_challenge_every_stage(target, seed, reached, data) -> None:
    spec = parents_of(target, data)
    mazes = ModerateCurator(context(target, seed)).generate(
        3, history(candidate(spec.to_string(), reached=reached))
    )
    for maze in mazes:
        if challenges(spec, target):
            assert groups(changed(spec, maze)), (spec, maze)
        else:  # the target's family (or the parent's, past it)
            assert changed(spec, maze) == set()


@FAST
@given(target=targets(), seed=st.integers(0, 2**20), data=st.data())
def test_risky_changes_several_fields_at_once(target, seed, data) -> None:
    spec = parents_of(target, data)
    curator = RiskyCurator(context(target, seed, unfair=0.0))
    mazes = curator.generate(4, history(candidate(spec.to_string())))
    rng = np.random.default_rng(0)
    singles = {
        dataclasses.replace(curator.challenge(name, spec, rng), seed=0)
        for name in challenges(spec, target)
    }
    for maze in mazes:
        if len(challenges(spec, target)) >= 2:
            got = dataclasses.replace(MazeSpec.from_string(maze), seed=0)
            assert got not in singles, f"{spec} -> {maze}: one challenge only"
            assert len(changed(spec, maze)) >= 2
        assert MazeSpec.from_string(maze).width <= max(spec.width, target.width)


def test_risky_goes_past_the_target_sometimes_but_never_past_max_size() -> None:
    target = MazeSpec.from_string(PAPER_TRAINING_MAZE)
    curator = RiskyCurator(context(target, unfair=1.0))
    past = 0
    for stage in range(1, 10):
        for maze in curator.generate(3, history(candidate(target.to_string()), stage)):
            spec = MazeSpec.from_string(maze)
            assert spec.width <= 30 and spec.height <= 30  # 1.5 x 20
            past += changed(target, spec) != set()
    assert past > 0
    capped = RiskyCurator(context(target, max_size=20, unfair=1.0))
    for stage in range(1, 5):
        for maze in capped.generate(3, history(candidate(target.to_string()), stage)):
            assert MazeSpec.from_string(maze).width <= 20


# -- selections --------------------------------------------------------------------------


def stage_of(mazes: list[str], table: dict[int, list[tuple[int, float]]]) -> list[Candidate]:
    """Candidates whose (reached, R̄) on every maze of the stage is ``table[branch]``."""
    out = []
    for branch, row in table.items():
        res = [results(m, reached, reward) for m, (reached, reward) in zip(mazes, row, strict=True)]
        out.append(
            dataclasses.replace(
                candidate(mazes[branch], branch),
                own=(res[branch],),
                others=tuple(r for i, r in enumerate(res) if i != branch),
            )
        )
    return out


EASY, MID, HARD = "M1_5x5_U", "M2_8x8_C1", "M3_15x15_C1_l.5_L.25_t.5_T.5"


def test_the_stage_mazes_are_ordered_by_difficulty() -> None:
    assert difficulty(EASY) < difficulty(MID) < difficulty(HARD)


def test_careful_picks_the_best_on_its_own_maze_with_ties_to_the_lower_branch() -> None:
    mazes = [EASY, MID, HARD]
    table = {
        0: [(3, 0.5), (0, 0), (0, 0)],
        1: [(0, 0), (4, 0.1), (0, 0)],
        2: [(4, 0), (4, 0), (3, 0.9)],
    }
    assert (
        make_curator("careful", context(PAPER_TRAINING_MAZE)).select(stage_of(mazes, table)).branch
        == 1
    )
    tie = {0: [(4, 0.2), (0, 0)], 1: [(0, 0), (4, 0.2)]}
    assert (
        make_curator("careful", context(PAPER_TRAINING_MAZE))
        .select(stage_of(mazes[:2], tie))
        .branch
        == 0
    )


def test_moderate_picks_the_generalist() -> None:
    mazes = [EASY, MID, HARD]
    table = {0: [(4, 1), (0, 0), (0, 0)], 1: [(0, 0), (4, 1), (0, 0)], 2: [(2, 0), (2, 0), (2, 0)]}
    assert (
        make_curator("moderate", context(PAPER_TRAINING_MAZE)).select(stage_of(mazes, table)).branch
        == 2
    )


def test_risky_picks_the_best_on_the_hardest_maze() -> None:
    mazes = [HARD, EASY, MID]  # the hardest maze is branch 0's
    table = {
        0: [(1, -1), (4, 1), (4, 1)],
        1: [(2, -2), (0, 0), (0, 0)],
        2: [(2, -1), (0, 0), (0, 0)],
    }
    assert (
        make_curator("risky", context(PAPER_TRAINING_MAZE)).select(stage_of(mazes, table)).branch
        == 2
    )


@pytest.mark.parametrize("name", STRATEGIES)
def test_a_run_plays_each_strategy_to_the_end(name: str, tmp_path) -> None:
    from tests.amaze.runs.toy_curriculum import ToyConfig, ToyRun

    config = ToyConfig(
        regime="edhucat",
        curator=name,
        stages=3,
        branches=2,
        budget_steps=1500,
        target="M4_9x9_C1_l.25_L.25_t.5_T.5",
    )
    result = ToyRun.fresh(config, tmp_path / "run")
    assert result.summary["curator"] == name and len(result.summary["final_lineage"]) == 3
    for stage in result.summary["curriculum"]:
        for maze in stage["mazes"]:
            assert_canonical(maze)
