"""The interpolation curriculum: per-field rules, monotonicity, validity and the CLI."""

from __future__ import annotations

import json
from itertools import pairwise

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from amaze.cli.main import main
from amaze.curriculum.interpolation import (
    InterpolationError,
    curriculum,
    effective_p_trap,
    interpolate,
    interpolation_start,
)
from amaze.errors import AmazeError
from amaze.maze.maze import Maze
from amaze.maze.signs import Sign
from amaze.maze.spec import MazeSpec, StartLocation

PAPER_TARGET = "M2000007_20x20_C1_l.25_L.25_t.5_T.5"
PAPER_STAGES = [
    "M2000007_5x5_U",
    "M2000007_7x7_U_l0.028_L.25",
    "M2000007_8x8_U_l0.056_L.25",
    "M2000007_10x10_U_l0.083_L.25",
    "M2000007_12x12_U_l0.111_L.25",
    "M2000007_13x13_C1_l0.139_L.25_t0.278_T.5",
    "M2000007_15x15_C1_l0.167_L.25_t0.333_T.5",
    "M2000007_17x17_C1_l0.194_L.25_t0.389_T.5",
    "M2000007_18x18_C1_l0.222_L.25_t0.444_T.5",
    "M2000007_20x20_C1_l0.25_L.25_t0.5_T.5",
]


def strings(stages: list[MazeSpec]) -> list[str]:
    return [stage.to_string() for stage in stages]


def test_paper_curriculum_is_pinned_and_ends_at_the_target():
    stages = curriculum(PAPER_TARGET)
    assert strings(stages) == PAPER_STAGES
    assert stages[-1] == MazeSpec.from_string(PAPER_TARGET)
    classes = [Maze.generate(stage).maze_class.label for stage in stages]
    assert classes == ["trivial"] * 5 + ["complex"] * 5


def test_default_start_is_a_trivial_maze_sharing_seed_corner_and_rotation():
    assert interpolation_start(PAPER_TARGET).to_string() == "M2000007_5x5_U"
    start = interpolation_start("M3_3x12_NE_R_C1")
    assert (start.width, start.height, start.seed) == (3, 5, 3)
    assert start.start == StartLocation.NORTH_EAST and not start.rotated and start.unicursive
    assert Maze.generate(start).maze_class.label == "trivial"


def test_sizes_are_rounded_half_up():
    # 5 -> 8 in 3 stages: the middle is 6.5, rounded up to 7 (banker's rounding gives 6);
    # 4 -> 7 in 3 stages: 5.5 -> 6.
    stages = interpolate("M0_5x4_U", "M1_8x7_U", 3)
    assert (stages[1].width, stages[1].height) == (7, 6)


def test_seed_corner_and_rotation_come_from_the_end_maze():
    stages = interpolate("M1_5x5_U", "M9_9x9_NW_R_C1", 4)
    assert [s.seed for s in stages] == [1, 9, 9, 9]
    assert [s.start for s in stages[1:]] == [StartLocation.NORTH_WEST] * 3
    assert [s.rotated for s in stages] == [True, False, False, False]
    with_seed = interpolate("M1_5x5_U", "M9_9x9_NW_R_C1", 4, seed=42)
    assert [s.seed for s in with_seed] == [1, 42, 42, 9]


def test_intersections_clues_and_traps_appear_half_way():
    stages = interpolate("M1_5x5_U", "M2_15x15_C1_t.5_T.5", 6)  # u = 0, .2, .4, .6, .8, 1
    assert [s.unicursive for s in stages] == [True, True, True, False, False, False]
    assert [bool(s.clue) for s in stages] == [False, False, False, True, True, True]
    assert [s.p_trap for s in stages] == [None, None, None, 0.3, 0.4, 0.5]
    # and the other way round: the start's flag for u < 1/2 only
    backwards = interpolate("M2_15x15_C1", "M1_5x5_U", 6)
    assert [s.unicursive for s in backwards] == [False, False, False, True, True, True]


