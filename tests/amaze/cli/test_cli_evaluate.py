"""``amaze evaluate AGENT MAZE...``: any agent on any mazes, by the evaluation protocol."""

from __future__ import annotations

import csv
import io
import json

import pytest

from amaze.cli.main import main
from amaze.evaluation.controllers import RandomController, train_tabular
from amaze.evaluation.protocol import evaluate
from amaze.evaluation.suite import standard_suite
from amaze.maze import rotations
from amaze.maze.spec import MazeSpec

MAZES = ("M1_5x5_U", "M2_6x6_C1", "M3_5x5_C1_l.25_L.25")
#: Keys of the JSON object, and of each of its per-maze objects.
KEYS = {"agent", "robot", "episodes", "rotations", "success_rate", "normalized_reward",
        "mean_steps", "mazes"}  # fmt: skip
MAZE_KEYS = {"maze", "episodes", "success_rate", "normalized_reward", "mean_steps"}


def run_cli(capsys, *args: str) -> tuple[int, str, str]:
    status = main(["evaluate", *args])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def evaluate_json(capsys, *args: str) -> dict:
    status, out, err = run_cli(capsys, *args, "--json")
    assert status == 0, err
    assert len(out.splitlines()) == 1  # one JSON object
    return json.loads(out)


def test_oracle_plays_each_maze_in_its_four_rotations(capsys):
    status, out, err = run_cli(capsys, "oracle", *MAZES)
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0] == "oracle (DD) on 3 mazes, each in its 4 rotations:"
    assert "episodes" in lines[1] and "success" in lines[1] and "mean steps" in lines[1]
    names = ["M1_5x5_U", "M2_6x6_C1", "M3_5x5_C1_l0.25_L.25"]
    for name, line in zip(names, lines[2:5], strict=True):
        assert line.split()[:3] == [name, "4", "100.0%"]
        assert line.split()[3] == "+1.000"
    assert lines[5].split()[:4] == ["all", "12", "100.0%", "+1.000"]
    assert len(lines) == 6  # the oracle reads the maze: no input recognition


def test_json_has_the_summary_keys_and_one_object_per_maze(capsys):
    outcome = evaluate_json(capsys, "random", *MAZES, "--seed", "3")
    assert KEYS <= set(outcome)
    assert outcome["agent"] == "random" and outcome["seed"] == 3 and outcome["robot"] == "DD"
    assert outcome["episodes"] == 12 and outcome["rotations"] == 4
    assert [m["maze"] for m in outcome["mazes"]] == ["M1_5x5_U", "M2_6x6_C1",
                                                     "M3_5x5_C1_l0.25_L.25"]  # fmt: skip
    for maze in outcome["mazes"]:
        assert MAZE_KEYS <= set(maze) and maze["episodes"] == 4
    assert outcome["input_recognition"] is not None  # as in summary.json


