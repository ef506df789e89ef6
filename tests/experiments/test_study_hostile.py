"""Studies given hostile input: odd study files, damaged runner records and run files, two runners.

Each mistake ends in one ``error:`` line naming the file or the value and
exit status 2 (or, in a report, in the run's part left out with a warning),
never a traceback; a runner killed outright leaves no worker behind, and a
folder whose runner or worker still lives is refused.
"""

from __future__ import annotations

import csv
import fcntl
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from amaze.runs.folder import write_json
from experiments import study as study_module
from experiments.cli import main
from experiments.report import write_report
from experiments.runner import LOCK_FILE, STATE_FILE, STUDY_FILE, StudyFolder, study_status
from experiments.study import MAX_DEPTH, MAX_RUNS, MAX_SEED, StudyError, parse_study
from experiments.worker import main as worker_main
from tests.experiments.test_runner import STUDY as RUNNER_STUDY
from tests.processes import process_running, wait_until

ROOT = Path(__file__).resolve().parents[2]
#: One short CMA-ES run (never trained here but by the runner tests).
STUDY = RUNNER_STUDY.replace("seeds = 3", "seeds = 1").replace("Three", "One")


def one_error(capsys: pytest.CaptureFixture[str]) -> str:
    """The one line the command printed on standard error, which must be an ``error:`` line."""
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


def finished_study(out: Path, text: str = STUDY) -> StudyFolder:
    """A study folder whose runs all hold a summary (so ``run`` starts no worker)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / STUDY_FILE).write_text(text)
    folder = StudyFolder(out)
    for run in parse_study(text).runs:
        write_json(folder.run_folder(run) / "summary.json", {"env_steps": 10, "success_rate": 1})
    return folder


# -- the study file ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "nested",
    [
        pytest.param("[" * 5000 + "]" * 5000, id="beyond-the-parser"),
        pytest.param("[" * 300 + "]" * 300, id="beyond-what-walks-it"),
        pytest.param("{a = " * 300 + "1" + "}" * 300, id="tables"),
        pytest.param("[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1), id="one-too-many"),
    ],
)
def test_a_deeply_nested_study_is_one_error(
    nested: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "nested.toml"
    path.write_text(STUDY + f"[options.all]\nx = {nested}\n")
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    assert f"nest more than {MAX_DEPTH} deep" in one_error(capsys)
    assert not (tmp_path / "out").exists()


def test_a_study_file_that_is_not_utf8_is_one_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "latin.toml"
    path.write_bytes(STUDY.replace("short", "sh\xf6rt").encode("latin-1"))
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "latin.toml" in one_error(capsys)


@pytest.mark.parametrize(
    ("seeds", "named"),
    [
        (f"[{MAX_SEED + 1}]", f"seed {MAX_SEED + 1}"),
        ("[3, 18446744073709551616]", "seed 18446744073709551616"),
        ("[-1]", "seed -1"),
    ],
)
def test_seeds_beyond_32_bits_are_refused_when_the_study_is_read(seeds: str, named: str) -> None:
    with pytest.raises(StudyError, match=named):
        parse_study(STUDY.replace("seeds = 1", f"seeds = {seeds}"), "study file 'x.toml'")


def test_the_largest_seed_is_a_seed() -> None:
    study = parse_study(STUDY.replace("seeds = 1", f"seeds = [{MAX_SEED}]"))
    assert study.runs[0].config["seed"] == MAX_SEED


def test_a_study_too_large_is_refused_before_a_run_is_built(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def built(*args: object) -> None:
        raise AssertionError("a run was built")

    monkeypatch.setattr(study_module, "_config", built)
    budgets = "\n".join(f"b{i} = {{ steps = {1000 * (i + 1)} }}" for i in range(8))
    text = f"""
name = "huge"
seeds = 1000
trainers = ["direct", "interpolation", "edhucat-careful", "edhucat-moderate",
            "edhucat-risky", "edhucat-random"]
