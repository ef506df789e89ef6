"""``amaze evaluate AGENT paper`` and ``amaze suite --paper``: the paper's evaluation suite."""

from __future__ import annotations

import json

from PIL import Image

from amaze.cli.main import main
from amaze.evaluation.controllers import RandomController
from amaze.evaluation.protocol import Evaluator
from amaze.evaluation.suite import PaperSuite, paper_suite
from amaze.maze.spec import MazeSpec


def run(capsys, *args: str) -> tuple[int, str, str]:
    status = main(list(args))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_evaluate_paper_plays_the_papers_suite(capsys):
    status, out, err = run(capsys, "evaluate", "oracle", "paper", "--json")
    assert status == 0, err
    outcome = json.loads(out)
    assert outcome["episodes"] == 72 and outcome["rotations"] == 4
    canonical = [MazeSpec.from_string(m.string).to_string() for m in paper_suite().mazes]
    assert [m["maze"] for m in outcome["mazes"]] == canonical
    assert outcome["success_rate"] == 1.0
    assert outcome["paper_input_recognition"] is None  # the oracle reads the maze


def test_evaluate_reports_the_papers_input_recognition(capsys):
    status, out, err = run(capsys, "evaluate", "random", "paper", "--seed", "4", "--json")
    assert status == 0, err
    outcome = json.loads(out)
    report = Evaluator("DD", paper_suite().maze_strings(rotations=False), rotations=4).evaluate(
        RandomController("DD", seed=4)
    )
    assert outcome["paper_input_recognition"] == report.paper_input_recognition is not None
    assert outcome["success_rate"] == report.success_rate
    status, out, _ = run(capsys, "evaluate", "random", "paper", "suite", "--seed", "4")
    assert status == 0
    assert out.splitlines()[0] == "random (DD) on 36 mazes, each in its 4 rotations:"
    assert "; as the paper scored it " in out.splitlines()[-1]


def test_suite_lists_renders_and_evaluates_the_papers(capsys, tmp_path):
    status, out, _ = run(capsys, "suite", "--paper")
    lines = out.splitlines()
    assert status == 0 and len(lines) == 19
    assert lines[0].startswith("the paper's evaluation suite: 18 mazes x 4 rotations")
    assert [line.split()[-1] for line in lines[1:]] == [m.string for m in paper_suite().mazes]
    status, out, _ = run(capsys, "suite", "--paper", "--json")
    assert status == 0 and PaperSuite.from_dict(json.loads(out)) == paper_suite()
    png = tmp_path / "paper.png"
    status, out, _ = run(capsys, "suite", "--paper", "--render", str(png))
    assert status == 0 and Image.open(png).size[0] > Image.open(png).size[1]
    status, out, _ = run(capsys, "suite", "--paper", "--evaluate", "oracle")
    assert status == 0
    assert out.splitlines()[0] == "oracle controller on the paper's evaluation suite:"
    assert "16 traps" in out and "success 100.0%" in out
