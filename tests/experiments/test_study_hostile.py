"""Studies given hostile input: odd study files, damaged runner records and run files, two runners.

Each mistake ends in one ``error:`` line naming the file or the value and
exit status 2 (or, in a report, in the run's part left out with a warning,
or an odd figure of a summary in an empty cell), never a traceback; a
runner killed outright leaves no worker behind, and a folder whose runner
or worker still lives is refused. Hostile values: NaN, infinities, ``1e308``,
integers of hundreds or thousands of digits, values of the wrong type,
control characters, files of gigabytes (sparse), and text a spreadsheet
would run as a formula (``=HYPERLINK(...)``), which the report's CSV files
write as text.
"""

from __future__ import annotations

import contextlib
import csv
import fcntl
import io
import json
import os
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from amaze.runs.folder import write_json
from amaze.runs.lifecycle import CONFIG_FILE
from experiments import study as study_module
from experiments.cli import main
from experiments.report import write_report
from experiments.report_runs import FORMULA_STARTS, spreadsheet_cell
from experiments.runner import (
    LOCK_FILE,
    MAX_PROGRESS_BYTES,
    STATE_FILE,
    STUDY_FILE,
    StudyFolder,
    study_status,
)
from experiments.study import (
    MAX_BUDGET_STEPS,
    MAX_DEPTH,
    MAX_RUNS,
    MAX_SEED,
    MAX_STUDY_BYTES,
    StudyError,
    parse_study,
)
from experiments.worker import main as worker_main
from tests.experiments.synthetic import evaluation_rows, make_study, write_evaluations
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


#: A number of 400 digits (beyond any float) and one of 5000 (beyond what Python converts).
HUGE, HUGER = "1" + "0" * 400, "1" + "0" * 5000


def _with(change: str, text: str = STUDY) -> str:
    """``text`` with ``change`` (``old => new``) made, which must apply."""
    old, new = change.split(" => ")
    assert old in text, old
    return text.replace(old, new, 1)


@pytest.mark.parametrize(
    ("change", "named"),
    [
        pytest.param(f"seeds = 1 => seeds = {HUGER}", "not valid TOML", id="int-5000-digits"),
        pytest.param(f"seeds = 1 => seeds = {HUGE}", "seeds 1000000", id="seeds-400-digits"),
        pytest.param(f"seeds = 1 => seeds = [{HUGE}]", "seed 1000000", id="seed-400-digits"),
        pytest.param("seeds = 1 => seeds = nan", "seeds nan", id="seeds-nan"),
        pytest.param("seeds = 1 => seeds = '3'", "seeds '3'", id="seeds-text"),
        pytest.param("seeds = 1 => seeds = 1979-05-27", "seeds datetime", id="seeds-date"),
        pytest.param("seconds = 3 => seconds = nan", "budget_seconds nan", id="seconds-nan"),
        pytest.param("seconds = 3 => seconds = -inf", "budget_seconds -inf", id="seconds-inf"),
        pytest.param("seconds = 3 => seconds = 1e400", "budget_seconds inf", id="seconds-1e400"),
        pytest.param(f"seconds = 3 => seconds = {HUGE}", "budget_seconds 1000", id="seconds-400"),
        pytest.param(
            f"seconds = 3 => steps = {MAX_BUDGET_STEPS + 1}", "steps 9007199254740993", id="steps"
        ),
        pytest.param(f"seconds = 3 => steps = {HUGE}", "steps 1000000", id="steps-400-digits"),
        pytest.param("seconds = 3 => steps = '1000'", "budget_steps '1000'", id="steps-text"),
        pytest.param(
            "checkpoint_seconds = 0.2 => checkpoint_seconds = nan",
            "checkpoint_seconds nan",
            id="option-nan",
        ),
        pytest.param('name = "tiny" => name = 10', "name 10", id="name-number"),
        pytest.param('name = "tiny" => name = "a\\u001b[2Jb"', r"name 'a\x1b[2Jb'", id="name-esc"),
        pytest.param('name = "tiny" => name = "a\\u0000b"', r"name 'a\x00b'", id="name-nul"),
        pytest.param('name = "tiny" => name = "a\\u202eb"', r"name 'a\u202eb'", id="name-bidi"),
        pytest.param(f'name = "tiny" => name = "{"n" * 201}"', "longer than 200", id="name-long"),
        pytest.param(
            'description = "One => description = "\\u001b[31mOne',
            r"description '\x1b[31mOne",
            id="description-esc",
        ),
        pytest.param('name = "tiny" => "\\u001b[2J" = 1', r"key(s) '\x1b[2J'", id="key-esc"),
        pytest.param("clock = { => -A1 = {", "budget name '-A1'", id="budget-dash"),
        pytest.param('clock = { => "ⅫⅫ" = {', "budget name 'ⅫⅫ'", id="budget-roman"),
        pytest.param(f"clock = {{ => {'b' * 300} = {{", "budget name 'bbb", id="budget-long"),
        pytest.param(
            '[options.cmaes] => [options."\\u001b[2J"]', r"options.'\x1b[2J'", id="options-esc"
        ),
    ],
)
def test_a_hostile_value_in_a_study_file_is_one_error_naming_it(
    change: str, named: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "hostile.toml"
    path.write_text(_with(change), encoding="utf-8")
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    error = one_error(capsys)
    assert "hostile.toml" in error and named in error, error
    assert error.isprintable() and len(error) < 1000  # no control character, no huge value
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("title", "named"),
    [
        ('"\\u001b[2J"', r"title '\x1b[2J'"),
        ('"a\\tb"', r"title 'a\tb'"),
        (f'"{"t" * 201}"', "longer than 200"),
        ("5", "title 5"),
    ],
    ids=["esc", "tab", "long", "number"],
)
def test_a_hostile_comparison_title_is_refused_by_name(title: str, named: str) -> None:
    text = STUDY + f'[[comparisons]]\nname = "c"\ntitle = {title}\ntreatments = ["direct/cmaes"]\n'
    with pytest.raises(StudyError, match="comparison 'c'") as problem:
        parse_study(text, "study file 'x.toml'")
    assert named in str(problem.value)


