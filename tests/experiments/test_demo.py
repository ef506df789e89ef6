"""The demo (``make demo``): its three parts on a tiny evolution budget, and its table."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from experiments import demo

pytestmark = pytest.mark.slow

#: Env steps of each evolution run in these tests: a generation or a few, a few seconds in all.
TINY_STEPS = 200_000


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """The demo run once with a tiny budget: its output folder and what it printed."""
    out = tmp_path_factory.mktemp("demo") / "demo_output"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert demo.main(["--out", str(out), "--steps", str(TINY_STEPS)]) == 0
    return out, printed.getvalue()


def test_table_has_both_runs_with_unseen_figures(demo_run: tuple[Path, str]) -> None:
    """The printed table has a column per run and the suite, unseen and budget rows."""
    _, printed = demo_run
    header = next(line for line in printed.splitlines() if "coevolution" in line.split())
    assert header.split() == ["coevolution", "direct"]
    for row in (
        "standard suite: success",
        "standard suite: mean R̄",
        "input recognition",
        "unseen family mazes (32 x 4): success",
        "unseen family mazes: mean R̄",
        "env steps",
        "seconds",
    ):
        line = next(line for line in printed.splitlines() if line.startswith(row))
        assert len(line[len(row) :].split()) == 2, line


def test_headline_json_is_one_quantity_for_both_runs(demo_run: tuple[Path, str]) -> None:
    """Both columns come from the same unseen mazes; the coevolution one matches its summary."""
    out, _ = demo_run
    table = json.loads((out / "headline.json").read_text())
    assert list(table) == ["coevolution", "direct"]
    for regime, figures in table.items():
        assert figures["unseen_episodes"] == 4 * 32
        assert 0.0 <= figures["unseen_success_rate"] <= 1.0
        assert figures["env_steps"] > 0
        assert Path(figures["agent_file"]).is_file()
        summary = json.loads((out / regime / "summary.json").read_text())
        assert figures["success_rate"] == pytest.approx(summary["success_rate"])
        assert figures["normalized_reward"] == pytest.approx(summary["normalized_reward"])
    summary = json.loads((out / "coevolution" / "summary.json").read_text())
    assert table["coevolution"]["unseen_success_rate"] == pytest.approx(
        summary["unseen_success_rate"]
    )
    assert table["coevolution"]["unseen_normalized_reward"] == pytest.approx(
        summary["unseen_normalized_reward"]
    )


def test_outputs_are_where_the_demo_says(demo_run: tuple[Path, str]) -> None:
    """Every picture the summary lists exists, and the three commands are printed."""
    out, printed = demo_run
    for name in (
        "classes.png",
        "mazes.csv",
        "headline.json",
        "agents/summary.json",
        "agents/inputs_random.png",
        "agents/trajectory_oracle.png",
        "agents/episode_random.gif",
        "agents/evaluation_maze_coevolution.png",
        "agents/evaluation_maze_direct.png",
        "coevolution/population.png",
        "coevolution/coevolution.png",
        "direct/fitness.png",
    ):
        assert (out / name).is_file(), name
    assert list((out / "coevolution" / "trajectories").glob("*.png"))
    assert list((out / "direct" / "trajectories").glob("*.png"))
    assert len(list((out / "mazes").glob("*.png"))) == 2 * 12
    assert str(out.resolve()) in printed
    for command in ("amaze-evolve --regime coevolution", "amaze-experiment run smoke", "amaze run"):
        assert command in printed


def test_format_comparison_lines_up_columns() -> None:
    """One header, one row per figure, one right-aligned cell per run."""
    figures = {
        "success_rate": 0.5,
        "normalized_reward": -1.25,
        "input_recognition": None,
        "column_success": {"trivial": 1.0, "16 traps": 0.0},
        "unseen_success_rate": 0.25,
        "unseen_normalized_reward": 0.5,
        "unseen_episodes": 128,
        "env_steps": 1234,
        "seconds": 1.5,
        "generations": 3,
    }
    lines = demo.format_comparison({"coevolution": figures, "direct": figures}).splitlines()
    assert lines[0].split() == ["coevolution", "direct"]
    assert len({len(line) for line in lines}) == 1
    assert any(line.startswith("input recognition") and line.endswith("n/a") for line in lines)
    assert any(line.startswith("  16 traps") for line in lines)


def test_steps_must_be_positive() -> None:
    with pytest.raises(SystemExit):
        demo.main(["--steps", "0"])


def test_the_demo_prints_as_it_goes_into_a_pipe(tmp_path: Path) -> None:
    """Piped to a file (``make demo > log``), the demo's lines come as they are printed:
    its first line is there while the demo still runs (a full run takes a minute)."""
    import subprocess
    import sys

    demo_process = subprocess.Popen(
        [sys.executable, "-m", "experiments.demo", "--out", str(tmp_path / "out")],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        first = demo_process.stdout.readline()
        assert first.startswith("amaze-evo demo:"), first
        assert demo_process.poll() is None  # the line came before the end
    finally:
        demo_process.kill()
        demo_process.wait()
