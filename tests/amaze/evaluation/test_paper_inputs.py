"""Input recognition as the paper's evaluation script computed it, beside the project's figure."""

from __future__ import annotations

import json

import numpy as np
import pytest

from amaze.evaluation.controllers import OracleController, RandomController
from amaze.evaluation.inputs import (
    PAPER_INPUT_SIGNS,
    InputClass,
    InputType,
    enumerate_inputs,
    evaluate_inputs,
    inputs_for_maze,
    paper_input_set,
)
from amaze.evaluation.protocol import INPUT_SIGNS_MAZE, Evaluator
from amaze.maze.directions import OFFSETS
from amaze.maze.signs import SignKind
from amaze.maze.spec import MazeSpec

# -- eval.py's generate_inputs and evaluate_inputs, transcribed (as of commit 6cb352f) ------------


def _script_inputs() -> list[tuple[np.ndarray, tuple[int, int], str | None]]:
    inputs = []

    def array():
        return np.zeros(8)

    def i_to_dir(i_):
        return OFFSETS[i_]

    for i in range(4):  # the dead ends
        a = array()
        a[:4] = 1
        a[i] = 0
        inputs.append((a, i_to_dir(i), None))
        a = a.copy()
        a[i] = 0.5
        inputs.append((a, i_to_dir(i), None))
    for i in range(3):  # the corridors
        for j in range(i + 1, 4):
            dirs = set(range(4)) - {i, j}
            for d in dirs:
                a = array()
                a[i] = 1
                a[j] = 1
                a[d] = 0.5
                i_sol = next(iter(dirs - {d}))
                sol = i_to_dir(i_sol)
                inputs.append((a, sol, None))
                for lure in iter(set(range(4)) - {i_sol}):
                    a_ = array()
                    a_[:] = a[:]
                    a_[4:] = 0
                    a_[lure + 4] = 0.25
                    inputs.append((a_, sol, "Lure"))
    for i in range(4):  # the intersections
        for j in iter(set(range(4)) - {i}):
            for k in iter(set(range(4)) - {i}):
                a = array()
                a[i] = 1
                a[k] = 0.5
                a[j + 4] = 1
                inputs.append((a, i_to_dir(j), "Clue"))
                if j != k:
                    a = a.copy()
                    a[j + 4] = 0.5
                    i_sol = next(iter(set(range(4)) - {i, j, k}))
                    inputs.append((a, i_to_dir(i_sol), "Trap"))
    return inputs


def _script_all(controller) -> float:
    counts = {k: [0, 0] for k in [None, "Clue", "Lure", "Trap"]}
    for i, a, t in _script_inputs():
        a_ = OFFSETS[int(controller(i[None, :].astype(np.float32))[0])]
        counts[t][0] += int(a_ == a)
        counts[t][1] += 1
    data = {"Empty" if k is None else k: v[0] / v[1] for k, v in counts.items()}
    return np.average(list(data.values()))


def full_set():
    """The project's set for the paper's signs (one clue, one lure, one trap): 140 inputs."""
    return enumerate_inputs("DD", *([sign] for sign in PAPER_INPUT_SIGNS))


def first_open_side(observations: np.ndarray) -> np.ndarray:
    """A policy that takes the first side (E, N, W, S) without a wall: right in dead ends only."""
    return np.argmax(observations[:, :4] < 1, axis=1).astype(np.int64)


def follow_the_sign(observations: np.ndarray) -> np.ndarray:
    return np.argmax(observations[:, 4:], axis=1).astype(np.int64)


# -- the set and the figure -----------------------------------------------------------------------


def test_paper_set_is_the_scripts():
    paper = paper_input_set("DD")
    script = _script_inputs()
    assert len(paper) == len(script) == 116
    assert np.array_equal(paper.observations, np.array([a for a, _, _ in script], np.float32))
    assert [OFFSETS[d] for d in paper.expected] == [sol for _, sol, _ in script]
    kinds = {None: InputClass.EMPTY, "Lure": InputClass.LURE, "Clue": InputClass.CLUE,
             "Trap": InputClass.TRAP}  # fmt: skip
    assert list(paper.classes) == [kinds[t] for _, _, t in script]
    assert {c.value: n for c, n in paper.totals().items()} == {
        "empty": 20, "lure": 36, "clue": 36, "trap": 24
    }  # fmt: skip
    assert [s.value for s in (*paper.clues, *paper.lures, *paper.traps)] == [
        float(v) for v in PAPER_INPUT_SIGNS
    ]


