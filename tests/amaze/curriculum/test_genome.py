"""The maze genome: mutation operators, the difficulty order and the distance between mazes."""

from __future__ import annotations

import dataclasses
import math
import warnings
from itertools import pairwise

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from amaze.curriculum import GenomeError, MazeGenome, SignSet, difficulty, harder_or_equal
from amaze.curriculum.difficulty import DIFFICULTY_WEIGHTS, DifficultyProfile, difficulty_profile
from amaze.curriculum.distance import SEED_DISTANCE, distance_components, maze_distance
from amaze.curriculum.genome import (
    _OPTIONS,
    OPERATOR_FIELDS,
    SEED_RANGE,
    add_signs,
    lightness_down,
    lightness_up,
    new_seed,
    new_start,
    probability_down,
    probability_up,
    remove_signs,
    size_down,
    size_up,
    toggle_unicursive,
)
from amaze.errors import MazeStringWarning
from amaze.evaluation.suite import PAPER_TRAINING_MAZE
from amaze.maze import Maze, MazeSpec, Sign, StartLocation
from amaze.maze.signs import BUILTIN_SHAPES

FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
MAX_SIZE = 10
GENOME = MazeGenome(max_size=MAX_SIZE)
FIELDS = [f.name for f in dataclasses.fields(MazeSpec)]

#: What each operator may change, written out independently of the module's table.
EXPECTED_FIELDS = {
    "seed": {"seed"},
    "size_up": {"width", "height"},
    "size_down": {"width", "height"},
    "start": {"start"},
    "unicursive": {"unicursive"},
    "add_clue": {"clue"},
    "remove_clue": {"clue"},
    "add_lure": {"lure", "p_lure"},
    "remove_lure": {"lure", "p_lure"},
    "add_trap": {"trap", "p_trap"},
    "remove_trap": {"trap", "p_trap"},
    "p_lure_up": {"p_lure"},
    "p_lure_down": {"p_lure"},
    "p_trap_up": {"p_trap"},
    "p_trap_down": {"p_trap"},
    "clue_lightness_up": {"clue"},
    "clue_lightness_down": {"clue"},
    "lure_lightness_up": {"lure"},
    "lure_lightness_down": {"lure"},
    "trap_lightness_up": {"trap"},
    "trap_lightness_down": {"trap"},
}

# Values on the grid of the steps and off it (the rounding must still move them).
values = st.one_of(
    st.sampled_from([1.0, 0.5, 0.25, 0.05, 0.95, 0.03, 0.125, 0.001]),
    st.floats(min_value=1e-3, max_value=1.0),
)
signs = st.builds(Sign, shape=st.sampled_from(BUILTIN_SHAPES), value=values)
probabilities = st.one_of(st.none(), values)
seeds = st.integers(0, 2**32)


@st.composite
def specs(draw, low: int = 5, high: int = MAX_SIZE) -> MazeSpec:
    return MazeSpec(
        width=draw(st.integers(low, high)),
        height=draw(st.integers(low, high)),
        seed=draw(st.one_of(st.integers(0, 2**31 + 10), st.sampled_from([0, SEED_RANGE - 1]))),
        start=draw(st.sampled_from(list(StartLocation))),
        rotated=draw(st.booleans()),
        unicursive=draw(st.booleans()),
        clue=tuple(draw(st.lists(signs, max_size=2))),
        lure=tuple(draw(st.lists(signs, max_size=2))),
        p_lure=draw(probabilities),
        trap=tuple(draw(st.lists(signs, max_size=2))),
        p_trap=draw(probabilities),
    )


def changed_fields(a: MazeSpec, b: MazeSpec) -> set[str]:
    return {name for name in FIELDS if getattr(a, name) != getattr(b, name)}


