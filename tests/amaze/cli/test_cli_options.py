"""Numeric options of the ``amaze`` command: one ``error:`` line and status 2, never a traceback.

``--deadline-factor`` (run, play, inputs, suite) and ``render --cell-size`` once
printed invalid JSON (``"pretty_reward": NaN``), ran forever or ended in a
traceback; a robot's vision was unbounded.
"""

from __future__ import annotations

import pytest

from amaze.cli.main import main


def run_cli(capsys, *args: str) -> tuple[int, str, str]:
    status = main(list(args))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def assert_one_error_line(status: int, out: str, err: str, named: str) -> None:
    assert status == 2, (out, err)
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert named in err and "Traceback" not in err
    assert out == ""


@pytest.mark.parametrize(
    ("factor", "named"),
    [
        ("nan", "deadline_factor nan is not a finite number"),
        ("inf", "deadline_factor inf is not a finite number"),
        ("-inf", "deadline_factor -inf is not a finite number"),
        ("0", "deadline_factor 0.0 is not a number in [1.0, 1000.0]"),
        ("-1", "deadline_factor -1.0 is not"),
        ("0.5", "deadline_factor 0.5 is not"),
        ("1e308", "deadline_factor 1e+308 is not"),
        ("four", "'four' is not a number"),
    ],
)
@pytest.mark.parametrize("command", ["run", "play"])
def test_deadline_factor_is_refused_with_one_error_line(
    capsys, command: str, factor: str, named: str
) -> None:
    args = (command, "M4_5x5_C1", f"--deadline-factor={factor}", "--json")
    status, out, err = run_cli(capsys, *args)
    assert_one_error_line(status, out, err, f"argument --deadline-factor: {named}")


@pytest.mark.parametrize("command", [["suite", "--evaluate", "random"], ["inputs"]])
def test_deadline_factor_of_the_other_agent_commands_is_checked(capsys, command) -> None:
    status, out, err = run_cli(capsys, *command, "--deadline-factor", "nan")
    assert_one_error_line(status, out, err, "deadline_factor nan")


@pytest.mark.parametrize("size", ["0", "-5", "3", "1000"])
def test_render_cell_size_out_of_range_is_one_error_line(capsys, tmp_path, size: str) -> None:
    target = tmp_path / "maze.png"
    status, out, err = run_cli(capsys, "render", "M4_5x5", "--cell-size", size, "-o", str(target))
    assert_one_error_line(status, out, err, f"cell_size {size} is not an integer in [4, 512]")
    assert not target.exists()


def test_render_picture_too_large_is_one_error_line(capsys, tmp_path) -> None:
    args = ("render", "M1_100x100", "--cell-size", "200", "-o", str(tmp_path / "big.png"))
    status, out, err = run_cli(capsys, *args)
    assert_one_error_line(status, out, err, "cell_size=200 makes a 20100x20100 px picture")


def test_unbounded_vision_is_one_error_line(capsys) -> None:
    status, out, err = run_cli(capsys, "run", "M4_5x5_C1", "--robot", "H10001")
    assert_one_error_line(status, out, err, "vision 10001 must be odd and within [5, 65]")