algorithms = ["ppo", "cmaes"]
[budgets]
{budgets}
"""
    with pytest.raises(StudyError) as problem:
        parse_study(text, "study file 'huge.toml'")
    message = str(problem.value)
    assert "96,000 runs" in message and f"{MAX_RUNS:,}" in message and "huge.toml" in message


@pytest.mark.parametrize(
    ("trainer", "options", "named"),
    [
        ("edhucat-careful", "{ colour = 'red' }", "colour"),
        ("edhucat-risky", "{ unfair = 2 }", "unfair"),
        ("edens", "{ validation = 0 }", "validation"),
        ("edhucat-follow-edens", "{ p = 3 }", "follow p 3"),
        ("edhucat-follow-edens", "{ base = 'human' }", "base 'human'"),
    ],
)
def test_curator_options_are_checked_when_the_study_is_read(
    trainer: str, options: str, named: str
) -> None:
    text = STUDY.replace('["direct"]', f'["{trainer}"]').replace('mazes = ["M1_5x5_C1"]', "")
    text += f'[options."{trainer}"]\ncurator_options = {options}\n'
    parse_study(text.replace(options, "{}"))  # the same study with no options is good
    with pytest.raises(StudyError) as problem:
        parse_study(text, "study file 'x.toml'")
    message = str(problem.value)
    assert f"run {trainer}_cmaes_clock_seed-0" in message and named in message


def test_an_advisors_options_are_checked_when_the_study_is_read() -> None:
    trainer = "edhucat-follow-edens"
    text = STUDY.replace('["direct"]', f'["{trainer}"]').replace('mazes = ["M1_5x5_C1"]', "")
    parse_study(text)  # follow with its advisor, edens: good
    bad = text + f'[options."{trainer}"]\nadvisor_options = {{ colour = "red" }}\n'
    with pytest.raises(StudyError) as problem:
        parse_study(bad, "study file 'x.toml'")
    message = str(problem.value)
    assert f"run {trainer}_cmaes_clock_seed-0: advisor: advisor 'edens'" in message
    assert "colour" in message


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ('trainers = [["direct"]]', "trainers"),
        ("algorithms = [{ a = 1 }]", "algorithms"),
        ("[[exclude]]\ntrainer = ['direct']\nalgorithm = 'cmaes'", "exclude"),
    ],
)
def test_values_of_the_wrong_type_are_refused_by_name(change: str, named: str) -> None:
    key = change.split("=")[0].strip()
    kept = "\n".join(line for line in STUDY.splitlines() if not line.startswith(f"{key} "))
    text = kept + "\n" + change + "\n" if change.startswith("[") else change + "\n" + kept
    with pytest.raises(StudyError, match=named):
        parse_study(text, "study file 'x.toml'")


# -- the runner's records ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("state", "named"),
    [
        ("null", "JSON object"),
        ("[]", "JSON object"),
        ('{"runner": "x"}', "runner 'x'"),
        ('{"failed": []}', "failed []"),
        ('{"wall_seconds": {"a": "soon"}}', "wall_seconds"),
        ('{"threads": {"a": true}}', "threads"),
        ('{"running": 5}', "running 5"),
        pytest.param("[" * 100_000, "state.json", id="deep"),
        ("{", "state.json"),
    ],
)
@pytest.mark.parametrize("command", ["status", "run"])
def test_a_damaged_runner_state_is_one_error(
    state: str, named: str, command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "study"
    out.mkdir()
    (out / STUDY_FILE).write_text(STUDY)
    (tmp_path / "tiny.toml").write_text(STUDY)
    (out / STATE_FILE).write_text(state)
    argv = ["status", str(out)] if command == "status" else ["run", str(tmp_path / "tiny.toml")]
    assert main(argv + (["--out", str(out)] if command == "run" else [])) == 2
    error = one_error(capsys)
    assert named in error and "state.json" in error
    assert not (out / "runs").exists()


def test_a_failure_of_a_run_finished_since_is_forgotten(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = finished_study(tmp_path / "study")
    run_id = parse_study(STUDY).runs[0].id
    stale = {"runner": None, "running": [], "failed": {run_id: {"status": 1, "time": "then"}}}
    write_json(folder.out / STATE_FILE, {**stale, "wall_seconds": {}, "threads": {}})
    _, statuses = study_status(folder.out)
    assert [s.state for s in statuses] == ["done"]
    (tmp_path / "tiny.toml").write_text(STUDY)
    # status and run agree: nothing failed
    assert main(["run", str(tmp_path / "tiny.toml"), "--out", str(folder.out)]) == 0
    assert json.loads((folder.out / STATE_FILE).read_text())["failed"] == {}
    capsys.readouterr()


def test_a_failed_run_is_named_by_run_and_by_status(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = STUDY.replace("seeds = 1", "seeds = 2")
    folder = finished_study(tmp_path / "study", text)
    done, failed = parse_study(text).runs
    (folder.run_folder(failed) / "summary.json").unlink()
    (folder.run_folder(failed) / "notes.txt").write_text("in the way")  # its trainer refuses it
    (tmp_path / "tiny.toml").write_text(text)
    assert main(["run", str(tmp_path / "tiny.toml"), "--out", str(folder.out)]) == 1
    printed = capsys.readouterr().out
    assert f"failed: {failed.id}" in printed and f"failed: {done.id}" not in printed
    assert main(["status", str(folder.out)]) == 0
    assert f"failed: {failed.id}" in capsys.readouterr().out


# -- one runner at a time, and no worker without its runner --------------------------------------


def hold_lock(out: Path, pid: int) -> subprocess.Popen:
    """A process that holds ``out``'s lock, as a worker of the (dead) runner ``pid`` would."""
    fd = os.open(out / LOCK_FILE, os.O_RDWR | os.O_CREAT)
    os.write(fd, json.dumps({"pid": pid, "start": 1, "started": "then"}).encode())
    fcntl.flock(fd, fcntl.LOCK_EX)
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"], pass_fds=(fd,))
    os.close(fd)  # the holder's copy keeps the lock
    return holder