def test_paper_set_is_the_projects_without_lures_in_dead_ends():
    full = inputs_for_maze(INPUT_SIGNS_MAZE, "H15")
    paper = paper_input_set("H15")  # hybrid robots get the same cases, as images
    rows = [
        k
        for k, case in enumerate(full.cases)
        if not (case.kind is SignKind.LURE and case.input_type is InputType.DEAD_END)
    ]
    assert paper.cases == tuple(full.cases[k] for k in rows) and len(full) - len(paper) == 24
    assert np.array_equal(paper.observations, full.observations[rows])
    assert not paper.observations.flags.writeable


@pytest.mark.parametrize("policy", [first_open_side, follow_the_sign], ids=lambda p: p.__name__)
def test_paper_figure_is_the_scripts_all(policy):
    paper = evaluate_inputs(policy, paper_input_set("DD"))
    full = evaluate_inputs(policy, full_set())
    assert paper.paper_input_recognition == _script_all(policy)
    assert full.paper_input_recognition == paper.paper_input_recognition == paper.class_average
    assert full.paper_rates == paper.rates
    assert full.summary()["paper_input_recognition"] == full.paper_input_recognition


def test_paper_figure_differs_from_the_projects():
    full = evaluate_inputs(first_open_side, full_set())
    # Lures: all 24 in dead ends right, 18 of the 36 in corridors.
    assert full.rates[InputClass.LURE] == pytest.approx(42 / 60)
    assert full.paper_rates[InputClass.LURE] == pytest.approx(18 / 36)
    rates = [full.paper_rates[c] for c in (InputClass.EMPTY, InputClass.CLUE, InputClass.TRAP)]
    assert full.paper_input_recognition == pytest.approx(np.mean([*rates, 0.5]))
    assert full.paper_input_recognition != pytest.approx(full.overall)
    assert full.paper_input_recognition != pytest.approx(full.class_average)


# -- in the evaluation report ---------------------------------------------------------------------


def test_the_report_and_summary_carry_both_figures():
    evaluator = Evaluator("DD", ["M1_5x5_C1"])
    assert [s.value for s in MazeSpec.from_string(INPUT_SIGNS_MAZE).clue] == [1.0]
    report = evaluator.evaluate(first_open_side)
    direct = evaluate_inputs(first_open_side, paper_input_set("DD"))
    assert report.paper_input_recognition == direct.class_average == _script_all(first_open_side)
    assert report.input_recognition == pytest.approx(
        evaluate_inputs(first_open_side, inputs_for_maze(INPUT_SIGNS_MAZE, "DD")).overall
    )
    summary = json.loads(json.dumps(report.summary()))
    assert summary["paper_input_recognition"] == report.paper_input_recognition
    assert summary["input_recognition"] == report.input_recognition
    assert "as the paper scored it" in report.format()
    # A seeded random controller: the same answers, scored both ways.
    random = evaluator.evaluate(RandomController("DD", seed=2))
    signs_set = inputs_for_maze(INPUT_SIGNS_MAZE, "DD")
    answers = evaluate_inputs(RandomController("DD", seed=2), signs_set)
    assert random.paper_input_recognition == answers.paper_input_recognition


def test_no_paper_figure_where_there_is_no_input_recognition():
    report = Evaluator("DD", ["M1_5x5_C1"]).evaluate(OracleController("DD"))
    assert report.input_recognition is report.paper_input_recognition is None
    assert report.summary()["paper_input_recognition"] is None
    assert "as the paper scored it" not in report.format()
    assert Evaluator("DD", ["M1_5x5_C1"], inputs=False).evaluate(first_open_side).summary()[
        "paper_input_recognition"
    ] is None  # fmt: skip
