"""Maze complexity metrics: golden values of the reference library, and properties."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from collections import Counter, defaultdict
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from amaze.maze import rotations
from amaze.maze.directions import direction_between
from amaze.maze.maze import Maze
from amaze.maze.metrics import (
    MazeMetrics,
    compute_metrics,
    deceptiveness,
    inseparability,
    invariant_deceptiveness,
    mutual_information,
    surprisingness,
)
from amaze.maze.spec import MazeSpec, StartLocation
from tests.amaze.conftest import load_reference

TOLERANCE = 1e-9
PROPERTIES = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])

REFERENCE_MAZES = load_reference()["mazes"]
ROTATION_CASES = [
    (entry["input"], rotation["build_data_start"], rotation)
    for entry in REFERENCE_MAZES
    for rotation in entry["all_rotations"]
]


def assert_reference_metrics(got: MazeMetrics, expected: dict[str, Any]) -> None:
    """Compare with the reference's ``Simulation.compute_metrics`` output."""
    actual = got.to_reference_dict()
    assert actual.keys() == expected.keys()
    for key, value in expected.items():
        if isinstance(value, dict):
            assert actual[key].keys() == value.keys()
            for sub, sub_value in value.items():
                assert actual[key][sub] == pytest.approx(sub_value, abs=TOLERANCE), (key, sub)
        else:
            assert actual[key] == pytest.approx(value, abs=TOLERANCE), key


def rotated_mazes(maze: Maze) -> list[Maze]:
    """The maze started from each corner (NW, NE, SW, SE), generated."""
    return [Maze.from_string(text) for text in rotations(maze)]


def reference_rotation(maze: Maze, start: StartLocation) -> Maze:
    """The maze the reference's ``Maze.all_rotations()`` builds for ``start``.

    The reference rebuilds its spec from the generated maze, whose width and
    height are swapped for SE/NW starts; for such a maze (``M4_10x5_SE_C1``) its
    rotations are those of a different base maze. The fixture's ``to_string`` of
    the rotations is not reliable for the same reason, so the start is used.
    """
    return Maze.generate(maze.spec.where(width=maze.width, height=maze.height, start=start))


# -- golden data ---------------------------------------------------------------


@pytest.mark.parametrize("entry", REFERENCE_MAZES, ids=[e["input"] for e in REFERENCE_MAZES])
def test_reference_metrics(entry):
    maze = Maze.from_string(entry["input"])
    assert (maze.width, maze.height) == (entry["width"], entry["height"])
    metrics = compute_metrics(maze)
    assert_reference_metrics(metrics, entry["metrics"])
    # The single-metric functions give the same numbers.
    assert surprisingness(maze) == metrics.surprisingness
    assert surprisingness(maze, "all") == metrics.surprisingness_all
    assert deceptiveness(maze) == metrics.deceptiveness
    assert invariant_deceptiveness(maze) == metrics.invariant_deceptiveness
    assert inseparability(maze) == metrics.inseparability == inseparability(maze.spec)
    assert mutual_information(maze) == metrics.mutual_information
    assert mutual_information(maze.spec) == metrics.mutual_information


@pytest.mark.parametrize(
    ("text", "start", "rotation"),
    ROTATION_CASES,
    ids=[f"{text}-{start}" for text, start, _ in ROTATION_CASES],
)
def test_reference_rotation_metrics(text, start, rotation):
    maze = reference_rotation(Maze.from_string(text), StartLocation[start])
    assert (maze.width, maze.height) == (rotation["width"], rotation["height"])
    assert maze.path_length == rotation["path_length"]
    assert_reference_metrics(compute_metrics(maze), rotation["metrics"])


