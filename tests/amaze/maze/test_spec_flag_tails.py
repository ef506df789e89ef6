"""``U``, ``R`` tokens with trailing characters: the flag alone, as the reference, and a warning."""

from __future__ import annotations

import warnings

import pytest

from amaze.errors import MazeStringWarning
from amaze.maze.maze import Maze
from amaze.maze.spec import MazeSpec


def parse_quietly(text: str) -> MazeSpec:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MazeStringWarning)
        return MazeSpec.from_string(text)


@pytest.mark.parametrize(
    ("text", "read_as", "token", "advice"),
    [
        ("M4_7x7_Ux", "M4_7x7_U", "Ux", "write 'U' alone"),
        ("M4_7x7_Unicursive", "M4_7x7_U", "Unicursive", "write 'U' alone"),
        ("M4_7x7_UR", "M4_7x7_U", "UR", "did you mean 'U_R' (two tokens)?"),
        ("M4_UC1", "M4_10x10_U", "UC1", "did you mean 'U_C1' (two tokens)?"),
        ("M4_7x7_R90", "M4_7x7_R", "R90", "write 'R' alone"),
        ("M4_7x7_RU", "M4_7x7_R", "RU", "did you mean 'R_U' (two tokens)?"),
    ],
)
def test_a_flag_with_a_tail_warns_and_keeps_the_reference_maze(text, read_as, token, advice):
    with pytest.warns(MazeStringWarning) as caught:
        spec = MazeSpec.from_string(text)
    (warning,) = caught
    assert str(warning.message) == (
        f"maze string '{text}': token '{token}' is read as '{token[0]}'"
        f" (the reference ignores what follows {token[0]}); {advice}"
    )
    assert spec == MazeSpec.from_string(read_as)
    assert spec.to_string() == read_as


def test_the_maze_is_the_one_of_the_flag_alone():
    assert parse_quietly("M4_7x7_Ux") == MazeSpec.from_string("M4_7x7_U")
    tail = Maze.generate(parse_quietly("M4_7x7_Ux"))
    assert tail.to_string() == Maze.from_string("M4_7x7_U").to_string()


@pytest.mark.parametrize("text", ["M4_7x7_U", "M4_7x7_R", "M4_7x7_U_R", "M4 7x7 U R", "Ux__M4_U"])
def test_flags_alone_do_not_warn(text):
    MazeSpec.from_string(text)  # MazeStringWarning is an error under pytest


def test_a_long_run_of_flags_warns_once_without_recursion():
    with pytest.warns(MazeStringWarning, match="did you mean 'U_U"):
        spec = MazeSpec.from_string("M1_" + "U" * 5000)
    assert spec.unicursive