def test_lures_appear_from_the_first_stage_with_a_positive_probability():
    stages = interpolate("M1_10x10_C1", "M1_10x10_C1_l.002_L.5", 5)
    # .0005 rounds half up to .001; 0 stays absent
    assert [s.p_lure for s in stages] == [None, 0.001, 0.001, 0.002, 0.002]
    assert [s.lure for s in stages] == [()] + [(Sign("arrow", 0.5),)] * 4


def test_sign_lightness_is_linear_when_both_mazes_have_the_kind():
    stages = interpolate("M1_10x10_C.5_l.2_Lwarning-.2", "M1_10x10_C1_C.25_l.2_L.6", 5)
    assert [s.to_string() for s in stages[1:4]] == [
        "M1_10x10_C.625_C.438_l0.2_L.3",
        "M1_10x10_C.75_C.375_l0.2_L.4",
        "M1_10x10_C.875_C.313_l0.2_L.5",
    ]
    # a kind only the start has keeps the start's signs while its probability is positive
    fading = interpolate("M1_10x10_C1_l.4_L.3", "M1_10x10_C1", 3)
    assert fading[1].to_string() == "M1_10x10_C1_l0.2_L.3"


@pytest.mark.parametrize(
    ("n", "message"),
    [(1, "n 1"), (0, "n 0"), (True, "n True"), (2.0, "n 2.0"), ("10", "n '10'")],
)
def test_bad_stage_counts_are_rejected(n, message):
    with pytest.raises(InterpolationError, match=message):
        interpolate("M1_5x5_U", PAPER_TARGET, n)


def test_bad_seeds_and_mazes_are_rejected():
    with pytest.raises(InterpolationError, match="seed -1"):
        interpolate("M1_5x5_U", PAPER_TARGET, seed=-1)
    with pytest.raises(AmazeError, match="'Q7'"):
        interpolate("M1_5x5_U_Q7", PAPER_TARGET)
    with pytest.raises(ValueError, match="end maze"):
        curriculum(42)  # type: ignore[arg-type]
    assert issubclass(InterpolationError, ValueError)


def test_two_stages_are_start_and_end():
    assert strings(interpolate("M1_5x5_U", PAPER_TARGET, 2)) == ["M1_5x5_U", PAPER_STAGES[-1]]


signs = st.lists(
    st.builds(
        Sign,
        st.sampled_from(["arrow", "point", "warning"]),
        st.sampled_from([0.25, 0.5, 0.8, 1.0]),
    ),
    min_size=1,
    max_size=2,
)


@st.composite
def easier_harder_pairs(draw) -> tuple[MazeSpec, MazeSpec]:
    """A target maze and a start maze no harder than it (sizes, probabilities, intersections)."""
    width, height = draw(st.integers(2, 25)), draw(st.integers(2, 25))
    p_lure = draw(st.sampled_from([None, 0.1, 0.25, 0.5]))
    p_trap = draw(st.sampled_from([None, 0.2, 0.5, 1.0]))
    end = MazeSpec(
        width=width,
        height=height,
        seed=draw(st.integers(0, 10_000)),
        start=draw(st.sampled_from(list(StartLocation))),
        rotated=draw(st.booleans()),
        unicursive=draw(st.booleans()),
        clue=draw(signs),
        lure=draw(signs),
        p_lure=p_lure,
        trap=draw(signs),
        p_trap=p_trap,
    )
    if draw(st.booleans()):
        return interpolation_start(end), end
    start_lure = draw(st.sampled_from([None, 0.05])) if end.p_lure else None
    start_trap = draw(st.sampled_from([None, 0.1])) if effective_p_trap(end) else None
    start = MazeSpec(
        width=draw(st.integers(2, width)),
        height=draw(st.integers(2, height)),
        seed=draw(st.integers(0, 10_000)),
        unicursive=end.unicursive or draw(st.booleans()),
        clue=draw(signs),
        lure=draw(signs),
        p_lure=start_lure,
        trap=draw(signs),
        p_trap=start_trap,
    )
    return start, end