@pytest.mark.parametrize(
    "name", ["-x", "=1", "a b", "é", "x" * 65], ids=["dash", "formula", "space", "accent", "long"]
)
def test_a_comparison_name_is_a_short_ascii_name(name: str) -> None:
    text = STUDY + f'[[comparisons]]\nname = "{name}"\ntreatments = ["direct/cmaes"]\n'
    with pytest.raises(StudyError, match="is not made of letters, digits and dashes"):
        parse_study(text)


def test_a_multi_line_description_is_text() -> None:
    text = _with('description = "One short CMA-ES runs." => description = """a\n\tb\r\nc"""')
    assert parse_study(text).description == "a\n\tb\nc"


@pytest.mark.parametrize("size", [MAX_STUDY_BYTES + 1, 2**30], ids=["just-over", "1-GiB"])
def test_a_study_file_too_large_is_refused_before_it_is_read(
    size: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "large.toml"
    with path.open("wb") as handle:
        handle.write(STUDY.encode() + b"#")
        handle.truncate(size)  # sparse: the rest reads as zero bytes
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    error = one_error(capsys)
    assert "large.toml" in error and f"{MAX_STUDY_BYTES:,} bytes" in error


def test_a_run_config_error_listing_thousands_of_keys_is_cut_short(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    keys = "".join(f"k{i} = 1\n" for i in range(30_000))
    path = tmp_path / "keys.toml"
    path.write_text(STUDY + keys)
    assert len(path.read_bytes()) < MAX_STUDY_BYTES
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    error = one_error(capsys)
    assert "keys.toml" in error and "k0" in error and len(error) < 1000


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
        ('{"wall_seconds": {"a": NaN}}', "wall_seconds holds nan"),
        ('{"wall_seconds": {"a": Infinity}}', "wall_seconds holds inf"),
        ('{"wall_seconds": {"a": 1e400}}', "wall_seconds holds inf"),
        ('{"wall_seconds": {"a": -1}}', "wall_seconds holds -1"),
        (f'{{"wall_seconds": {{"a": {HUGE}}}}}', "wall_seconds holds 1000"),
        (f'{{"threads": {{"a": {HUGE}}}}}', "threads holds 1000"),
        (f'{{"threads": {{"a": {HUGER}}}}}', "state.json"),
        ('{"threads": {"a": -2}}', "threads holds -2"),
    ],
)
@pytest.mark.parametrize("command", ["status", "run", "report"])
def test_a_damaged_runner_state_is_one_error(
    state: str, named: str, command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "study"
    out.mkdir()
    (out / STUDY_FILE).write_text(STUDY)
    (tmp_path / "tiny.toml").write_text(STUDY)
    (out / STATE_FILE).write_text(state)
    argv = [command, str(out)] if command != "run" else ["run", str(tmp_path / "tiny.toml")]
    assert main(argv + (["--out", str(out)] if command == "run" else [])) == 2
    error = one_error(capsys)
    assert named in error and "state.json" in error
    assert len(error) < 1000
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


@pytest.mark.slow
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


# -- the report over hostile run files -----------------------------------------------------------

#: A study whose name a spreadsheet would run as a formula.
FORMULA_STUDY = _with(
    'name = "tiny" => name = "=HYPERLINK(\\"x\\")"',
    STUDY.replace("clock = { seconds = 3 }", "steps = { steps = 1000 }"),
)
#: Odd figures of a summary (key, JSON value), the runs.csv column of each and its cell:
#: empty, or for an odd budget_spent the share computed from env_steps (1000 of 1000).
ODD_FIGURES = [
    ("success_rate", "NaN", "success_rate", ""),
    ("success_rate", "Infinity", "success_rate", ""),
    ("normalized_reward", "-Infinity", "normalized_reward", ""),
    ("normalized_reward", "1e308", "normalized_reward", ""),
    ("seconds", "-1e308", "seconds", ""),
    ("input_recognition", HUGE, "input_recognition", ""),
    ("success_rate", '"0.5"', "success_rate", ""),
    ("normalized_reward", "[1, 2]", "normalized_reward", ""),
    ("seconds", '{"a": 1}', "seconds", ""),
    ("success_rate", "true", "success_rate", ""),
    ("budget_spent", '{"steps": 1e400}', "budget_spent", "1.0"),
    ("budget_spent", f'{{"steps": {HUGE}}}', "budget_spent", "1.0"),
    ("input_rates", '{"lure": 1e308}', "input_lure", ""),
    ("advice", f'{{"mazes_kept_share": -{HUGE}}}', "advice_mazes_kept", ""),
    ("stopped_early", '["a"]', "stopped_early", ""),
    ("stopped_early", "1e308", "stopped_early", ""),
]
#: Values of env_steps that leave a run's row out.
ODD_STEPS = ["NaN", "Infinity", "1e308", HUGE, '"1000"', "-1", "null", "[1000]"]
#: Text a spreadsheet would run as a formula, as a summary's stopped_early.
FORMULAS = ['=HYPERLINK("x")', "+cmd|' /C calc'!A0", "@SUM(1)", "-2+3", "\tx", "\rx", "=1+2\n"]
#: Text whose line breaks must not end its row (a CR there would start a row with =).
BROKEN_LINES = ["ok\r=1+2", "ok\r\n@SUM(1)", "ok\n-2+3"]
#: Hostile evaluations.csv rows: each leaves the run's evaluations out.
HOSTILE_DIGESTS = ['=HYPERLINK("x")', "+cmd|' /C calc'!A0", "@SUM(1)", "-2+3", "a\x1b[2J", "a" * 99]
HOSTILE_VALUES = [("success_rate", "1e308"), ("env_steps", HUGE), ("normalized_reward", "inf")]


def _good_summary(run) -> dict:
    return {
        "env_steps": 1000,
        "seconds": 2.0,
        "success_rate": 0.25 * (run.seed % 4),
        "normalized_reward": -1.5 + run.seed / 10,  # negative numbers stay numbers
        "input_recognition": 0.5,
        "input_rates": {"empty": 1.0, "lure": 0.5, "clue": 0.5, "trap": 0.0},
    }


def _raw_summary(run, key: str, value: str) -> str:
    """``run``'s good summary as JSON text, with ``key`` set to the JSON text ``value``."""
    good = json.dumps({k: v for k, v in _good_summary(run).items() if k != key})
    return good[:-1] + f', "{key}": {value}}}'


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


@pytest.fixture(scope="module")
def hostile_report(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """One report over runs of one treatment, each with one hostile file, and what it printed.

    Seeds in order: :data:`ODD_FIGURES`, :data:`ODD_STEPS`, :data:`FORMULAS` (each a
    summary), the hostile digests and values (each an evaluations.csv), two good runs.
    """
    kinds: list[tuple[str, object]] = [
        *(("figure", item) for item in ODD_FIGURES),
        *(("steps", item) for item in ODD_STEPS),
        *(("formula", item) for item in FORMULAS),
        *(("lines", item) for item in BROKEN_LINES),
        *(("digest", item) for item in HOSTILE_DIGESTS),
        *(("value", item) for item in HOSTILE_VALUES),
        ("good", None),
        ("good", None),
    ]
    text = FORMULA_STUDY.replace("seeds = 1", f"seeds = {len(kinds)}")
    runs = parse_study(text).runs

    def evaluations(run) -> list[dict]:
        return evaluation_rows([0.1, 0.2], [-0.5, 0.5], [500, 1000], [1.0, 2.0])

    out = tmp_path_factory.mktemp("hostile-report") / "study"
    folder = make_study(out, text, _good_summary, evaluations)
    for run, (kind, item) in zip(runs, kinds, strict=True):
        summary = folder.run_folder(run) / "summary.json"
        if kind == "figure":
            summary.write_text(_raw_summary(run, item[0], item[1]))
        elif kind == "steps":
            summary.write_text(_raw_summary(run, "env_steps", item))
        elif kind in ("formula", "lines"):
            summary.write_text(_raw_summary(run, "stopped_early", json.dumps(item)))
        elif kind == "digest":
            rows = evaluation_rows([0.1], [0.0], [1000], [1.0], digest=item)
            write_evaluations(folder.run_folder(run) / "evaluations.csv", rows)
        elif kind == "value":
            rows = evaluation_rows([0.1], [0.0], [1000], [1.0])
            rows[0][item[0]] = item[1]
            write_evaluations(folder.run_folder(run) / "evaluations.csv", rows)
    err = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stderr(err):
        warnings.simplefilter("error", RuntimeWarning)  # no overflow in a mean or an axis
        status = main(["report", str(out)])
    return {"status": status, "out": out, "runs": runs, "kinds": kinds, "err": err.getvalue()}


def _csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_a_report_over_hostile_run_files_says_what_it_left_out(hostile_report: dict) -> None:
    assert hostile_report["status"] == 0
    err = hostile_report["err"].strip().splitlines()
    left = [kind for kind, _ in hostile_report["kinds"] if kind in ("steps", "digest", "value")]
    assert len(err) == len(left), err
    assert all(line.startswith("warning: run ") for line in err)
    assert all(line.isprintable() and len(line) < 1000 for line in err)
    report = (hostile_report["out"] / "report.md").read_text()
    for run, (kind, _) in zip(hostile_report["runs"], hostile_report["kinds"], strict=True):
        assert (f"`{run.id}`" in report) == (kind in ("steps", "digest", "value")), run.id


def test_odd_figures_of_a_summary_are_empty_cells(hostile_report: dict) -> None:
    rows = {row["seed"]: row for row in _csv(hostile_report["out"] / "runs.csv")}
    for run, (kind, item) in zip(hostile_report["runs"], hostile_report["kinds"], strict=True):
        if kind == "steps":
            assert str(run.seed) not in rows  # its row left out
        elif kind == "figure":
            row = rows[str(run.seed)]
            assert row[item[2]] == item[3], (item, row[item[2]])
            assert row["env_steps"] == "1000" and row["success_rate"] != "inf"
        elif kind in ("digest", "value"):
            row = rows[str(run.seed)]
            assert row["evaluation_set"] == "" and row["eval_set_success_rate"] == ""


def test_text_from_run_files_is_no_formula_in_the_csv_files(hostile_report: dict) -> None:
    runs = _csv(hostile_report["out"] / "runs.csv")
    tests = _csv(hostile_report["out"] / "tests.csv")
    for row in runs + tests:
        for column, cell in row.items():
            if cell.startswith(FORMULA_STARTS):  # only numbers may: -1.5 is a number
                assert _is_number(cell), (column, cell)
    by_seed = {row["seed"]: row for row in runs}
    assert all(row["study"] == "'" + '=HYPERLINK("x")' for row in runs)
    for run, (kind, item) in zip(hostile_report["runs"], hostile_report["kinds"], strict=True):
        one_line = item.replace("\r", " ").replace("\n", " ") if isinstance(item, str) else ""
        if kind == "formula":
            assert by_seed[str(run.seed)]["stopped_early"] == "'" + one_line
        elif kind == "lines":  # the line breaks are spaces: no row starts with "=1+2"
            assert by_seed[str(run.seed)]["stopped_early"] == one_line
    assert any(row["normalized_reward"].startswith("-") for row in runs)


@pytest.mark.parametrize(
    ("value", "cell"),
    [
        ('=HYPERLINK("x")', '\'=HYPERLINK("x")'),
        ("+cmd|' /C calc'!A0", "'+cmd|' /C calc'!A0"),
        ("@SUM(1)", "'@SUM(1)"),
        ("-2+3", "'-2+3"),
        ("\t=1", "'\t=1"),
        ("\r=1", "' =1"),
        ("a\r\n=1", "a  =1"),
        ("plain", "plain"),
        ("", ""),
        (-2, -2),
        (-2.5, -2.5),
        (float("nan"), ""),
        (float("-inf"), float("-inf")),
    ],
    ids=repr,
)
def test_a_spreadsheet_cell_is_text_or_a_number(value: object, cell: object) -> None:
    assert spreadsheet_cell(value) == cell


@pytest.mark.parametrize("name", ["summary.json", "evaluations.csv"])
def test_a_run_file_of_a_gigabyte_is_left_out_unread(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = STUDY.replace("seeds = 1", "seeds = 2")
    folder = finished_study(tmp_path / "study", text)
    run = parse_study(text).runs[0]
    with (folder.run_folder(run) / name).open("wb") as handle:
        handle.truncate(2**30)  # sparse
    assert main(["report", str(folder.out)]) == 0
    warnings_printed = capsys.readouterr().err.strip().splitlines()
    assert len(warnings_printed) == 1 and name in warnings_printed[0]
    assert "bytes" in warnings_printed[0] and run.id in warnings_printed[0]


# -- status over hostile progress logs -----------------------------------------------------------

#: progress.csv contents of an interrupted run of a steps budget of 1000.
HOSTILE_PROGRESS = [
    b"steps,seconds\nNaN,1\n",
    b"steps,seconds\ninf,1\n",
    b"steps,seconds\n-inf,1\n",
    b"steps,seconds\n1e308,1\n",
    b"steps,seconds\n" + HUGER.encode() + b",1\n",
    b'steps,seconds\n=HYPERLINK("x"),1\n',
    b"steps,seconds\n500\n",  # a short row
    b"steps\n" + b"9" * 200_000 + b"\n",  # a field over the csv module's limit
    b"garbage\x00\xff",
    b"",
]


@pytest.mark.parametrize(
    "log",
    HOSTILE_PROGRESS,
    ids=["nan", "inf", "-inf", "1e308", "5001-digits", "formula", "short", "long", "bytes", "none"],
)
def test_a_hostile_progress_log_is_some_share_of_the_budget(
    log: bytes, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = STUDY.replace("clock = { seconds = 3 }", "steps = { steps = 1000 }")
    folder = finished_study(tmp_path / "study", text)
    run = parse_study(text).runs[0]
    run_folder = folder.run_folder(run)
    (run_folder / "summary.json").unlink()
    write_json(run_folder / CONFIG_FILE, run.config)
    (run_folder / "progress.csv").write_bytes(log)
    [status] = study_status(folder.out)[1]
    assert status.state == "interrupted"
    share = int(status.detail.split(" %")[0])
    assert 0 <= share <= 100
    assert main(["status", str(folder.out)]) == 0
    capsys.readouterr()


def test_a_progress_log_of_a_gigabyte_is_read_from_its_end(tmp_path: Path) -> None:
    text = STUDY.replace("clock = { seconds = 3 }", "steps = { steps = 1000 }")
    folder = finished_study(tmp_path / "study", text)
    run = parse_study(text).runs[0]
    run_folder = folder.run_folder(run)
    (run_folder / "summary.json").unlink()
    write_json(run_folder / CONFIG_FILE, run.config)
    path = run_folder / "progress.csv"
    with path.open("wb") as handle:
        handle.write(b"steps,seconds\n100,1\n")
        handle.truncate(2**30)  # sparse zeros, then the last row
        handle.seek(0, os.SEEK_END)
        handle.write(b"\n250,2\n")
    assert path.stat().st_size > MAX_PROGRESS_BYTES
    [status] = study_status(folder.out)[1]
    assert status.detail == "25 %, resumes"
