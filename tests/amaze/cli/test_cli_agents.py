"""The ``amaze`` commands that run agents: run/play, inputs, suite."""

from __future__ import annotations

import csv
import json

import pytest
from PIL import Image

from amaze.cli.main import main
from amaze.evaluation.controllers import train_tabular
from amaze.evaluation.suite import standard_suite


def run_cli(capsys, *args: str) -> tuple[int, str, str]:
    status = main(list(args))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_run_oracle_prints_the_outcome_and_saves_pictures(capsys, tmp_path):
    png, gif = tmp_path / "out" / "t.png", tmp_path / "e.gif"
    status, out, err = run_cli(
        capsys, "run", "M4_10x10_C1", "--controller", "oracle",
        "--trajectory", str(png), "--gif", str(gif),
    )  # fmt: skip
    assert status == 0, err
    assert "success in 28 steps (path length 29), 0 collisions" in out
    assert "R̄ +1.000" in out
    assert Image.open(png).size[0] > 100
    with Image.open(gif) as animation:
        assert animation.is_animated and animation.n_frames == 29


def test_play_is_run_and_json_is_reproducible(capsys):
    args = ("play", "M4_6x6_C1", "--robot", "CC7", "--seed", "5", "--json")
    outcomes = []
    for _ in range(2):
        status, out, err = run_cli(capsys, *args)
        assert status == 0, err
        outcomes.append(json.loads(out))
    assert outcomes[0] == outcomes[1]
    assert outcomes[0]["robot"] == "CC7" and outcomes[0]["controller"] == "random"
    assert outcomes[0]["steps"] > 0
    status, out, _ = run_cli(capsys, "play", "M4_6x6_C1", "--robot", "CC7", "--seed", "6", "--json")
    assert json.loads(out) != outcomes[0]


def test_run_a_saved_tabular_agent(capsys, tmp_path):
    agent = train_tabular(["M4_5x5_C1"], method="q_learning", episodes=30, seed=0)
    path = agent.save(tmp_path / "agent.json")
    status, out, err = run_cli(capsys, "run", "M4_5x5_C1", "--controller", str(path), "--json")
    assert status == 0, err
    assert json.loads(out)["success"] is True


def test_inputs_writes_csv_and_png(capsys, tmp_path):
    status, out, err = run_cli(
        capsys, "inputs", "--controller", "random", "--csv", str(tmp_path / "i.csv"),
        "--png", str(tmp_path / "i.png"),
    )  # fmt: skip
    assert status == 0, err
    assert out.startswith("140 inputs (DD, random):")
    with open(tmp_path / "i.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 140
    assert {"Walls", "Type", "Expected", "Action", "Success"} <= set(rows[0])
    assert Image.open(tmp_path / "i.png").size[1] > 200


def test_suite_lists_renders_and_evaluates(capsys, tmp_path):
    status, out, err = run_cli(capsys, "suite", "--render", str(tmp_path / "s.png"))
    assert status == 0, err
    for maze in standard_suite().mazes:
        assert maze.string in out
    assert Image.open(tmp_path / "s.png").size[0] > 500
    status, out, err = run_cli(capsys, "suite", "--json")
    assert json.loads(out)["sample_size"] == 10000
    status, out, err = run_cli(
        capsys, "suite", "--evaluate", "oracle", "--csv", str(tmp_path / "e.csv")
    )
    assert status == 0, err
    assert "72 episodes (DD): success 100.0%, mean R̄ +1.000" in out
    assert len((tmp_path / "e.csv").read_text().splitlines()) == 73


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "M4_10x10_C1", "--controller", "bogus"], "unknown controller 'bogus'"),
        (["run", "M4_10x10_C1", "--trajectory", "x.jpg"], "must end in .png"),
        (["run", "M4_10x10_C1", "--robot", "XX"], "'XX'"),
        (["run", "M4_10x10_Q"], "Q"),
        (["run", "M4_10x10_C1", "--controller", "missing.json"], "missing.json"),
        (["inputs", "--controller", "oracle"], "reads the maze itself"),
        (["inputs", "--robot", "CC11"], "CC11"),
        (["suite", "--evaluate", "nope"], "unknown controller 'nope'"),
        (["suite", "--csv", "x.csv"], "--evaluate"),
    ],
)
def test_user_mistakes_are_one_line_errors(capsys, args, message):
    status, out, err = run_cli(capsys, *args)
    assert status == 2
    assert out == ""
    assert err.startswith("error: ") and err.count("\n") == 1
    assert message in err