def test_figures_are_those_of_the_python_protocol(capsys, tmp_path):
    outcome = evaluate_json(
        capsys, "random", *MAZES, "--seed", "5", "--csv", str(tmp_path / "e.csv")
    )
    report = evaluate(RandomController("DD", seed=5), "DD", list(MAZES), rotations=4)
    assert outcome["success_rate"] == report.success_rate
    assert outcome["normalized_reward"] == report.normalized_reward
    assert outcome["mean_steps"] == report.mean_steps
    assert outcome["input_recognition"] == report.input_recognition
    with open(tmp_path / "e.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [row["maze"] for row in rows] == rotations(list(MAZES))
    assert [int(row["steps"]) for row in rows] == [e.steps for e in report.episodes]


def test_one_rotation_plays_each_maze_as_given(capsys):
    outcome = evaluate_json(capsys, "oracle", *MAZES, "--rotations", "1")
    assert outcome["episodes"] == 3 and outcome["rotations"] == 1
    assert [m["episodes"] for m in outcome["mazes"]] == [1, 1, 1]
    status, out, _ = run_cli(capsys, "oracle", "M1_5x5_U", "--rotations", "1")
    assert status == 0
    assert out.splitlines()[0] == "oracle (DD) on 1 maze, each as given (1 rotation):"


def test_suite_plays_the_standard_suite(capsys):
    outcome = evaluate_json(capsys, "oracle", "suite")
    assert outcome["episodes"] == 72 and outcome["rotations"] == 4
    canonical = [MazeSpec.from_string(m.string).to_string() for m in standard_suite().mazes]
    assert [m["maze"] for m in outcome["mazes"]] == canonical
    assert outcome["success_rate"] == 1.0


def test_mazes_from_a_file_and_from_standard_input(capsys, tmp_path, monkeypatch):
    listing = tmp_path / "mazes.txt"
    listing.write_text("# training mazes\nM1_5x5_U\n\n  M2_6x6_C1  # with a clue\n")
    outcome = evaluate_json(capsys, "oracle", str(listing), "--rotations", "1")
    assert [m["maze"] for m in outcome["mazes"]] == ["M1_5x5_U", "M2_6x6_C1"]
    monkeypatch.setattr("sys.stdin", io.StringIO("M3_5x5_U\n# done\n"))
    outcome = evaluate_json(capsys, "oracle", "-", "M1_5x5_U", "--rotations", "1")
    assert [m["maze"] for m in outcome["mazes"]] == ["M3_5x5_U", "M1_5x5_U"]


def test_a_seedless_maze_keeps_one_seed_in_its_rotations(capsys):
    outcome = evaluate_json(capsys, "oracle", "5x5_U")
    (maze,) = outcome["mazes"]
    assert maze["maze"].startswith("M") and maze["episodes"] == 4


def test_the_robot_comes_from_the_agent_file(capsys, tmp_path):
    agent = train_tabular(["M1_5x5_U"], method="q_learning", episodes=20, seed=0)
    path = agent.save(tmp_path / "agent.json")
    outcome = evaluate_json(capsys, str(path), "M1_5x5_U")
    assert outcome["robot"] == "DD" and outcome["episodes"] == 4
    status, _, err = run_cli(capsys, str(path), "M1_5x5_U", "--robot", "H15")
    assert status == 2
    assert err == f"error: tabular controller '{path}' drives DD robots only, not H15 (CD15)\n"


def test_random_and_oracle_take_the_robot_option(capsys):
    outcome = evaluate_json(capsys, "random", "M1_5x5_U", "--robot", "H7")
    assert outcome["robot"] == "CD7"
    outcome = evaluate_json(capsys, "oracle", "M1_5x5_U", "--robot", "CC7", "--rotations", "1")
    assert outcome["robot"] == "CC7" and outcome["success_rate"] == 1.0
    assert outcome["input_recognition"] is None


def test_a_flag_token_with_a_tail_warns(capsys):
    status, out, err = run_cli(capsys, "oracle", "M1_5x5_Ux", "--rotations", "1")
    assert status == 0
    assert "M1_5x5_U " in out
    assert err.startswith("warning: maze string 'M1_5x5_Ux': token 'Ux' is read as 'U'")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["oracle", "M1_5x5_Q"], "error: maze 'M1_5x5_Q': unknown or malformed token 'Q'"),
        (["oracle", "M1_500x5"], "error: maze string 'M1_500x5': width 500"),
        (["oracle", "M1_5x5", "--rotations", "2"], "error: amaze evaluate: argument --rotations"),
        (["oracle", "M1_5x5", "--rotations", "x"], "error: amaze evaluate: argument --rotations"),
        (["missing.npz", "M1_5x5"], "error: agent file 'missing.npz' does not exist"),
        (["missing.json", "M1_5x5"], "error: cannot read tabular controller 'missing.json'"),
        (["cheater", "M1_5x5"], "error: unknown controller 'cheater'"),
        (["oracle", "M1_5x5", "--robot", "DD15"], "error: robot string 'DD15': DD"),
        (["oracle", "M1_5x5", "--csv", "out.txt"], "error: output 'out.txt' must end in .csv"),
    ],
)
def test_bad_input_is_one_error_line(capsys, args, message):
    status, out, err = run_cli(capsys, *args)
    assert status == 2
    assert out == ""
    assert err.startswith(message) and err.count("\n") == 1


def test_an_empty_list_of_mazes_is_an_error(capsys, tmp_path):
    listing = tmp_path / "mazes.txt"
    listing.write_text("# nothing yet\n\n")
    status, _, err = run_cli(capsys, "oracle", str(listing))
    assert status == 2
    assert err == "error: no maze to evaluate on: give maze strings, a file of them, - or suite\n"
    listing.write_text("M1_5x5_U\nM2_5x5_Q\n")
    status, _, err = run_cli(capsys, "oracle", str(listing))
    assert status == 2
    assert err.startswith(f"error: maze file '{listing}', line 2: maze 'M2_5x5_Q'")
    status, _, err = run_cli(capsys, "oracle", str(tmp_path))
    assert status == 2
    assert err == f"error: maze file '{tmp_path}' is a folder\n"