def test_a_folder_locked_by_a_live_worker_is_refused_then_taken_when_it_is_gone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = finished_study(tmp_path / "study")
    (tmp_path / "tiny.toml").write_text(STUDY)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    holder = hold_lock(folder.out, dead.pid)
    try:
        argv = ["run", str(tmp_path / "tiny.toml"), "--out", str(folder.out)]
        assert main(argv) == 2
        error = one_error(capsys)
        assert str(folder.out) in error and "gone" in error and str(dead.pid) in error
    finally:
        holder.kill()
        holder.wait()
    assert main(argv) == 0  # the lock of processes that are gone is taken
    capsys.readouterr()


def test_a_runner_killed_outright_takes_its_workers_with_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = STUDY.replace("seconds = 3", "seconds = 120")
    (tmp_path / "long.toml").write_text(study)
    out = tmp_path / "study"
    command = [sys.executable, "-m", "experiments.cli", "run", str(tmp_path / "long.toml")]
    command += ["--out", str(out), "--workers", "1"]
    environment = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    runner = subprocess.Popen(command, cwd=ROOT, env=environment, stdout=subprocess.DEVNULL)
    folder = StudyFolder(out)
    run = parse_study(study).runs[0]
    log = folder.log_file(run)
    try:
        wait_until(lambda: (folder.run_folder(run) / "config.json").is_file(), timeout=60)
        worker = int(log.read_text().split("worker process ")[1].split()[0])
        assert process_running(worker)
        # a second runner while the first one works is refused
        assert main(["run", str(tmp_path / "long.toml"), "--out", str(out)]) == 2
        error = one_error(capsys)
        assert f"being run by process {runner.pid}" in error
        assert [s.state for s in study_status(out)[1]] == ["running"]
    finally:
        runner.send_signal(signal.SIGKILL)
        runner.wait()
    wait_until(lambda: not process_running(worker), timeout=10)
    # the lock goes with the worker's last thread, a moment after its main one
    wait_until(lambda: study_status(out)[1][0].state == "interrupted", timeout=10)


def test_a_worker_refuses_a_run_folder_another_process_trains_in(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = parse_study(STUDY).runs[0]
    write_json(tmp_path / "config.json", run.config)
    out = tmp_path / "run"
    out.mkdir()
    fd = os.open(out, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        argv = ["--config", str(tmp_path / "config.json"), "--out", str(out)]
        assert worker_main(argv) == 2
    finally:
        os.close(fd)
    assert str(out) in one_error(capsys)
    assert list(out.iterdir()) == []


# -- the report ----------------------------------------------------------------------------------

#: What is written in place of each run's summary (seed k gets the k-th).
DAMAGED_SUMMARIES = [
    b'{"env_steps": 5, "success_rate": 0.5',  # truncated
    b"",
    b"[1, 2]",
    b'{"success_rate": 0.5}',  # no env_steps
    b"\xef\xbb\xbf{}",  # a byte-order mark
    b"[" * 100_000,  # nested too deep
]
#: What is written as the readable runs' anytime evaluations (evaluations.csv).
DAMAGED_LOGS = [
    b"garbage\x00\xff",
    b"point,fraction,env_steps\nabc,def,1\n",  # not numbers, and columns missing
    b"a,b\n1,2\n",
    b"point\n" + b"1\n" * 10 + b"99999999999\n",  # points that do not increase, a huge one
]


def test_a_report_leaves_out_what_it_cannot_read_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    count = len(DAMAGED_SUMMARIES) + len(DAMAGED_LOGS) + 1
    text = STUDY.replace("seeds = 1", f"seeds = {count}")
    folder = finished_study(tmp_path / "study", text)
    runs = parse_study(text).runs
    for run, damage in zip(runs, DAMAGED_SUMMARIES, strict=False):
        (folder.run_folder(run) / "summary.json").write_bytes(damage)
    for run, damage in zip(runs[len(DAMAGED_SUMMARIES) :], DAMAGED_LOGS, strict=False):
        (folder.run_folder(run) / "evaluations.csv").write_bytes(damage)
    assert main(["report", str(folder.out)]) == 0
    warnings = capsys.readouterr().err.strip().splitlines()
    assert len(warnings) == len(DAMAGED_SUMMARIES) + len(DAMAGED_LOGS)
    assert all(line.startswith("warning: run ") for line in warnings)
    report = (folder.out / "report.md").read_text()
    assert "## Left out" in report
    for run in runs[:-1]:
        assert f"`{run.id}`" in report
    with (folder.out / "runs.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == count - len(DAMAGED_SUMMARIES)


def test_a_report_without_damage_says_nothing_is_left_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = finished_study(tmp_path / "study")
    write_report(folder.out, warn=lambda message: pytest.fail(message))
    assert "Left out" not in (folder.out / "report.md").read_text()
    capsys.readouterr()
