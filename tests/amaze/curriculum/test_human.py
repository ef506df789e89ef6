"""The terminal curator, with scripted input."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from amaze.curriculum.curators import (
    Candidate,
    CuratorContext,
    CuratorError,
    History,
    MazeResults,
    make_curator,
)
from amaze.curriculum.human import TerminalCurator
from amaze.evaluation.suite import PAPER_TRAINING_MAZE
from amaze.maze import MazeSpec

CONTEXT = CuratorContext(target=PAPER_TRAINING_MAZE, seed=3, stages=4, branches=2)
MAZES = ("M1_5x5_U", "M2_6x6_C1")


def candidate(branch: int) -> Candidate:
    own, other = MAZES[branch], MAZES[1 - branch]
    return Candidate(
        stage=2,
        branch=branch,
        mazes=(own,),
        own=(
            MazeResults(own, (True, False, True, True), (0.5, -1.25, 0.75, 1.0), (11, 99, 12, 13)),
        ),
        others=(MazeResults(other, (False,) * 4, (-2.0,) * 4, (50,) * 4),),
        lineage=(0, 1, branch),
        env_steps=1234,
        seconds=2.5,
        converged=branch == 1,
        lineage_steps=5678,
        pictures=(Path(f"/runs/x/branch-{branch}/trajectory.png"),),
    )


def curator(text: str) -> tuple[TerminalCurator, io.StringIO]:
    out = io.StringIO()
    return TerminalCurator(CONTEXT, input=io.StringIO(text), output=out), out


def test_it_is_the_builtin_human_curator() -> None:
    assert isinstance(make_curator("human", CONTEXT), TerminalCurator)


def test_select_shows_every_number_and_re_asks_after_bad_typing() -> None:
    human, out = curator("\nzero\n7\n-1\n 1 \n")
    chosen = human.select([candidate(0), candidate(1)])
    assert chosen.branch == 1
    text = out.getvalue()
    for shown in (
        "M1_5x5_U",
        "M2_6x6_C1",
        "reached yes no  yes yes",
        "+0.50 -1.25 +0.75 +1.00",
        "11 99 12 13",
        "success 0.00, R̄ -2.000",  # on the other branch's maze
        "lineage [0, 1, 0]",
        "1234 steps",
        "5678 with its lineage",
        "not converged",
        "converged",
        "/runs/x/branch-1/trajectory.png",
    ):
        assert shown in text, shown
    assert text.count("is not one of the branches") == 4


def test_generate_validates_each_maze_and_takes_suggestions_on_empty_lines() -> None:
    history = History(stage=2, parent=candidate(0), stages=())
    human, out = curator("M1_3x0\nhello world\nM9_7x7_C1_l.5_L.25\n\n")
    mazes = human.generate(2, history)
    assert mazes[0] == MazeSpec.from_string("M9_7x7_C1_l.5_L.25").to_string()
    suggestion = MazeSpec.from_string(mazes[1])
    assert suggestion.where(seed=1) == MazeSpec.from_string(MAZES[0])  # the parent, new seed
    assert suggestion.seed != 1
    text = out.getvalue()
    assert "parent's maze: M1_5x5_U" in text and PAPER_TRAINING_MAZE.split("_")[1] in text
    assert text.count("bad maze") == 2
    assert f"[empty: {mazes[1]}]" in text
    # the same stage suggests the same mazes (a resumed run sees the same questions)
    again, _ = curator("\n\n")
    assert again.generate(2, history)[1] == mazes[1]


@pytest.mark.parametrize("text", ["", "x\n", "9\n"])
def test_the_end_of_input_in_select_raises_a_clear_error(text: str) -> None:
    human, _ = curator(text)
    with pytest.raises(CuratorError, match=r"input ended.*resume"):
        human.select([candidate(0), candidate(1)])


@pytest.mark.parametrize("text", ["", "M1_5x5_U\n", "M1_5x5_U\nbad maze\n"])
def test_the_end_of_input_in_generate_raises_a_clear_error(text: str) -> None:
    human, _ = curator(text)
    with pytest.raises(CuratorError, match=r"input ended.*resume"):
        human.generate(2, History(stage=1, parent=candidate(0), stages=()))
