"""Jobs as Ray tasks: status, retries of killed runs, resumes, stops, replicates on Ray."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

from amaze.runs.launchers import Job, run_jobs
from amaze.runs.ray_tasks import LOST_STATUS, TASK_RETRIES, RayLauncher
from amaze.runs.replicates import replicate_command
from tests.processes import process_running, wait_until

pytestmark = [pytest.mark.xdist_group("ray"), pytest.mark.slow]

#: A tiny CMA-ES run of amaze-evolve (about 3 s, most of it start-up).
EVOLVE = ["--algo", "cmaes", "--mazes", "M1_5x5_C1", "--budget-steps", "20000"]
#: The fields of a summary that do not depend on timing.
DETERMINISTIC = (
    "env_steps",
    "generations",
    "champion_fitness",
    "success_rate",
    "normalized_reward",
    "input_recognition",
)


def python(code: str) -> list[str]:
    return [sys.executable, "-c", code]


def finish(launcher: RayLauncher, job: Job, timeout: float = 60.0) -> int:
    """Run ``job`` on ``launcher`` to its end; its exit status."""
    handle = launcher.start(job)
    statuses: list[int | None] = []
    wait_until(lambda: statuses.append(launcher.poll(handle)) or statuses[-1] is not None, timeout)
    return int(statuses[-1])


def test_a_task_runs_its_command_and_returns_its_status(tmp_path: Path, ray_cluster) -> None:
    launcher = RayLauncher(ray_cluster, tmp_path)
    code = "import os; print(os.getcwd(), os.environ['NUMBA_NUM_THREADS']); raise SystemExit(3)"
    log = tmp_path / "logs" / "job.txt"
    assert finish(launcher, Job(python(code), log)) == 3  # a plain failure: not retried
    first, *rest = log.read_text().splitlines()
    assert re.fullmatch(r"--- \S+: Ray task on \S+, worker process \d+", first)
    assert f"{tmp_path} 1" in rest and "\n".join(rest).count("Ray task on") == 0


def test_a_command_that_cannot_start_fails_with_its_reason(tmp_path: Path, ray_cluster) -> None:
    launcher = RayLauncher(ray_cluster, tmp_path / "nowhere")
    log = tmp_path / "log.txt"
    assert finish(launcher, Job(python("print('ran')"), log)) == LOST_STATUS
    text = log.read_text()
    assert "ran" not in text and "FileNotFoundError" in text and text.count("Ray task on") == 1


def test_a_killed_command_is_retried_then_given_up(tmp_path: Path, ray_cluster) -> None:
    launcher = RayLauncher(ray_cluster, tmp_path)
    # killed the first time, then a success: the retry's status is the job's
    once = "import os, pathlib; p = pathlib.Path('killed'); k = not p.exists(); p.touch()\n"
    once += "if k: os.kill(os.getpid(), 9)"
    assert finish(launcher, Job(python(once), tmp_path / "once.txt")) == 0
    assert (tmp_path / "once.txt").read_text().count("Ray task on") == 2
    # killed every time: given up after the retries, with the signal as status
    always = Job(python("import os; os.kill(os.getpid(), 9)"), tmp_path / "always.txt")
    assert finish(launcher, always) == -9
    log = always.log.read_text()
    assert log.count("Ray task on") == TASK_RETRIES + 1 and "killed by signal 9" in log


def test_a_task_resumes_a_folder_that_holds_a_run(tmp_path: Path, ray_cluster) -> None:
    launcher = RayLauncher(ray_cluster, tmp_path)
    job = Job(python("print('fresh')"), tmp_path / "log.txt", python("print('resumed')"))
    job = Job(job.command, job.log, job.resume, tmp_path / "config.json")
    assert finish(launcher, job) == 0
    (tmp_path / "config.json").write_text("{}")
    assert finish(launcher, job) == 0
    assert re.findall(r"^(fresh|resumed)$", job.log.read_text(), re.MULTILINE) == [
        "fresh",
        "resumed",
    ]


def test_an_interrupted_loop_cancels_its_tasks_and_their_runs(tmp_path: Path, ray_cluster) -> None:
    launcher = RayLauncher(ray_cluster, tmp_path)
    log = tmp_path / "log.txt"
    stopped: list[list[str]] = []

    def polled(running: list[str]) -> None:
        if "run process" in (log.read_text() if log.exists() else ""):
            raise KeyboardInterrupt  # Ctrl-C once the run has started

    with pytest.raises(KeyboardInterrupt):
        run_jobs(
            launcher,
            ["job"],
            1,
            lambda key: Job(python("import time; time.sleep(60)"), log),
            lambda key, status: pytest.fail("the job ended"),
            polled=polled,
            stopped=stopped.append,
        )
    assert stopped == [["job"]]
    child = int(re.search(r"run process (\d+)", log.read_text())[1])
    wait_until(lambda: not process_running(child), timeout=10)


def test_replicates_on_ray_give_the_results_of_local_ones(
    tmp_path: Path, ray_cluster, capsys: pytest.CaptureFixture[str]
) -> None:
    address = ray_cluster.get_runtime_context().gcs_address
    local, distributed = tmp_path / "local", tmp_path / "ray"
    assert replicate_command("evolution.cli", EVOLVE, 0, 2, str(local)) == 0
    capsys.readouterr()
    argv = [*EVOLVE, "--backend", "ray", "--address", address, "--replicates", "2"]
    ray_argv = [*argv, "--out", str(distributed)]
    assert replicate_command("evolution.cli", ray_argv, 0, 2, str(distributed), backend="ray") == 0
    printed = capsys.readouterr().out
    lines = printed.split("\nreplicate ")[0].splitlines()  # then the closing table
    assert sorted(lines) == sorted(
        [f"seed {s}: started, log in {distributed / f'seed-{s}' / 'log.txt'}" for s in (0, 1)]
        + ["seed 0: done", "seed 1: done"]
    )
    for seed in (0, 1):
        summaries = [
            json.loads((out / f"seed-{seed}" / "summary.json").read_text())
            for out in (local, distributed)
        ]
        assert [{k: s[k] for k in DETERMINISTIC} for s in summaries] == [
            {k: summaries[0][k] for k in DETERMINISTIC}
        ] * 2
        assert summaries[1]["seed"] == seed
    log = (distributed / "seed-0" / "log.txt").read_text()
    assert "--backend" not in log and "--address" not in log
    # run again: the folders hold runs, which resume (finished, they finish again)
    assert replicate_command("evolution.cli", ray_argv, 0, 2, str(distributed), backend="ray") == 0
    log = (distributed / "seed-1" / "log.txt").read_text()
    assert log.count("Ray task on") == 2 and f"--resume {distributed / 'seed-1'}" in log