@pytest.mark.parametrize("entry", REFERENCE_MAZES, ids=[e["input"] for e in REFERENCE_MAZES])
def test_all_rotations_order_and_invariance(entry):
    maze = Maze.from_string(entry["input"])
    rotated = rotated_mazes(maze)
    starts = [StartLocation[r["build_data_start"]] for r in entry["all_rotations"]]
    assert [r.spec.start for r in rotated] == starts
    swapped = maze.width != maze.spec.width
    if not swapped:  # same base maze as the reference: its numbers, rotation by rotation
        for rotation, expected in zip(rotated, entry["all_rotations"], strict=True):
            assert_reference_metrics(compute_metrics(rotation), expected["metrics"])
    if not maze.spec.rotated:  # R: each start generates a different maze
        return
    # Surprisingness and the paper's deceptiveness do not depend on the orientation.
    values = [compute_metrics(r) for r in (maze, *rotated)]
    for field in ("surprisingness", "surprisingness_all", "invariant_deceptiveness"):
        first = getattr(values[0], field)
        assert all(getattr(v, field) == pytest.approx(first, abs=1e-12) for v in values), field


def test_reference_deceptiveness_depends_on_orientation():
    entry = next(e for e in REFERENCE_MAZES if e["input"].startswith("M20000018_"))
    published = [r["metrics"]["deceptiveness"] for r in entry["all_rotations"]]
    ours = [deceptiveness(r) for r in rotated_mazes(Maze.from_string(entry["input"]))]
    assert ours == pytest.approx(published, abs=TOLERANCE)
    assert len({round(value, 6) for value in ours}) == 4  # NW/NE/SW/SE all differ
    assert [round(v, 4) for v in ours] == [1.6927, 1.6985, 1.6855, 1.6716]


def test_published_table():
    """The values of docs/reference-behaviour.md §3.10 (rounded to 4 decimals)."""
    table = {
        "M4_10x10_C1": (3.2366, 4.5488, 0.0),
        "M16_5x10_U": (3.1219, 3.7469, 0.0),
        "M20000018_20x20_C1_l.25_L.25_t.5_T.5": (4.5368, 4.7909, 1.6855),
        "M2000018_20x20_C1_l.25_L.25_t.5_T.5": (4.5970, 4.7911, 0.8593),
        "M2000007_20x20_C1_l.25_L.25_t.5_T.5": (4.5813, 4.8646, 1.5013),
        "M0_20x20_C1_l.2_L.25_t.5_T.5": (4.8367, 5.2856, 3.6016),
        "M10_10x10_C1_l.2_L.25_t.5_T.5": (4.4999, 5.1020, 1.5065),
    }
    for text, expected in table.items():
        m = compute_metrics(Maze.from_string(text))
        got = (m.surprisingness, m.surprisingness_all, m.deceptiveness)
        assert tuple(round(v, 4) for v in got) == expected, text


@pytest.mark.parametrize("entry", REFERENCE_MAZES, ids=[e["input"] for e in REFERENCE_MAZES])
def test_invariant_deceptiveness_needs_lures_or_traps(entry):
    maze = Maze.from_string(entry["input"])
    value = invariant_deceptiveness(maze)
    if maze.lures or maze.traps:
        assert value > 0
    else:
        assert value == 0


# -- sign metrics ----------------------------------------------------------------


def test_inseparability_example():
    spec = MazeSpec.from_string("M1_C1_l.25_L.25_t.5_T.5")
    # Ranges [0, .375] lure, [.375, .75] trap, [.75, 1] clue.
    expected = -2 * 0.375 * math.log2(0.375) - 0.25 * math.log2(0.25)
    assert inseparability(spec) == pytest.approx(expected, abs=1e-15)
    assert round(inseparability(spec), 4) == 1.5613


def test_mutual_information_example():
    spec = MazeSpec.from_string("M1_C1_t.5_T.5")
    # P(x) = 1/2, P(trap) = .75, P(clue) = .25.
    expected = math.log2(1 / (0.5 * 0.75)) + math.log2(1 / (0.5 * 0.25))
    assert mutual_information(spec) == pytest.approx(expected, abs=1e-15)
    assert round(mutual_information(spec), 3) == 4.415
    assert mutual_information(spec) > 1  # not a true mutual information


