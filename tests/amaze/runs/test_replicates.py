"""Replicates: command lines per seed, parallel worker processes, logs and exit status."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from amaze.runs.replicates import (
    Replicate,
    plan_replicates,
    replicate_command,
    run_replicates,
    strip_options,
)


def test_strip_options_removes_values_in_both_forms() -> None:
    argv = ["--a", "1", "--seed=3", "--out", "x", "--keep", "y"]
    assert strip_options(argv, ("--seed", "--out")) == ["--a", "1", "--keep", "y"]


def test_plan_gives_each_seed_its_folder(tmp_path: Path) -> None:
    plan = plan_replicates("m", ["--x", "1", "--seed", "4", "--workers=2"], 4, 2, tmp_path)
    assert [r.seed for r in plan] == [4, 5]
    assert plan[1].out == tmp_path / "seed-5"
    assert plan[1].command[1:] == ["-m", "m", "--x", "1", "--seed", "5", "--out", str(plan[1].out)]
    with pytest.raises(ValueError, match="0"):
        plan_replicates("m", [], 0, 0, tmp_path)


def _waiter(tmp_path: Path, seed: int, code: int) -> Replicate:
    """A process that marks its start, then waits (up to 20 s) until all three have started."""
    script = "\n".join(
        [
            "import os, pathlib, sys, time",
            "print('threads', os.environ['NUMBA_NUM_THREADS'])",
            f"root = pathlib.Path({str(tmp_path)!r})",
            f"(root / 'started-{seed}').touch()",
            "deadline = time.monotonic() + 20",
            "while len(list(root.glob('started-*'))) < 3 and time.monotonic() < deadline:",
            "    time.sleep(0.05)",
            f"sys.exit({code} if len(list(root.glob('started-*'))) == 3 else 9)",
        ]
    )
    return Replicate(seed, tmp_path / f"seed-{seed}", [sys.executable, "-c", script])


def test_workers_run_at_once_and_failures_are_reported(tmp_path: Path) -> None:
    plan = [_waiter(tmp_path, 0, 0), _waiter(tmp_path, 1, 3), _waiter(tmp_path, 2, 0)]
    assert run_replicates(plan, workers=3) == 3  # 9 if they had run one after another
    for replicate in plan:
        assert (replicate.out / "log.txt").read_text().startswith("threads ")
    with pytest.raises(ValueError, match="workers"):
        run_replicates(plan, workers=0)


def test_a_replicate_trains_in_the_folder_that_holds_its_log(tmp_path: Path, capsys) -> None:
    argv = ["--algo", "cmaes", "--mazes", "M0_5x5_U", "--max-generations", "1"]
    assert replicate_command("evolution.cli", argv, 3, 1, str(tmp_path)) == 0
    assert (tmp_path / "seed-3" / "summary.json").is_file()
    assert (tmp_path / "seed-3" / "log.txt").read_text().startswith("1 generations")
    assert capsys.readouterr().out.splitlines()[-1] == "seed 3: done"