def non_decreasing(values: list) -> bool:
    return all(a <= b for a, b in pairwise(values))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(pair=easier_harder_pairs(), n=st.integers(2, 12))
def test_stages_are_valid_monotone_and_deterministic(pair, n):
    start, end = pair
    stages = interpolate(start, end, n)
    assert len(stages) == n
    assert stages[0].to_string() == start.to_string()
    assert stages[-1].to_string() == end.to_string()
    assert strings(interpolate(start.to_string(), end.to_string(), n)) == strings(stages)
    assert non_decreasing([s.width for s in stages])
    assert non_decreasing([s.height for s in stages])
    assert non_decreasing([s.p_lure or 0.0 for s in stages])
    assert non_decreasing([effective_p_trap(s) for s in stages])
    flags = [s.unicursive for s in stages]
    assert flags == sorted(flags, reverse=True)  # intersections never vanish again
    for stage in stages[1:-1]:
        assert stage.seed == end.seed and stage.start == end.start
        assert stage.rotated == end.rotated
        assert bool(stage.clue) == (not stage.unicursive)
        assert bool(stage.lure) == bool(stage.p_lure)
    for stage in stages:
        text = stage.to_string()
        assert MazeSpec.from_string(text) == stage
        maze = Maze.generate(stage)  # a rotated maze may swap width and height
        assert sorted((maze.width, maze.height)) == sorted((stage.width, stage.height))
        assert maze.path_length >= 2


def run_cli(capsys, *args: str) -> tuple[int, str, str]:
    status = main(list(args))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_cli_prints_one_line_per_stage(capsys):
    status, out, err = run_cli(capsys, "interpolate", "trivial", PAPER_TARGET)
    assert status == 0, err
    lines = out.splitlines()
    assert len(lines) == 10
    for index, (line, expected) in enumerate(zip(lines, PAPER_STAGES, strict=True)):
        assert line.split()[:2] == [str(index), expected]
    assert "trivial" in lines[0] and "complex" in lines[-1] and "traps=3" in lines[-1]


def test_cli_json_and_seed(capsys):
    status, out, _ = run_cli(
        capsys, "interpolate", "M1_5x5_U", "M2_8x8_C1", "-n", "3", "--json", "--seed", "4"
    )
    assert status == 0
    assert json.loads(out) == ["M1_5x5_U", "M4_7x7_C1", "M2_8x8_C1"]


def test_cli_renders_all_stages(capsys, tmp_path):
    path = tmp_path / "stages.png"
    status, out, _ = run_cli(
        capsys, "interpolate", "trivial", "M5_12x12_C1_l.2_L.5", "-n", "4", "--render", str(path)
    )
    assert status == 0
    assert str(path) in out and len(out.splitlines()) == 5
    with Image.open(path) as picture:
        assert picture.width > 400 and picture.height > 100


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["M1_5x5_U", PAPER_TARGET, "-n", "1"], "n 1"),
        (["M1_5x5_U", PAPER_TARGET, "-n", "ten"], "'ten'"),
        (["M1_5x5_Q", PAPER_TARGET], "'Q'"),
        (["trivial", "M1_0x5"], "width 0"),
        (["M1_5x5_U", PAPER_TARGET, "--render", "stages.jpg"], "must end in .png"),
    ],
)
def test_cli_bad_input_is_one_line_and_status_2(capsys, args, message):
    status, out, err = run_cli(capsys, "interpolate", *args)
    assert status == 2 and out == ""
    assert err.startswith("error: ") and err.count("\n") == 1 and message in err


def test_a_huge_stage_count_is_refused_not_a_hang() -> None:
    from amaze.curriculum.interpolation import MAX_STAGES

    with pytest.raises(InterpolationError, match="1000000000"):
        interpolate("M1_5x5_U", "M1_20x20_C1", 10**9)
    assert len(interpolate("M1_5x5_U", "M1_20x20_C1", MAX_STAGES)) == MAX_STAGES
