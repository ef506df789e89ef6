"""The study runner: runs in worker processes, a killed study resumes without redoing a run."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from experiments.cli import main
from experiments.runner import StudyFolder, format_status, study_status
from experiments.study import parse_study
from tests.processes import wait_until

ROOT = Path(__file__).resolve().parents[2]
#: Three CMA-ES runs of about 3 s of training each, one at a time.
STUDY = """
name = "tiny"
description = "Three short CMA-ES runs."
seeds = 3
trainers = ["direct"]
algorithms = ["cmaes"]

[budgets]
clock = { seconds = 3 }

[options.cmaes]
checkpoint_seconds = 0.2
mazes = ["M1_5x5_C1"]
"""


@pytest.mark.slow
def test_a_killed_study_resumes_without_redoing_finished_runs(tmp_path: Path) -> None:
    (tmp_path / "tiny.toml").write_text(STUDY)
    out = tmp_path / "study"
    command = [sys.executable, "-m", "experiments.cli", "run", str(tmp_path / "tiny.toml")]
    command += ["--out", str(out), "--workers", "1"]
    environment = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    runner = subprocess.Popen(command, cwd=ROOT, env=environment, stdout=subprocess.PIPE, text=True)
    study = parse_study(STUDY)
    folder = StudyFolder(out)
    first, second, third = study.runs
    # stop the study while the second run trains (the first is finished)
    wait_until(lambda: folder.finished(first))
    wait_until(lambda: (folder.run_folder(second) / "progress.csv").is_file())
    _, statuses = study_status(out)
    assert [s.state for s in statuses] == ["done", "running", "pending"]
    runner.send_signal(signal.SIGTERM)  # as `kill` does; Ctrl-C is handled alike
    runner.communicate(timeout=60)
    finished_at = (folder.run_folder(first) / "summary.json").stat().st_mtime_ns
    _, statuses = study_status(out)
    assert [s.state for s in statuses] == ["done", "interrupted", "pending"]
    assert "interrupted" in format_status(study, statuses)

    assert main(["run", str(tmp_path / "tiny.toml"), "--out", str(out), "--workers", "1"]) == 0
    _, statuses = study_status(out)
    assert [s.state for s in statuses] == ["done", "done", "done"]
    assert (folder.run_folder(first) / "summary.json").stat().st_mtime_ns == finished_at
    assert folder.log_file(first).read_text().count("started by the study runner") == 1
    assert folder.log_file(second).read_text().count("started by the study runner") == 2
    state = json.loads((out / "state.json").read_text())
    assert state["runner"] is None and state["failed"] == {}
    assert set(state["wall_seconds"]) == {run.id for run in study.runs}
    summary = json.loads((folder.run_folder(third) / "summary.json").read_text())
    assert summary["seed"] == 2 and summary["budget_seconds"] == 3
    # a study's folder is its own
    other = STUDY.replace('"tiny"', '"other"')
    (tmp_path / "other.toml").write_text(other)
    assert main(["run", str(tmp_path / "other.toml"), "--out", str(out)]) == 2


@pytest.mark.slow
def test_a_failed_run_is_reported_and_tried_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    (tmp_path / "tiny.toml").write_text(STUDY.replace("seeds = 3", "seeds = 1"))
    out = tmp_path / "study"
    study = parse_study((tmp_path / "tiny.toml").read_text())
    folder = StudyFolder(out)
    # a folder in the way of the run: its trainer refuses it
    folder.run_folder(study.runs[0]).mkdir(parents=True)
    (folder.run_folder(study.runs[0]) / "notes.txt").write_text("mine")
    folder.out.joinpath("study.toml").write_text(study.text)
    assert main(["run", str(tmp_path / "tiny.toml"), "--out", str(out)]) == 1
    _, statuses = study_status(out)
    assert statuses[0].state == "failed"
    assert "not empty" in folder.log_file(study.runs[0]).read_text()
    (folder.run_folder(study.runs[0]) / "notes.txt").unlink()
    assert main(["run", str(tmp_path / "tiny.toml"), "--out", str(out)]) == 0
    assert study_status(out)[1][0].state == "done"
    capsys.readouterr()


#: CMA-ES and a variant of it at another population size, a few thousand env steps each.
VARIANT_STUDY = """
name = "variant"
trainers = ["direct"]
algorithms = ["cmaes", "cmaes-small"]

[variants]
cmaes-small = "cmaes"

[budgets]
steps = { steps = 4_000 }

[options.all]
mazes = ["M1_5x5_C1"]

[options.cmaes-small]
algorithm = { population_size = 6 }
"""


@pytest.mark.slow
def test_a_study_with_a_variant_runs_reports_and_resumes_under_the_variant_s_name(
    tmp_path: Path, capsys
) -> None:
    (tmp_path / "variant.toml").write_text(VARIANT_STUDY)
    out = tmp_path / "study"
    argv = ["run", str(tmp_path / "variant.toml"), "--out", str(out), "--workers", "2"]
    assert main(argv) == 0
    assert main(["report", str(out)]) == 0
    folder = StudyFolder(out)
    base, small = folder.study().runs
    assert (small.id, small.base_algorithm) == ("direct_cmaes-small_steps_seed-0", "cmaes")
    config = json.loads((folder.run_folder(small) / "config.json").read_text())
    assert (config["algo"], config["algorithm"]["population_size"]) == ("cmaes", 6)
    summary = json.loads((folder.run_folder(small) / "summary.json").read_text())
    assert summary["env_steps"] >= 4_000
    with (out / "runs.csv").open() as handle:
        rows = {row["algorithm"]: row for row in csv.DictReader(handle)}
    assert set(rows) == {"cmaes", "cmaes-small"}
    assert rows["cmaes-small"]["treatment"] == "direct/cmaes-small/steps"
    assert rows["cmaes-small"]["folder"] == "runs/direct_cmaes-small_steps_seed-0"
    report = (out / "report.md").read_text()
    assert "CMAES-SMALL" in report
    colours = json.loads((out / "figures" / "colours.json").read_text())
    assert colours["direct/cmaes"] != colours["direct/cmaes-small"]
    # the folder's study.toml is read back: run again, nothing is redone
    assert main(argv) == 0
    assert [s.state for s in study_status(out)[1]] == ["done", "done"]
    for run in (base, small):
        assert folder.log_file(run).read_text().count("started by the study runner") == 1
    capsys.readouterr()


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["run", "no-such-study", "--out", "x"], "no-such-study"),
        (["run", "smoke", "--out", "x", "--workers", "0"], "--workers"),
        (["run", "smoke", "--out", "x", "--address", "head:6379"], "--address"),
        (["run", "smoke", "--out", "x", "--backend", "spark"], "--backend"),
        (["status", "nowhere"], "nowhere"),
        (["report", "nowhere"], "nowhere"),
        (["fly"], "fly"),
    ],
)
def test_bad_commands_give_one_error_line_and_status_2(
    argv: list[str], named: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and named in err[0]
    assert not (tmp_path / "x").exists()


def test_a_study_on_ray_without_ray_is_a_usage_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    assert main(["run", "smoke", "--out", str(tmp_path / "x"), "--backend", "ray"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'amaze-evo[ray]'" in err[0]
    assert not (tmp_path / "x").exists()
