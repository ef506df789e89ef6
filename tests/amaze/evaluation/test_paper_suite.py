"""The paper's evaluation suite: its construction against the script's text, the shipped file."""

from __future__ import annotations

import json
import math
from collections import defaultdict

import numpy as np
import pytest

from amaze.curriculum.validation import reserved_seeds
from amaze.errors import AmazeError
from amaze.evaluation.paper_suite import (
    PAPER_FAMILIES,
    PAPER_SAMPLE_SIZE,
    PAPER_SEED_OFFSET,
    build_paper_suite,
    family_maze,
    nearest_quantiles,
    sample_family,
    script_entropy,
    script_trap_direction,
    trap_columns,
)
from amaze.evaluation.suite import ROWS, EvaluationSuite, PaperSuite, paper_suite
from amaze.maze.directions import OFFSETS, Direction
from amaze.maze.maze import Maze, MazeClass
from amaze.maze.metrics import surprisingness
from amaze.maze.spec import MazeSpec
from tests.run_folders import load_tool

#: The 18 mazes of the paper's evaluation script (eval.py at kgd-al/amaze c4feded).
PAPER_MAZES = (
    ("trivial", "M1007944_20x20_U", "M1003591_20x20_U", "M1005871_20x20_U"),
    ("simple", "M1007944_20x20_C1", "M1006802_20x20_C1", "M1007277_20x20_C1"),
    ("lures", "M1007944_20x20_C1_l.25_L.25", "M1009511_20x20_C1_l.25_L.25",
     "M1000996_20x20_C1_l.25_L.25"),
    ("1 trap", "M1003473_20x20_C1_l.25_L.25_t.5_T.5", "M1000515_20x20_C1_l.25_L.25_t.5_T.5",
     "M1009035_20x20_C1_l.25_L.25_t.5_T.5"),
    ("3 traps", "M1004434_20x20_C1_l.25_L.25_t.5_T.5", "M1003742_20x20_C1_l.25_L.25_t.5_T.5",
     "M1008201_20x20_C1_l.25_L.25_t.5_T.5"),
    ("16 traps", "M1004997_20x20_C1_l.25_L.25_t.5_T.5", "M1002731_20x20_C1_l.25_L.25_t.5_T.5",
     "M1000996_20x20_C1_l.25_L.25_t.5_T.5"),
)  # fmt: skip


# -- the script, transcribed ----------------------------------------------------------------------
# A plain reading of eval.py's _generate_mazes and of _maze_complexity.py at c4feded: tuples of
# floats counted in a dict, the trap direction loop of Maze.generate, the selection with lists.


def _script_visuals(maze: Maze) -> dict:
    visuals = {}
    for placed in (*maze.clues, *maze.lures):
        visuals[placed.cell] = (placed.sign.value, placed.direction)
    for trap in maze.traps:  # c4feded's Maze.generate: the first side that is allowed
        pos, new_d = trap.cell, None
        for d_ in Direction:
            if trap.truth == d_:
                continue
            if maze.walls[pos][d_]:
                continue
            if maze.solution[trap.solution_index - 1] == tuple(
                sum(t) for t in zip(pos, OFFSETS[d_], strict=True)
            ):
                continue
            new_d = d_
            break
        visuals[pos] = (trap.sign.value, new_d)
    return visuals


def _script_entropy(maze: Maze) -> float:
    visuals = _script_visuals(maze)
    inputs = defaultdict(lambda: 0)
    for j, (c, r) in enumerate(maze.solution):
        i = np.zeros(8)
        i[:4] = [maze.walls[c, r, d] for d in Direction]
        if (c, r) in visuals:
            value, direction = visuals[c, r]
            i[4 + direction.value] = value
        if j > 0:
            c0_i, c0_j = maze.solution[j - 1]
            i[OFFSETS.index((c0_i - c, c0_j - r))] = 0.5
        inputs[tuple(i)] += 1
    entropy = 0
    total_states = sum(inputs.values())
    for n in inputs.values():
        p = n / total_states
        entropy += -p * math.log(p)
    return entropy