def test_sign_metrics_follow_probabilities():
    # Without a probability, the lure or trap types do not exist (and are not counted).
    assert inseparability(MazeSpec.from_string("M1_C1")) == 0
    assert mutual_information(MazeSpec.from_string("M1_C1")) == 0
    assert mutual_information(MazeSpec.from_string("M1_5x5")) == 0
    assert inseparability(MazeSpec.from_string("M1_5x5")) == 0
    lures = MazeSpec.from_string("M1_C1_l.5_L.25")
    assert inseparability(lures) == pytest.approx(
        -0.625 * math.log2(0.625) - 0.375 * math.log2(0.375)
    )
    # Lures do not enter the mutual information.
    assert mutual_information(lures) == 0
    # A trap overrides a clue of the same value.
    spec = MazeSpec.from_string("M1_C.5_t1_T.5")
    assert mutual_information(spec) == pytest.approx(0.0, abs=1e-15)


# -- API -------------------------------------------------------------------------


def test_unknown_variant():
    maze = Maze.from_string("M4_5x5_C1")
    with pytest.raises(ValueError, match="'cells'"):
        surprisingness(maze, "cells")  # type: ignore[arg-type]


def test_maze_metrics_record():
    metrics = compute_metrics(Maze.from_string("M10_10x10_C1_l.2_L.25_t.5_T.5"))
    with pytest.raises(dataclasses.FrozenInstanceError):
        metrics.deceptiveness = 0.0  # type: ignore[misc]
    data = metrics.to_dict()
    assert list(data) == [
        "surprisingness",
        "surprisingness_all",
        "deceptiveness",
        "invariant_deceptiveness",
        "inseparability",
        "mutual_information",
        "n_inputs_path",
        "n_inputs_all",
    ]
    assert data["n_inputs_path"] == 59 and data["n_inputs_all"] == 199
    assert MazeMetrics(**data) == metrics


def test_sign_values_missing_from_the_spec():
    """A hand-made maze whose signs are not listed in its spec is still measured."""
    maze = Maze.from_string("M10_10x10_C1_l.2_L.25_t.5_T.5")
    bare = Maze(
        MazeSpec(maze.width, maze.height, seed=maze.spec.seed),
        maze.walls,
        maze.start,
        maze.end,
        list(maze.solution),
        list(maze.intersections),
        list(maze.clues),
        list(maze.lures),
        list(maze.traps),
    )
    ours, theirs = compute_metrics(maze), compute_metrics(bare)
    for field in ("surprisingness", "surprisingness_all", "deceptiveness"):
        assert getattr(theirs, field) == pytest.approx(getattr(ours, field), abs=1e-12)
    assert theirs.invariant_deceptiveness == pytest.approx(ours.invariant_deceptiveness, abs=1e-12)
    assert theirs.inseparability == 0 and theirs.mutual_information == 0