def assert_valid(spec: MazeSpec) -> None:
    """Generates, round-trips through its canonical string, and emits no warning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        maze = Maze.generate(spec)
        assert MazeSpec.from_string(maze.to_string()) == spec
    assert not [w for w in caught if issubclass(w.category, MazeStringWarning)]


def assert_within_bounds(spec: MazeSpec, genome: MazeGenome = GENOME) -> None:
    assert genome.min_size <= spec.width <= genome.max_size
    assert genome.min_size <= spec.height <= genome.max_size
    for p in (spec.p_lure, spec.p_trap):
        assert p is None or 0 < p <= 1
    for sign in spec.clue + spec.lure + spec.trap:
        assert 0 < sign.value <= 1


# -- operators -----------------------------------------------------------------


def test_the_operators_are_listed_by_name_with_their_fields() -> None:
    assert set(GENOME.operators()) == set(EXPECTED_FIELDS)
    assert {name: set(f) for name, f in OPERATOR_FIELDS.items()} == EXPECTED_FIELDS
    assert set(_OPTIONS) | {"seed"} == set(OPERATOR_FIELDS)
    assert len(set(GENOME.operators())) == len(GENOME.operators())


def test_every_operator_applies_somewhere() -> None:
    full = MazeSpec.from_string("M4_8x8_C.5_l.5_L.5_t.5_T.5")
    bare = MazeSpec.from_string("M4_8x8")
    assert set(GENOME.applicable(full)) | set(GENOME.applicable(bare)) == set(EXPECTED_FIELDS)


@pytest.mark.parametrize("name", sorted(EXPECTED_FIELDS))
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(spec=specs(), seed=seeds)
def test_each_operator_changes_only_its_fields_and_gives_a_valid_maze(name, spec, seed) -> None:
    mutant = GENOME.apply(name, spec, np.random.default_rng(seed))
    if name in GENOME.applicable(spec):
        assert mutant != spec
        assert changed_fields(spec, mutant) <= EXPECTED_FIELDS[name]
        assert_valid(mutant)
    else:
        assert mutant is spec


@FAST
@given(specs(), seeds, st.integers(1, 4))
def test_mutants_are_valid_and_within_bounds(spec, seed, n) -> None:
    mutant = GENOME.mutate(spec, np.random.default_rng(seed), n=n)
    assert_valid(mutant)
    assert_within_bounds(mutant)


@settings(max_examples=25, deadline=None)
@given(specs(), seeds)
def test_long_mutation_chains_stay_within_bounds(spec, seed) -> None:
    rng = np.random.default_rng(seed)
    current = spec
    for _ in range(40):
        current = GENOME.mutate(current, rng)
        assert_within_bounds(current)
    assert_valid(current)


@FAST
@given(specs(), seeds, st.integers(1, 3))
def test_mutation_is_determined_by_the_generator_seed(spec, seed, n) -> None:
    first = GENOME.mutate(spec, np.random.default_rng(seed), n=n)
    again = GENOME.mutate(spec, np.random.default_rng(seed), n=n)
    assert first == again
    names = ["size_up", "start", "lure_lightness_down"]
    assert GENOME.mutate(spec, np.random.default_rng(seed), names, n) == GENOME.mutate(
        spec, np.random.default_rng(seed), names, n
    )


def test_a_sequence_of_mutations_from_one_generator_is_reproducible() -> None:
    def chain(seed: int) -> list[str]:
        rng = np.random.default_rng(seed)
        spec = MazeSpec.from_string("M4_10x10_C1")
        out = []
        for _ in range(20):
            spec = GENOME.mutate(spec, rng)
            out.append(spec.to_string())
        return out

    assert chain(7) == chain(7)
    assert chain(7) != chain(8)


@FAST
@given(specs(), seeds)
def test_the_seed_operator_always_draws_another_seed(spec, seed) -> None:
    mutant = new_seed(spec, np.random.default_rng(seed))
    assert mutant.seed != spec.seed and 0 <= mutant.seed < SEED_RANGE
    assert changed_fields(spec, mutant) == {"seed"}


def test_the_seed_operator_skips_the_current_seed() -> None:
    drawn = int(np.random.default_rng(0).integers(SEED_RANGE - 1))
    spec = MazeSpec.from_string("M5_5x5")
    # a draw at or above the current seed moves up by one, so the current seed never comes
    assert new_seed(spec.where(seed=drawn), np.random.default_rng(0)).seed == drawn + 1
    assert new_seed(spec.where(seed=drawn + 1), np.random.default_rng(0)).seed == drawn
    assert new_seed(spec.where(seed=drawn + 2), np.random.default_rng(0)).seed == drawn
    # seeds beyond the range of fresh seeds are never drawn again
    assert new_seed(spec.where(seed=SEED_RANGE + 3), np.random.default_rng(0)).seed < SEED_RANGE


def test_size_operators_stop_at_the_bounds() -> None:
    rng = np.random.default_rng(0)
    top = MazeSpec.from_string("M1_10x10")
    assert size_up(top, rng, max_size=10) is top
    assert "size_up" not in GENOME.applicable(top)
    bottom = MazeSpec.from_string("M1_5x5")
    assert size_down(bottom, rng) is bottom
    assert "size_down" not in GENOME.applicable(bottom)
    # a step past the bound stops at it
    assert size_up(MazeSpec.from_string("M1_9x9"), rng, step=5, max_size=10, square=True) == (
        MazeSpec.from_string("M1_10x10")
    )
    # only the side that can still grow is grown
    assert size_up(MazeSpec.from_string("M1_10x7"), rng, max_size=10) == MazeSpec.from_string(
        "M1_10x8"
    )


def test_the_square_mode_keeps_square_mazes_square() -> None:
    genome = MazeGenome(max_size=30, size_step=2, square=True)
    rng = np.random.default_rng(3)
    spec = MazeSpec.from_string("M1_8x8")
    for _ in range(30):
        spec = genome.mutate(spec, rng, ["size_up", "size_down"])
        assert spec.width == spec.height and 5 <= spec.width <= 30


def test_sizes_outside_the_bounds_only_move_towards_them() -> None:
    rng = np.random.default_rng(0)
    big = MazeSpec.from_string("M1_30x30")
    assert size_up(big, rng, max_size=20) is big
    smaller = size_down(big, rng, max_size=20, square=True)
    assert (smaller.width, smaller.height) == (29, 29)
    tiny = MazeSpec.from_string("M1_3x3")
    assert size_down(tiny, rng) is tiny
    assert size_up(tiny, rng, square=True).to_string() == "M1_4x4"


def test_start_goes_to_one_of_the_three_other_corners() -> None:
    spec = MazeSpec.from_string("M1_6x6")
    corners = {new_start(spec, np.random.default_rng(k)).start for k in range(40)}
    assert corners == set(StartLocation) - {StartLocation.SOUTH_WEST}


def test_adding_and_removing_a_kind_uses_the_sign_set_and_the_couplings() -> None:
    rng = np.random.default_rng(0)
    spec = MazeSpec.from_string("M4_10x10_C1")
    assert add_signs(spec, rng, "trap").to_string() == "M4_10x10_C1_t0.5_T.5"
    assert add_signs(spec, rng, "lure").to_string() == "M4_10x10_C1_l0.25_L.25"
    assert add_signs(spec, rng, "clue") is spec  # already there
    assert remove_signs(spec, rng, "clue").to_string() == "M4_10x10"
    assert remove_signs(spec, rng, "lure") is spec  # not there
    custom = SignSet(clue="point-.75", lure=".1", trap="star-.5", p_lure=0.4, p_trap=0.2)
    genome = MazeGenome(signs=custom)
    bare = MazeSpec.from_string("M4_10x10")
    assert genome.apply("add_clue", bare, rng).to_string() == "M4_10x10_Cpoint-.75"
    assert genome.apply("add_lure", bare, rng).to_string() == "M4_10x10_l0.4_L.1"
    assert genome.apply("add_trap", bare, rng).to_string() == "M4_10x10_t0.2_Tstar-.5"
    full = MazeSpec.from_string(PAPER_TRAINING_MAZE)
    assert remove_signs(full, rng, "trap").to_string() == "M2000007_20x20_C1_l0.25_L.25"
    assert remove_signs(full, rng, "lure").to_string() == "M2000007_20x20_C1_t0.5_T.5"


def test_clue_and_trap_operators_wait_for_intersections() -> None:
    rng = np.random.default_rng(0)
    spec = MazeSpec.from_string("M4_10x10_U_C1_t.5_T.5")
    silent = {"add_clue", "remove_clue", "add_trap", "remove_trap", "p_trap_up", "p_trap_down"}
    silent |= {f"{k}_lightness_{w}" for k in ("clue", "trap") for w in ("up", "down")}
    assert not silent & set(GENOME.applicable(spec))
    assert add_signs(MazeSpec.from_string("M4_10x10_U"), rng, "trap").unicursive
    assert add_signs(MazeSpec.from_string("M4_10x10_U"), rng, "lure").p_lure == 0.25
    # the dormant clue and traps come back with the intersections
    back = toggle_unicursive(spec, rng)
    assert back.to_string() == "M4_10x10_C1_t0.5_T.5"
    assert Maze.generate(back).maze_class.label == "traps"


def test_probability_steps_are_rounded_and_bounded() -> None:
    rng = np.random.default_rng(0)
    spec = MazeSpec.from_string("M4_10x10_C1_l.25_L.25_t.98_T.5")
    assert probability_up(spec, rng, "lure").p_lure == 0.3
    assert probability_down(spec, rng, "lure").p_lure == 0.2
    assert probability_up(spec, rng, "trap").p_trap == 1.0  # stops at 1
    at_one = spec.where(p_trap=1.0)
    assert probability_up(at_one, rng, "trap") is at_one
    low = spec.where(p_lure=0.05)
    assert probability_down(low, rng, "lure") is low  # 0 would remove the lures
    odd = spec.where(p_lure=0.1234)
    assert probability_up(odd, rng, "lure", step=0.001).p_lure == 0.124
    with pytest.raises(GenomeError, match="clues have no probability"):
        probability_up(spec, rng, "clue")


def test_lightness_steps_are_rounded_and_bounded() -> None:
    rng = np.random.default_rng(0)
    spec = MazeSpec.from_string("M4_10x10_C1_l.25_L.25_t.5_T.5")
    assert lightness_up(spec, rng, "clue") is spec  # already 1
    assert lightness_down(spec, rng, "clue").to_string() == "M4_10x10_C.95_l0.25_L.25_t0.5_T.5"
    assert lightness_up(spec, rng, "lure").lure == (Sign("arrow", 0.3),)
    dark = spec.where(trap=(Sign("point", 0.05),))
    assert lightness_down(dark, rng, "trap") is dark  # no sign is invisible
    two = spec.where(clue=(Sign("arrow", 1.0), Sign("star", 0.5)))
    assert lightness_up(two, rng, "clue").clue == (Sign("arrow", 1.0), Sign("star", 0.55))


def test_operators_listed_several_times_are_drawn_more_often() -> None:
    spec = MazeSpec.from_string("M1_8x8_C1")
    rng = np.random.default_rng(0)
    names = ["start"] * 9 + ["unicursive"]
    draws = [GENOME.mutate(spec, rng, names) for _ in range(400)]
    flips = sum(mutant.unicursive for mutant in draws)
    assert 10 <= flips <= 80  # about 40 of 400


def test_no_applicable_operator_leaves_the_spec_as_it_is() -> None:
    spec = MazeSpec.from_string("M1_10x10")
    assert GENOME.mutate(spec, np.random.default_rng(0), ["size_up", "remove_lure"], n=3) is spec
    assert GENOME.mutate(spec, np.random.default_rng(0), n=0) is spec


def test_bad_arguments_are_named() -> None:
    rng = np.random.default_rng(0)
    spec = MazeSpec.from_string("M1_10x10")
    with pytest.raises(GenomeError, match="'grow'"):
        GENOME.mutate(spec, rng, ["grow"])
    with pytest.raises(GenomeError, match="max_size 4"):
        MazeGenome(max_size=4)
    with pytest.raises(GenomeError, match="min_size 1"):
        MazeGenome(min_size=1)
    with pytest.raises(GenomeError, match="probability_step 0"):
        MazeGenome(probability_step=0)
    with pytest.raises(GenomeError, match=r"lightness_step 0\.0001"):
        MazeGenome(lightness_step=0.0001)
    with pytest.raises(GenomeError, match="size_step 0"):
        MazeGenome(size_step=0)
    with pytest.raises(GenomeError, match="'glyph'"):
        add_signs(spec, rng, "glyph")
    with pytest.raises(GenomeError, match=r"numpy\.random\.Generator"):
        GENOME.mutate(spec, 3)  # type: ignore[arg-type]
    with pytest.raises(GenomeError, match="p_trap 0"):
        SignSet(p_trap=0)
    with pytest.raises(GenomeError, match="lure sign"):
        SignSet(lure="blob-.5")


# -- difficulty ------------------------------------------------------------------

LADDER = [
    "M4_5x5_U",  # trivial: one corridor
    "M4_10x10_C1",  # simple: two intersections, each with a clue
    "M4_10x10_C1_t.5_T.5",  # the same with one trap instead of a clue
    PAPER_TRAINING_MAZE,  # complex: lures and traps
]


def test_difficulty_profiles_and_scores_by_hand() -> None:
    # Path lengths, intersections and S are the reference's (docs/reference-behaviour.md §3.10).
    trivial, simple, trap, paper = (difficulty_profile(text) for text in LADDER)
    assert (trivial.path_length, trivial.intersections, trivial.lures, trivial.traps) == (
        11,
        0,
        0,
        0,
    )
    assert trivial.deceptiveness == 0
    assert (simple.path_length, simple.intersections, simple.lures, simple.traps) == (29, 2, 0, 0)
    assert simple.surprisingness == pytest.approx(3.2366, abs=1e-4)
    # one trap replacing a clue: the metrics do not see it, the trap count does
    assert dataclasses.replace(simple, traps=1) == trap
    assert (paper.path_length, paper.intersections, paper.lures, paper.traps) == (101, 6, 24, 3)
    assert paper.surprisingness == pytest.approx(4.5813, abs=1e-4)
    assert paper.deceptiveness > 0
    assert difficulty(LADDER[1]) == pytest.approx(0.01 * 29 + 0.1 * 2 + 3.2366, abs=1e-4)
    assert difficulty(LADDER[2]) == pytest.approx(difficulty(LADDER[1]) + 0.5)
    assert difficulty(paper) == pytest.approx(
        1.01 + 0.6 + 0.02 * 24 + 0.5 * 3 + 4.5813 + 0.25 * paper.deceptiveness, abs=1e-4
    )


def test_the_ladder_is_ordered_by_score_and_by_dominance() -> None:
    profiles = [difficulty_profile(text) for text in LADDER]
    scores = [difficulty(profile) for profile in profiles]
    assert scores == sorted(scores) and len(set(scores)) == len(scores)
    for easier, harder in pairwise(profiles):
        assert harder_or_equal(harder, easier)
        assert not harder_or_equal(easier, harder)
    assert harder_or_equal(LADDER[3], LADDER[0])  # on mazes (generated) as well as profiles
    assert sorted(reversed(LADDER), key=difficulty) == LADDER


def test_long_corridors_and_short_trap_mazes_are_incomparable() -> None:
    corridor, traps = "M4_20x20_U", "M4_10x10_C1_t.5_T.5"
    assert not harder_or_equal(corridor, traps) and not harder_or_equal(traps, corridor)


profiles = st.builds(
    DifficultyProfile,
    path_length=st.integers(2, 500),
    intersections=st.integers(0, 50),
    lures=st.integers(0, 100),
    traps=st.integers(0, 50),
    surprisingness=st.floats(0, 8),
    deceptiveness=st.floats(0, 20),
)


@FAST
@given(profiles, profiles, profiles)
def test_dominance_is_a_partial_order_that_the_score_extends(a, b, c) -> None:
    assert harder_or_equal(a, a)
    if harder_or_equal(a, b) and harder_or_equal(b, a):
        assert a == b
    if harder_or_equal(a, b) and harder_or_equal(b, c):
        assert harder_or_equal(a, c)
    if harder_or_equal(a, b):
        assert difficulty(a) >= difficulty(b)
    assert set(a.components()) == set(DIFFICULTY_WEIGHTS)


def test_score_weights_must_cover_every_component() -> None:
    profile = difficulty_profile("M4_5x5_U")
    with pytest.raises(GenomeError, match="traps"):
        profile.score({"path_length": 1})
    assert profile.score(dict.fromkeys(DIFFICULTY_WEIGHTS, 0.0)) == 0


# -- distance ----------------------------------------------------------------------


def test_distance_by_hand() -> None:
    assert maze_distance("M4_10x10_C1", "M4_10x10_C1_l.25_L.25") == pytest.approx(1.25)
    assert maze_distance("M4_10x10_C1", "M9_10x10_C1") == pytest.approx(SEED_DISTANCE)
    assert maze_distance("M4_5x5", "M4_20x20") == pytest.approx(math.log(4) / math.log(50))
    assert maze_distance("M4_5x5", "M4_5x5_NE") == 1.0
    assert maze_distance("M4_5x5", "M4_5x5_SE") == 0.5
    assert maze_distance("M4_8x8_C1", "M4_8x8_C.75") == pytest.approx(0.25)
    assert maze_distance("M4_8x8_C1", "M4_8x8_Cpoint-1") == pytest.approx(0.5)
    assert maze_distance("M4_8x8_C1", "M4_8x8_C1_C.5") == pytest.approx(1.0)
    assert maze_distance("M4_8x8_U", "M4_8x8_U_R") == 1.0
    parts = distance_components("M4_8x8_C1_t.5_T.5", "M4_8x8_C1_t.25_T.75")
    assert parts["trap"] == pytest.approx(0.25) and parts["p_trap"] == pytest.approx(0.25)


def test_distance_with_the_metrics_term() -> None:
    a, b = Maze.from_string("M4_10x10_C1"), "M4_10x10_C1_l.25_L.25"
    plain = maze_distance(a, b)
    ma, mb = (difficulty_profile(m) for m in (a, b))
    gap = abs(ma.surprisingness - mb.surprisingness) + abs(ma.deceptiveness - mb.deceptiveness)
    assert gap > 0
    assert maze_distance(a, b, metrics_weight=0.5) == pytest.approx(plain + 0.5 * gap)
    with pytest.raises(GenomeError, match="metrics_weight"):
        maze_distance(a, b, metrics_weight=-1)


@FAST
@given(specs(2, 100), specs(2, 100), specs(2, 100))
def test_distance_is_a_metric(a, b, c) -> None:
    assert maze_distance(a, a) == 0
    assert maze_distance(a, b) == maze_distance(b, a)
    assert (maze_distance(a, b) == 0) == (a == b)
    assert maze_distance(a, c) <= maze_distance(a, b) + maze_distance(b, c) + 1e-12
    assert maze_distance(a, b.where(seed=a.seed)) <= maze_distance(a, b)


@settings(max_examples=20, deadline=None)
@given(specs(5, 8), specs(5, 8), specs(5, 8))
def test_distance_with_metrics_is_a_metric(a, b, c) -> None:
    def d(x: MazeSpec, y: MazeSpec) -> float:
        return maze_distance(x, y, metrics_weight=0.3)

    assert d(a, a) == 0 and d(a, b) == d(b, a)
    assert (d(a, b) == 0) == (a == b)
    assert d(a, c) <= d(a, b) + d(b, c) + 1e-12


@FAST
@given(specs(), seeds)
def test_a_mutation_moves_a_maze_by_a_bounded_distance(spec, seed) -> None:
    mutant = GENOME.mutate(spec, np.random.default_rng(seed))
    assert 0 < maze_distance(spec, mutant) <= 2.0