def _script_suite(seeds: int) -> list[str]:
    levels = [("U", "Trivial"), ("C1", "Simple"), ("C1_l.25_L.25", "Lures"),
              ("C1_l.25_L.25_t.5_T.5", "Traps")]  # fmt: skip

    def make_maze(lvl, seed):
        return f"M{seed + 1_000_000}_20x20_{lvl}"

    df: dict[str, list[float]] = {name: [] for _, name in levels}
    traps: list[int] = []
    for level, name in levels:
        for j in range(seeds):
            maze = Maze.from_string(make_maze(level, j))
            if maze.spec.p_trap:
                traps.append(len(maze.traps))
            df[name].append(_script_entropy(maze))

    def arg_quantiles(data):
        data = np.array(data)
        quantiles = np.quantile(data, [0, 0.5, 1])
        return [(np.abs(data - v)).argmin() for v in quantiles]

    mazes = []
    for (level, _), column in zip(levels[:3], list(df)[:3], strict=True):
        mazes += [make_maze(level, j) for j in arg_quantiles(df[column])]
    traps_ms = defaultdict(list)
    for i, t in enumerate(traps):
        traps_ms[t].append(i)
    traps_filtered_ms = {t: v for t, v in traps_ms.items() if len(v) >= 3 and t > 0}
    traps_filtered = [(t, df["Traps"][j], j) for t, v in traps_filtered_ms.items() for j in v]
    table = np.array([[t, c] for t, c, _ in traps_filtered])
    for ft in np.quantile(table, [0, 0.5, 1]):
        t = round(ft)
        t_mazes = [(c, j) for tt, c, j in traps_filtered if tt == t]
        for k in arg_quantiles([c for c, _ in t_mazes]):
            mazes.append(make_maze(levels[-1][0], t_mazes[k][1]))
    return mazes


# -- the construction -----------------------------------------------------------------------------


@pytest.mark.parametrize("seeds", [200, 131])
def test_construction_is_the_scripts_on_a_sample(seeds):
    suite = build_paper_suite(seeds)
    assert [m.string for m in suite.mazes] == _script_suite(seeds)
    assert suite.sample_size == seeds and len(suite) == 18
    assert [m.row for m in suite.mazes] == list(ROWS) * 6


def test_script_entropy_is_the_scripts_bit_for_bit():
    strings = [family_maze(family, j) for _, family in PAPER_FAMILIES for j in range(60)]
    strings += [m.string for m in paper_suite().mazes]
    for string in strings:
        maze = Maze.from_string(string)
        assert script_entropy(maze) == _script_entropy(maze)
        # The project's Surprisingness in bits, but for the unit and the traps at four-way
        # crossings (see the next test).
        if not any(t.reference_undefined for t in maze.traps):
            assert script_entropy(maze) == pytest.approx(surprisingness(maze) * math.log(2))


def test_traps_at_four_way_crossings_point_as_at_c4feded():
    differ = []
    for j in range(400):
        maze = Maze.from_string(family_maze(PAPER_FAMILIES[-1][1], j))
        for trap in maze.traps:
            direction = script_trap_direction(maze, trap)
            assert direction == _script_visuals(maze)[trap.cell][1]
            if not trap.reference_undefined:
                assert direction == trap.direction  # the only side left: 1.0 agrees
            elif direction != trap.direction:
                differ.append(maze)
    assert differ  # the sample has traps where c4feded and 1.0 differ
    # A trap's direction changes the score only when its input then equals another cell's:
    # in the family's 10,000 samples, for these two mazes.
    for j in (9349, 9998):
        maze = Maze.from_string(family_maze(PAPER_FAMILIES[-1][1], j))
        assert script_entropy(maze) == _script_entropy(maze)
        assert script_entropy(maze) != pytest.approx(surprisingness(maze) * math.log(2))


def test_nearest_quantiles_take_the_first_of_equally_near_scores():
    assert nearest_quantiles([3.0, 1.0, 2.0, 1.0, 3.0]) == [1, 2, 0]
    assert nearest_quantiles([2.0, 1.0, 4.0, 3.0]) == [1, 0, 2]  # median 2.5: 2 and 3 tie
    with pytest.raises(AmazeError, match="no score"):
        nearest_quantiles([])


def test_trap_columns_pool_counts_and_scores():
    # Counts 1 and 2 (three mazes each) are kept, 5 (two mazes) and 0 are not. The pooled
    # sample is {1, 1, 1, 2, 2, 2} and the six scores: its quantiles 0.3, 1.65, 2 round to
    # 0 traps, which no maze has.
    traps = [1, 2, 1, 0, 2, 1, 2, 5, 5]
    scores = [0.9, 1.4, 0.3, 0.1, 1.2, 1.1, 1.9, 0.2, 0.2]
    with pytest.raises(AmazeError, match="rounds to 0 traps"):
        trap_columns(scores, traps)
    scores = [0.9, 1.4, 0.7, 0.1, 1.2, 1.1, 1.9, 0.2, 0.2]  # quantiles 0.7, 1.15, 2
    assert trap_columns(scores, traps) == [(1, [2, 0, 5]), (1, [2, 0, 5]), (2, [4, 1, 6])]
    with pytest.raises(AmazeError, match="common enough"):
        trap_columns([1.0, 2.0], [1, 2])


