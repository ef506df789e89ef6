"""The standard evaluation suite: its definition, the shipped file, determinism."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from amaze.errors import AmazeError
from amaze.evaluation.suite import (
    COLUMNS,
    PAPER_EVALUATION_MAZE,
    PAPER_TRAINING_MAZE,
    ROWS,
    SAMPLE_SIZE,
    EvaluationSuite,
    build_suite,
    sample_column,
    select_rows,
    standard_suite,
)
from amaze.maze.maze import Maze, MazeClass
from amaze.maze.metrics import surprisingness
from amaze.maze.signs import SignKind
from amaze.maze.spec import MazeSpec


def test_shipped_suite_has_the_papers_shape():
    suite = standard_suite()
    assert suite.sample_size == SAMPLE_SIZE == 10000
    assert len(suite) == 18
    assert [m.column for m in suite.mazes] == [c.name for c in COLUMNS for _ in ROWS]
    assert [m.row for m in suite.mazes] == list(ROWS) * len(COLUMNS)
    assert len(suite.maze_strings()) == 72
    assert len(set(suite.maze_strings())) == 72
    assert len(suite.maze_strings(rotations=False)) == 18


@pytest.mark.parametrize("column", COLUMNS, ids=lambda c: c.name)
def test_shipped_mazes_belong_to_their_column(column):
    expected_class = {
        "trivial": MazeClass.TRIVIAL,
        "simple": MazeClass.SIMPLE,
        "lures": MazeClass.LURES,
    }.get(column.name, MazeClass.COMPLEX)
    rows = [m for m in standard_suite().mazes if m.column == column.name]
    scores = []
    for entry in rows:
        maze = Maze.from_string(entry.string)
        assert entry.string.split("_", 1)[1] == column.family
        assert maze.maze_class is expected_class
        assert surprisingness(maze) == pytest.approx(entry.surprisingness, abs=1e-12)
        traps = sum(1 for p in maze.signs if p.kind is SignKind.TRAP)
        if column.traps is not None:
            assert traps == column.traps
        scores.append(entry.surprisingness)
        # The four rotations are the same maze started from each corner: same S.
        rotations = [Maze.from_string(s) for s in entry.rotations()]
        assert sorted(MazeSpec.from_string(s).start.shorthand for s in entry.rotations()) == [
            "NE", "NW", "SE", "SW"
        ]  # fmt: skip
        for rotated in rotations:
            assert surprisingness(rotated) == pytest.approx(entry.surprisingness, abs=1e-9)
    assert scores[0] <= scores[1] <= scores[2]
    assert scores[0] < scores[2]


def test_one_column_regenerates_exactly_at_full_size():
    """Rebuilding the 'simple' column from its definition gives the shipped rows."""
    column = next(c for c in COLUMNS if c.name == "simple")
    sample = sample_column(column, SAMPLE_SIZE)
    assert len(sample) == SAMPLE_SIZE
    assert len({seed for seed, _ in sample}) == SAMPLE_SIZE
    shipped = [m for m in standard_suite().mazes if m.column == "simple"]
    assert select_rows(column, sample) == shipped


def test_trap_columns_keep_only_mazes_with_that_many_traps():
    column = next(c for c in COLUMNS if c.name == "3 traps")
    sample = sample_column(column, 40)
    for seed, score in sample:
        maze = Maze.from_string(column.maze_string(seed))
        assert sum(1 for p in maze.signs if p.kind is SignKind.TRAP) == 3
        assert surprisingness(maze) == score


def test_rows_are_min_median_max_with_ties_broken_by_seed():
    column = COLUMNS[0]
    sample = [(5, 2.0), (3, 2.0), (9, 4.0), (1, 3.0), (7, 3.0)]
    rows = select_rows(column, sample)
    assert [m.string for m in rows] == ["M3_20x20_U", "M1_20x20_U", "M9_20x20_U"]
    assert [m.row for m in rows] == list(ROWS)


@pytest.mark.slow
def test_small_suite_is_deterministic_across_processes():
    code = (
        "import json; from amaze.evaluation.suite import build_suite;"
        " print(json.dumps(build_suite(30).to_dict()))"
    )
    outputs = [
        subprocess.run(
            [sys.executable, "-c", code],
            capture_output=True,
            text=True,
            check=True,
            env={"PYTHONHASHSEED": str(hash_seed), "PATH": ""},
        ).stdout
        for hash_seed in (0, 1)
    ]
    assert outputs[0] == outputs[1]
    assert EvaluationSuite.from_dict(json.loads(outputs[0])) == build_suite(30)


def test_bad_inputs_are_refused():
    with pytest.raises(AmazeError, match="sample_size"):
        sample_column(COLUMNS[0], 0)
    with pytest.raises(AmazeError, match="suite"):
        EvaluationSuite.from_dict({"mazes": [{"column": "x"}]})


def test_paper_pair_are_complex_20x20_mazes_of_one_family():
    train, test = Maze.from_string(PAPER_TRAINING_MAZE), Maze.from_string(PAPER_EVALUATION_MAZE)
    assert train.maze_class is test.maze_class is MazeClass.COMPLEX
    assert PAPER_TRAINING_MAZE.split("_", 1)[1] == PAPER_EVALUATION_MAZE.split("_", 1)[1]
    assert train != test
