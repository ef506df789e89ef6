"""The ``amaze`` command line: the inspect contract, render, stats and error handling."""

from __future__ import annotations

import csv
import io
import json
import subprocess
import sys
from pathlib import Path

import pytest

from amaze.cli.main import main
from amaze.maze.description import INSPECT_KEYS, STATS_COLUMNS
from tests.amaze.conftest import load_reference

PRIMARY = load_reference()["mazes"]


def run_cli(capsys, *args: str) -> tuple[int, str, str]:
    status = main(list(args))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.mark.parametrize("fixture", PRIMARY, ids=[m["input"] for m in PRIMARY])
def test_inspect_json_matches_reference(capsys, fixture):
    status, out, err = run_cli(capsys, "inspect", "--json", fixture["input"])
    assert status == 0, err
    lines = out.splitlines()
    assert len(lines) == 1
    record = json.loads(lines[0])
    assert tuple(record) == INSPECT_KEYS
    assert record["string"] == fixture["build_data_to_string"]
    assert (record["width"], record["height"]) == (fixture["width"], fixture["height"])
    assert record["start"] == fixture["start"] and record["end"] == fixture["end"]
    assert record["solution"] == fixture["solution"]
    hex_digits = "".join(
        f"{sum(bit << k for k, bit in enumerate(cell)):x}"
        for column in record["walls"]
        for cell in column
    )
    assert hex_digits == fixture["walls_hex"]
    assert record["intersections"] == fixture["intersections"]
    assert record["class"] == fixture["maze_class"].lower()
    expected_signs = [
        (kind, s["cell"], s["sign_dir"], s["true_dir"], s["hash_dependent"])
        for kind in ("clue", "lure", "trap")
        for s in fixture["signs"][kind]
    ]
    assert len(record["signs"]) == len(expected_signs)
    for sign, (kind, cell, direction, truth, undefined) in zip(
        record["signs"], expected_signs, strict=True
    ):
        assert set(sign) == {"kind", "cell", "direction", "truth", "value", "shape"}
        assert (sign["kind"], sign["cell"], sign["truth"]) == (kind, cell, truth)
        assert undefined or sign["direction"] == direction
        assert 0 < sign["value"] <= 1 and isinstance(sign["shape"], str)
    metrics = fixture["metrics"]
    assert record["metrics"]["surprisingness"] == pytest.approx(
        metrics["surprisingness"]["path"], abs=1e-9
    )
    assert record["metrics"]["surprisingness_all"] == pytest.approx(
        metrics["surprisingness"]["all"], abs=1e-9
    )
    assert record["metrics"]["deceptiveness"] == pytest.approx(metrics["deceptiveness"], abs=1e-9)


def test_inspect_reads_stdin_and_keeps_order(capsys, monkeypatch):
    monkeypatch.setattr(sys, "stdin", io.StringIO("M1_5x5\n\nM2_6x6_C1\n"))
    status, out, _ = run_cli(capsys, "inspect", "--json", "M0_4x4", "-")
    assert status == 0
    strings = [json.loads(line)["string"] for line in out.splitlines()]
    assert strings == ["M0_4x4", "M1_5x5", "M2_6x6_C1"]


def test_inspect_summary_is_readable(capsys):
    status, out, _ = run_cli(capsys, "inspect", "M4_10x10_C1")
    assert status == 0
    assert "M4_10x10_C1" in out and "class: simple" in out
    assert "path 29 cells, 2 intersections" in out


def test_render_writes_a_png(capsys, tmp_path):
    target = tmp_path / "maze.png"
    status, out, err = run_cli(capsys, "render", "M4_10x10_C1", "-o", str(target), "--dark")
    assert status == 0, err
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert str(target) in out


@pytest.mark.parametrize("name", ["", "maze.jpg"])
def test_render_rejects_bad_outputs(capsys, tmp_path, name):
    status, _, err = run_cli(capsys, "render", "M4_5x5", "-o", str(tmp_path / name))
    assert status == 2
    assert err.startswith("error: ") and err.count("\n") == 1


def test_stats_table_and_csv(capsys, tmp_path):
    target = tmp_path / "stats.csv"
    status, out, _ = run_cli(
        capsys, "stats", "M4_10x10_C1", "M20000018_20x20_C1_l.25_L.25_t.5_T.5", "--csv", str(target)
    )
    assert status == 0
    assert "complex" in out and "simple" in out
    with target.open() as stream:
        rows = list(csv.DictReader(stream))
    assert tuple(rows[0]) == STATS_COLUMNS
    assert rows[1]["string"] == "M20000018_20x20_C1_l0.25_L.25_t0.5_T.5"
    assert (rows[1]["path"], rows[1]["lures"], rows[1]["class"]) == ("85", "19", "complex")
    assert float(rows[1]["surprisingness"]) == pytest.approx(4.5368, abs=1e-4)


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["inspect", "M4_5x5_SEx"], "SEx"),
        (["inspect", "--json", "M4_Cfoo"], "foo"),
        (["stats", "M4_1x5"], "width 1"),
        (["render", "M4_5x5_q"], "q"),
        (["frobnicate"], "frobnicate"),
        (["inspect"], "MAZE"),
        (["render", "M4_5x5", "--cell-size", "big"], "big"),
        (["--signs", "/no/such/folder", "inspect", "M1_5x5"], "/no/such/folder"),
        (["stats", "M4_5x5", "--csv", "/no/such/dir/x.csv"], "/no/such/dir"),
    ],
)
def test_user_mistakes_give_one_line_and_status_2(capsys, args, named):
    status, _, err = run_cli(capsys, *args)
    assert status == 2
    assert err.startswith("error: ") and err.count("\n") == 1
    assert named in err
    assert "Traceback" not in err


def test_warnings_are_one_line_on_stderr(capsys):
    status, _, err = run_cli(capsys, "inspect", "M4_5x5_l.25")
    assert status == 0
    assert err.startswith("warning: ") and "l.25" in err


def test_module_entry_point_exits_with_status_2(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "amaze", "inspect", "M-1"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert result.returncode == 2
    assert result.stderr.strip().startswith("error: ") and "M-1" in result.stderr
    assert "Traceback" not in result.stderr
    assert list(tmp_path.iterdir()) == []  # nothing written into the working directory


def test_console_script_is_installed():
    script = Path(sys.executable).with_name("amaze")
    result = subprocess.run(
        [str(script), "inspect", "--json", "M4_10x10_C1"], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["class"] == "simple"