def test_bad_sample_sizes_are_refused():
    for size in (0, -3, 2.5):
        with pytest.raises(AmazeError, match="sample_size"):
            sample_family(PAPER_FAMILIES[0][1], size)


# -- the shipped suite ----------------------------------------------------------------------------


def test_shipped_suite_is_the_papers():
    suite = paper_suite()
    assert isinstance(suite, PaperSuite) and isinstance(suite, EvaluationSuite)
    assert suite.sample_size == PAPER_SAMPLE_SIZE == 10_000
    assert suite.seed_offset == PAPER_SEED_OFFSET == 1_000_000
    assert suite.families == PAPER_FAMILIES
    assert [(m.column, m.row, m.string) for m in suite.mazes] == [
        (column, row, string) for column, *strings in PAPER_MAZES
        for row, string in zip(ROWS, strings, strict=True)
    ]  # fmt: skip
    assert len(suite.maze_strings()) == 72 and len(set(suite.maze_strings())) == 72
    assert PaperSuite.from_dict(json.loads(json.dumps(suite.to_dict()))) == suite


@pytest.mark.parametrize("column", [c for c, *_ in PAPER_MAZES])
def test_shipped_mazes_have_their_recorded_scores(column):
    entries = [m for m in paper_suite().mazes if m.column == column]
    expected_class = {"trivial": MazeClass.TRIVIAL, "simple": MazeClass.SIMPLE,
                      "lures": MazeClass.LURES}.get(column, MazeClass.COMPLEX)  # fmt: skip
    for entry in entries:
        maze = Maze.from_string(entry.string)
        assert maze.maze_class is expected_class
        assert script_entropy(maze) == entry.script_entropy
        assert surprisingness(maze) == pytest.approx(entry.surprisingness, abs=1e-12)
        assert len(maze.traps) == entry.traps
        if entry.traps:
            assert column == f"{entry.traps} trap{'s' if entry.traps > 1 else ''}"
        # Played in every rotation, no trap of these mazes depends on the hash order of 1.0
        # or on the commit: the mazes played are those the script played.
        for rotated in entry.rotations():
            assert not any(t.reference_undefined for t in Maze.from_string(rotated).traps)
    scores = [m.script_entropy for m in entries]
    assert scores[0] <= scores[1] <= scores[2]


@pytest.mark.slow
@pytest.mark.parametrize("name, family", PAPER_FAMILIES[:3], ids=[n for n, _ in PAPER_FAMILIES[:3]])
def test_plain_columns_regenerate_at_full_size(name, family):
    scores, _ = sample_family(family)
    rows = [family_maze(family, j) for j in nearest_quantiles(scores)]
    assert rows == [m.string for m in paper_suite().mazes if m.column == name]


@pytest.mark.slow
def test_trap_columns_regenerate_at_full_size():
    scores, traps = sample_family(PAPER_FAMILIES[-1][1])
    columns = trap_columns(scores, traps)
    assert [t for t, _ in columns] == [1, 3, 16]
    shipped = [m.string for m in paper_suite().mazes if m.traps]
    assert [family_maze(PAPER_FAMILIES[-1][1], j) for _, rows in columns for j in rows] == shipped


def test_the_tool_writes_what_the_construction_builds(tmp_path):
    output = tmp_path / "paper_suite.json"
    load_tool("make_paper_suite").main(
        ["--sample-size", "90", "--workers", "1", "--output", str(output)]
    )
    written = PaperSuite.from_dict(json.loads(output.read_text(encoding="utf-8")))
    assert written == build_paper_suite(90)
    assert [m.string for m in written.mazes] == _script_suite(90)


def test_bad_descriptions_are_refused():
    with pytest.raises(AmazeError, match="paper suite"):
        PaperSuite.from_dict({"mazes": [], "sample_size": 3})


def test_validation_mazes_never_take_the_papers_seeds():
    seeds = {MazeSpec.from_string(m).seed for m in paper_suite().maze_strings(rotations=False)}
    assert len(seeds) == 15 and seeds <= reserved_seeds()  # M1007944 thrice, M1000996 twice
