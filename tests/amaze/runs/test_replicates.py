"""Replicates: command lines per seed, parallel worker processes, logs and exit status."""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

from amaze.runs.command import TrainingCommand
from amaze.runs.replicates import (
    Replicate,
    plan_replicates,
    replicate_command,
    replicates_table,
    run_replicates,
    strip_options,
)
from tests.amaze.runs.toy_curriculum import ToyRun


def test_a_flag_before_an_option_keeps_that_option() -> None:
    """``--no-progress`` takes no value: the ``--out`` after it is not swallowed with it."""
    argv = ["--algo", "ppo", "--replicates", "3", "--no-progress", "--out", "runs/r"]
    plan = plan_replicates("rl_baselines.cli", argv, 0, 3, "runs/r")
    for replicate in plan:
        tail = replicate.command[3:]
        assert tail == ["--algo", "ppo", "--seed", str(replicate.seed), "--out", str(replicate.out)]


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
    log = (tmp_path / "seed-3" / "log.txt").read_text()
    assert "cmaes direct seed 3: 0% of" in log  # its progress, as plain lines
    assert "\n1 generations" in log  # its closing headline
    printed = capsys.readouterr().out.splitlines()
    summary = json.loads((tmp_path / "seed-3" / "summary.json").read_text())
    assert printed[-7] == "seed 3: done"
    assert printed[-6].split() == ["replicate", "success", "R̄", "inputs", "env", "steps"]
    assert printed[-5].split()[:3] == ["seed", "3", f"{summary['success_rate']:.3f}"]
    assert [line.split()[0] for line in printed[-4:]] == ["min", "max", "median", "IQR"]


def test_the_closing_table_gives_min_max_median_and_iqr(tmp_path: Path) -> None:
    """Max and median sit beside the paper's Table 3; median and IQR stay the last lines."""
    plan = []
    for seed, success in zip(range(5), (0.2, 0.5, 0.3, 0.9, 0.4), strict=True):
        out = tmp_path / f"seed-{seed}"
        out.mkdir()
        summary = {
            "success_rate": success,
            "normalized_reward": -success,
            "input_recognition": None,  # not measured: n/a, left out of the statistics
            "env_steps": 1000 * (seed + 1),
        }
        (out / "summary.json").write_text(json.dumps(summary))
        plan.append(Replicate(seed, out, []))
    plan.append(Replicate(5, tmp_path / "seed-5", []))  # failed: no summary
    lines = replicates_table(plan).splitlines()
    assert lines[0].split() == ["replicate", "success", "R̄", "inputs", "env", "steps"]
    assert lines[6].split() == ["seed", "5", "no", "summary", "(see", "its", "log.txt)"]
    rows = {line.split()[0]: line.split()[1:] for line in lines[7:]}
    assert list(rows) == ["min", "max", "median", "IQR"]
    assert rows["min"] == ["0.200", "-0.900", "n/a", "1,000"]
    assert rows["max"] == ["0.900", "-0.200", "n/a", "5,000"]
    assert rows["median"] == ["0.400", "-0.400", "n/a", "3,000"]
    assert rows["IQR"] == ["0.200", "0.200", "n/a", "2,000"]


def _toy_command(**fields) -> TrainingCommand:
    """A training command of the toy trainer, with an ``--actors`` option as ``amaze-evolve``'s."""
    return TrainingCommand(
        "toy",
        "a toy trainer",
        "tests.amaze.runs.toy_curriculum",
        ToyRun,
        add_arguments=lambda group: group.add_argument("--actors", type=int),
        run_context=lambda args: contextlib.nullcontext(),
        **fields,
    )


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--replicates", "2", "--backend", "ray", "--actors", "2"], "--actors"),
        (["--replicates", "2", "--actors=2"], "--actors"),
        (["--replicates", "2", "--address", "head:6379"], "--address"),
        (["--address", "head:6379"], "--address"),
    ],
)
def test_replicates_refuse_options_of_another_backend(
    argv: list[str], named: str, tmp_path: Path, capsys
) -> None:
    assert _toy_command().main([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and named in err[0]
    assert not (tmp_path / "out").exists()


def test_ray_missing_is_a_usage_error(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    argv = ["--replicates", "2", "--backend", "ray", "--out", str(tmp_path / "out")]
    assert _toy_command().main(argv) == 2
    assert "pip install 'amaze-evo[ray]'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_local_backend_never_imports_ray() -> None:
    code = (
        "import sys, amaze.runs.command, amaze.runs.ray_tasks, experiments.cli;"
        " sys.exit('ray' in sys.modules)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