def test_import_is_light():
    code = (
        "import sys, amaze\n"
        "before = set(sys.modules)\n"
        "import amaze.maze.metrics\n"
        "heavy = {'torch', 'pandas', 'PyQt5', 'numba', 'matplotlib'}\n"
        "new = {m.split('.')[0] for m in set(sys.modules) - before} & heavy\n"
        "assert not new, new\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


# -- properties --------------------------------------------------------------------


def naive_metrics(maze: Maze) -> dict[str, float]:
    """A direct, per-cell transcription of docs/reference-behaviour.md §6 and of the paper's D."""
    values, directions = maze.cell_signs.value, maze.cell_signs.direction

    def inputs(cell):
        vector = [float(w) for w in maze.walls[cell]] + [0.0] * 4
        if directions[cell] >= 0:
            vector[4 + directions[cell]] = float(values[cell])
        return vector

    def entropy(counter):
        total = sum(counter.values())
        return -sum(n / total * math.log2(n / total) for n in counter.values())

    every = Counter([tuple(inputs(maze.start))])
    cells = maze.solution if maze.unicursive else all_cells(maze)
    for cell in cells:
        vector = inputs(cell)
        for side in range(4):
            if not vector[side]:
                every[(*vector[:side], 0.5, *vector[side + 1 :])] += 1

    states, costs, truths = [], [], []
    for k, cell in enumerate(maze.solution):
        vector = inputs(cell)
        if k:
            vector[direction_between(cell, maze.solution[k - 1])] = 0.5
        exit_ = direction_between(cell, maze.solution[k + 1]) if k + 1 < maze.path_length else None
        pointed = max(range(4), key=lambda d: (vector[4 + d], -d))  # argmax: first maximum
        costs.append(exit_ != pointed)
        truths.append(directions[cell] >= 0 and directions[cell] != exit_)
        states.append(tuple(vector))

    def conditional(cost):
        by_walls, by_state, costly = Counter(), Counter(), set()
        for state, c in zip(states, cost, strict=True):
            by_walls[state[:4]] += 1
            by_state[state] += 1
            if c:
                costly.add(state)
        terms = defaultdict(float)
        for state in costly:
            p = by_state[state] / by_walls[state[:4]]
            terms[sum(v == 1 for v in state[:4]) <= 1] += -p * math.log2(p)
        return terms

    length = maze.path_length
    n_inter = sum(sum(v == 1 for v in s[:4]) <= 1 for s in states)
    reference = conditional(costs)
    paper = conditional(truths)
    return {
        "surprisingness": entropy(Counter(states)),
        "surprisingness_all": entropy(every),
        "n_inputs_all": sum(every.values()),
        "deceptiveness": (n_inter * reference[False] + (length - n_inter) * reference[True])
        / length,
        "invariant_deceptiveness": paper[True] + paper[False],
    }


def all_cells(maze: Maze):
    return [(i, j) for i in range(maze.width) for j in range(maze.height)]


probabilities = st.sampled_from(["0", ".1", ".25", ".5", "1"])


@st.composite
def maze_strings(draw) -> str:
    seed = draw(st.integers(0, 10**6))
    width, height = draw(st.integers(2, 9)), draw(st.integers(2, 9))
    p_lure, p_trap = draw(probabilities), draw(probabilities)
    extra = draw(st.sampled_from(["", "_C.75", "_Lwarning-.3_T.9", "_U", "_C.5"]))
    return f"M{seed}_{width}x{height}_C1_l{p_lure}_L.25_t{p_trap}_T.5{extra}"


@PROPERTIES
@given(maze_strings(), st.sampled_from(list(StartLocation)))
def test_orientation_invariance(text, start):
    maze = Maze.from_string(text, start=start)
    reference = compute_metrics(maze)
    for rotation in rotated_mazes(maze):
        metrics = compute_metrics(rotation)
        assert metrics.surprisingness == pytest.approx(reference.surprisingness, abs=1e-12)
        assert metrics.surprisingness_all == pytest.approx(reference.surprisingness_all, abs=1e-12)
        assert metrics.invariant_deceptiveness == pytest.approx(
            reference.invariant_deceptiveness, abs=1e-12
        )
        assert metrics.n_inputs_path == reference.n_inputs_path
        assert metrics.n_inputs_all == reference.n_inputs_all


@PROPERTIES
@given(maze_strings(), st.sampled_from(list(StartLocation)), st.booleans())
def test_bounds_and_counts(text, start, rotated):
    maze = Maze.from_string(text, start=start, rotated=rotated)
    metrics = compute_metrics(maze)
    assert metrics.surprisingness >= 0 and metrics.surprisingness_all >= 0
    assert metrics.deceptiveness >= 0 and metrics.invariant_deceptiveness >= 0
    assert metrics.surprisingness <= math.log2(metrics.n_inputs_path) + 1e-12
    assert metrics.n_inputs_path == maze.path_length == len(maze.solution)
    assert 0 < metrics.n_inputs_all <= 3 * maze.width * maze.height
    if not maze.lures and not maze.traps:
        assert metrics.invariant_deceptiveness == 0


@PROPERTIES
@given(maze_strings(), st.sampled_from(list(StartLocation)), st.booleans())
def test_matches_a_naive_transcription(text, start, rotated):
    maze = Maze.from_string(text, start=start, rotated=rotated)
    metrics = compute_metrics(maze).to_dict()
    for key, value in naive_metrics(maze).items():
        assert metrics[key] == pytest.approx(value, abs=1e-12), key
