"""The study runner on Ray: results as on this machine; lost workers retried, their runs resumed."""

from __future__ import annotations

import json
import os
import re
import signal
import threading
from pathlib import Path
from typing import Any

import pytest

from experiments.cli import main
from experiments.runner import StudyFolder, run_study, study_status
from experiments.study import Study, parse_study
from tests.processes import process_running, wait_until

pytestmark = [pytest.mark.xdist_group("ray"), pytest.mark.slow]

#: Two CMA-ES runs of a few thousand env steps (about 3 s each, most of it start-up).
STUDY = """
name = "tiny"
description = "Short CMA-ES runs."
seeds = 2
trainers = ["direct"]
algorithms = ["cmaes"]

[budgets]
steps = { steps = 20_000 }

[options.cmaes]
checkpoint_seconds = 0.1
mazes = ["M1_5x5_C1"]
"""
#: One run long enough (about 2 s of training) to be killed half-way.
LONG_STUDY = STUDY.replace("seeds = 2", "seeds = 1").replace("20_000", "4_000_000")
#: The fields of a summary that do not depend on timing.
DETERMINISTIC = (
    "env_steps",
    "generations",
    "episodes",
    "champion_fitness",
    "success_rate",
    "normalized_reward",
    "input_recognition",
)


def deterministic(folder: StudyFolder, study: Study) -> list[dict[str, Any]]:
    """The deterministic fields of the summaries of ``study``'s runs in ``folder``."""
    summaries = [
        json.loads((folder.run_folder(run) / "summary.json").read_text()) for run in study.runs
    ]
    return [{key: summary[key] for key in DETERMINISTIC} for summary in summaries]


def test_a_study_on_ray_gives_the_results_of_a_local_one(tmp_path: Path, ray_cluster) -> None:
    study = parse_study(STUDY)
    local, distributed = StudyFolder(tmp_path / "local"), StudyFolder(tmp_path / "ray")
    assert run_study(study, local.out, workers=2, progress="off") == 0
    assert run_study(study, distributed.out, progress="off", backend="ray") == 0
    assert deterministic(distributed, study) == deterministic(local, study)
    _, statuses = study_status(distributed.out)
    assert [s.state for s in statuses] == ["done", "done"]
    state = json.loads((distributed.out / "state.json").read_text())
    assert state["runner"] is None and state["running"] == [] and state["failed"] == {}
    assert state["threads"] == {run.id: 1 for run in study.runs}
    assert set(state["wall_seconds"]) == {run.id for run in study.runs}
    for run in study.runs:
        log = distributed.log_file(run).read_text()
        assert log.count("started by the study runner") == 1
        assert log.count("Ray task on") == 1 and "NUMBA" not in log


def test_a_run_whose_ray_worker_is_killed_resumes_from_its_checkpoint(
    tmp_path: Path, ray_cluster
) -> None:
    study = parse_study(LONG_STUDY)
    (run,) = study.runs
    local, distributed = StudyFolder(tmp_path / "local"), StudyFolder(tmp_path / "ray")
    assert run_study(study, local.out, workers=1, progress="off") == 0
    statuses: list[int] = []
    runner = threading.Thread(
        target=lambda: statuses.append(
            run_study(study, distributed.out, progress="off", backend="ray")
        )
    )
    runner.start()
    try:
        # kill -9 the Ray worker part-way through the run, after a checkpoint; the run is
        # stopped (SIGSTOP) first, so that however loaded the machine, it cannot end before
        checkpoint = distributed.run_folder(run) / "checkpoints" / "state.npz"
        wait_until(lambda: checkpoint.is_file() and distributed.fraction(run) > 0.2, timeout=600)
        log = distributed.log_file(run).read_text()
        worker = int(re.search(r"Ray task on \S+, worker process (\d+)", log)[1])
        child = int(re.search(r"run process (\d+)", log)[1])
        os.kill(child, signal.SIGSTOP)
        summary = distributed.run_folder(run) / "summary.json"
        assert not summary.exists(), "the run ended before it could be killed"
        os.kill(worker, signal.SIGKILL)
        wait_until(lambda: not process_running(child), timeout=120)  # it went with its worker
    finally:
        runner.join(timeout=900)
    assert statuses == [0]
    log = distributed.log_file(run).read_text()
    assert log.count("started by the study runner") == 1
    assert log.count("Ray task on") == 2  # the task, then Ray's retry
    assert deterministic(distributed, study) == deterministic(local, study)
    state = json.loads((distributed.out / "state.json").read_text())
    assert state["failed"] == {} and state["runner"] is None


def test_a_failed_run_on_ray_is_recorded_not_retried(
    tmp_path: Path, ray_cluster, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "tiny.toml").write_text(STUDY.replace("seeds = 2", "seeds = 1"))
    study = parse_study((tmp_path / "tiny.toml").read_text())
    folder = StudyFolder(tmp_path / "study")
    # a folder in the way of the run: its trainer refuses it (exit status 2)
    folder.run_folder(study.runs[0]).mkdir(parents=True)
    (folder.run_folder(study.runs[0]) / "notes.txt").write_text("mine")
    address = ray_cluster.get_runtime_context().gcs_address
    argv = ["run", str(tmp_path / "tiny.toml"), "--out", str(folder.out)]
    folder.out.joinpath("study.toml").write_text(study.text)
    assert main([*argv, "--backend", "ray", "--address", address]) == 1
    _, statuses = study_status(folder.out)
    assert statuses[0].state == "failed" and "exit 2" in statuses[0].detail
    log = folder.log_file(study.runs[0]).read_text()
    assert "not empty" in log and log.count("Ray task on") == 1
    state = json.loads((folder.out / "state.json").read_text())
    assert state["failed"][study.runs[0].id]["status"] == 2
    assert "failed (exit 2)" in capsys.readouterr().out
