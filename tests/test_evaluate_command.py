"""``amaze evaluate`` on an evolved agent: the figures of the Python protocol, and of summary.json.

Across packages: the agent is evolved by ``evolution`` and scored by the
``amaze`` command, which loads it through the ``npz`` entry point.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from amaze.cli.main import main
from amaze.evaluation.protocol import evaluate
from amaze.maze import rotations
from evolution.agent_file import load_agent
from evolution.run import evolve

MAZES = ["M1_5x5_U", "M2_6x6_C1", "M3_5x5_C1_l.25_L.25"]
FIGURES = ("success_rate", "normalized_reward", "pretty_reward", "input_recognition")


@pytest.fixture(scope="module")
def evolved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The agent file of a short CMA-ES run (the one agent file at the top of its folder)."""
    out = tmp_path_factory.mktemp("evolved") / "run"
    config = {
        "algo": "cmaes",
        "mazes": ["M0_5x5_U"],
        "budget_steps": None,
        "max_generations": 2,
        "algorithm": {"population_size": 6},
    }
    evolve(config, out)
    (agent,) = out.glob("*.npz")
    return agent


def run_cli(capsys, *args: str) -> tuple[int, str, str]:
    status = main(["evaluate", *args])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_the_command_plays_three_mazes_in_four_rotations_as_the_python_protocol(
    capsys, evolved, tmp_path
):
    episodes_csv = tmp_path / "episodes.csv"
    status, out, err = run_cli(capsys, str(evolved), *MAZES, "--json", "--csv", str(episodes_csv))
    assert status == 0, err
    outcome = json.loads(out)
    assert outcome["episodes"] == 12 and outcome["rotations"] == 4
    assert outcome["agent"] == str(evolved) and outcome["robot"] == "DD"
    report = evaluate(load_agent(evolved), "DD", MAZES, rotations=4)
    summary = report.summary()
    for key in (*FIGURES, "episodes", "rotations", "robot"):
        assert outcome[key] == summary[key], key
    assert outcome["mean_steps"] == report.mean_steps
    per_maze = report.per_maze()
    assert len(outcome["mazes"]) == len(per_maze) == 3
    for maze, ((name, _), scores) in zip(outcome["mazes"], per_maze.items(), strict=True):
        assert maze["maze"] == name and maze["episodes"] == 4
        assert maze["success_rate"] == scores["success_rate"]
        assert maze["normalized_reward"] == scores["normalized_reward"]
        assert maze["mean_steps"] == scores["mean_steps"]
    with episodes_csv.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [row["maze"] for row in rows] == [e.maze for e in report.episodes] == rotations(MAZES)
    assert [int(row["steps"]) for row in rows] == [e.steps for e in report.episodes]
    assert [float(row["normalized_reward"]) for row in rows] == [
        e.normalized_reward for e in report.episodes
    ]


def test_the_readable_table_has_a_row_per_maze(capsys, evolved):
    status, out, err = run_cli(capsys, str(evolved), *MAZES)
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0] == f"{evolved} (DD) on 3 mazes, each in its 4 rotations:"
    assert [line.split()[:2] for line in lines[2:6]] == [
        ["M1_5x5_U", "4"], ["M2_6x6_C1", "4"], ["M3_5x5_C1_l0.25_L.25", "4"], ["all", "12"],
    ]  # fmt: skip
    assert lines[6].startswith("  input recognition ")


def test_one_rotation_plays_three_episodes(capsys, evolved):
    status, out, err = run_cli(capsys, str(evolved), *MAZES, "--rotations", "1", "--json")
    assert status == 0, err
    outcome = json.loads(out)
    assert outcome["episodes"] == 3 and outcome["rotations"] == 1
    report = evaluate(load_agent(evolved), "DD", MAZES, rotations=1)
    assert outcome["normalized_reward"] == report.normalized_reward


def test_the_suite_reproduces_the_summary_of_the_run(capsys, evolved):
    status, out, err = run_cli(capsys, str(evolved), "suite", "--json")
    assert status == 0, err
    outcome = json.loads(out)
    assert outcome["episodes"] == 72 and outcome["rotations"] == 4
    summary = json.loads((evolved.parent / "summary.json").read_text())
    for key in (*FIGURES, "episodes"):
        assert outcome[key] == summary[key], key


def test_a_bad_maze_is_one_error_line(capsys, evolved):
    status, out, err = run_cli(capsys, str(evolved), "M1_5x5_U", "M2_5x5_Q")
    assert status == 2
    assert out == ""
    assert err == "error: maze 'M2_5x5_Q': unknown or malformed token 'Q'\n"


def test_a_robot_the_agent_does_not_drive_is_named_as_given(capsys, evolved):
    status, _, err = run_cli(capsys, str(evolved), "M1_5x5_U", "--robot", "H15")
    assert status == 2
    assert err == f"error: agent '{evolved}' drives DD robots, not H15 (CD15): pass --robot DD\n"


def test_a_run_folder_is_scored_with_its_agent(capsys, evolved):
    by_file = run_cli(capsys, str(evolved), MAZES[0], "--json")
    by_folder = run_cli(capsys, str(evolved.parent), MAZES[0], "--json")
    assert by_folder[0] == 0 and json.loads(by_folder[1]) == json.loads(by_file[1])


def test_a_folder_without_an_agent_says_which_file_to_give(capsys, evolved, tmp_path):
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    (unfinished / "config.json").write_text("{}")
    replicates = tmp_path / "replicates"
    (replicates / "seed-0").mkdir(parents=True)
    (replicates / "seed-0" / "config.json").write_text("{}")
    for folder, words in [
        (unfinished, "has no agent yet"),
        (replicates, "holds replicates (seed-0)"),
        (tmp_path / "replicates" / "seed-0" / "..", "holds replicates"),
        (evolved.parents[1], "not a run folder"),
    ]:
        status, _, err = run_cli(capsys, str(folder), MAZES[0])
        assert status == 2 and words in err, err
