"""Evolution runs: run folder, budgets, config errors, the CLI, and resume after a real kill."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from amaze.runs.anytime import EVALUATION_FIELDS
from amaze.runs.checkpoint import read_checkpoint
from amaze.runs.command import Terminated
from amaze.runs.folder import ProgressLog
from evolution import EvolutionConfigError
from evolution.agent_file import load_agent, read_agent
from evolution.checkpoint import evolution_codec
from evolution.cli import main
from evolution.run import EvolutionRun, EvolveConfig, _State, evolve, resume

SMALL_MAZES = ["M0_5x5_U", "M1_5x5_C1"]
ROOT = Path(__file__).resolve().parents[2]


def _config(algo: str, **overrides: object) -> dict:
    algorithm = {"population_size": 16}
    config = {
        "algo": algo,
        "mazes": SMALL_MAZES,
        "budget_steps": None,
        "max_generations": 4,
        "algorithm": algorithm,
    }
    config.update(overrides)
    return config


def _rows(out: Path) -> list[dict[str, str]]:
    lines = (out / "progress.csv").read_text().splitlines()
    header = lines[0].split(",")
    return [dict(zip(header, line.split(","), strict=True)) for line in lines[1:]]


def _without_time(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    timing = (
        "seconds",
        "eval_seconds",
        "training_seconds",
        "elapsed_seconds",
        "evaluation_seconds",
    )
    return [{k: v for k, v in r.items() if k not in timing} for r in rows]


def _evaluations(out: Path) -> list[dict[str, str]]:
    return ProgressLog(out / "evaluations.csv", EVALUATION_FIELDS).rows()


@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_run_folder(tmp_path: Path, algo: str) -> None:
    out = tmp_path / "run"
    result = evolve(_config(algo), out)
    for name in ("config.json", "progress.csv", "agent.npz", "summary.json", "fitness.png"):
        assert (out / name).stat().st_size > 0, name
    state = read_checkpoint(
        out / "checkpoints" / "state.npz", evolution_codec(_State), EvolutionConfigError, object
    )
    assert state.generation == 4 and state.steps == result.env_steps  # the last one is saved
    assert len(list((out / "trajectories").glob("*.png"))) == 4
    rows = _rows(out)
    assert [int(r["generation"]) for r in rows] == [1, 2, 3, 4]
    steps = [int(r["steps"]) for r in rows]
    assert steps == sorted(steps) and steps[-1] == result.env_steps
    champions = [float(r["champion"]) for r in rows]
    assert champions == sorted(champions)  # the best so far never decreases
    assert champions[-1] == pytest.approx(result.summary["champion_fitness"])
    assert max(float(r["best"]) for r in rows) == pytest.approx(result.summary["champion_fitness"])
    summary = json.loads((out / "summary.json").read_text())
    for key in ("success_rate", "normalized_reward", "input_recognition", "env_steps", "seconds"):
        assert key in summary
    assert summary["env_steps"] == result.env_steps and summary["generations"] == 4
    # the agent file is a self-contained agent whose training fitness is recorded
    assert summary["agent"] == "agent.npz" and summary["agent_rule"] == "best-fitness"
    _, metadata = read_agent(out / "agent.npz")
    assert metadata["fitness"] == pytest.approx(result.summary["champion_fitness"])
    assert metadata["mazes"] == SMALL_MAZES and metadata["algorithm"] == algo
    assert load_agent(out / "agent.npz").robot.to_string() == "DD"


def test_seconds_budget(tmp_path: Path) -> None:
    config = _config("neat", budget_seconds=0.5, max_generations=None)
    result = evolve(config, tmp_path / "r")
    assert result.seconds >= 0.5 and result.summary["generations"] >= 1


def test_same_seed_same_run_and_refusal_to_overwrite(tmp_path: Path) -> None:
    first = evolve(_config("cmaes"), tmp_path / "a")
    second = evolve(_config("cmaes"), tmp_path / "b")
    assert _without_time(_rows(tmp_path / "a")) == _without_time(_rows(tmp_path / "b"))
    assert first.summary["champion_fitness"] == second.summary["champion_fitness"]
    with pytest.raises(EvolutionConfigError, match="already holds a run"):
        evolve(_config("cmaes"), tmp_path / "a")


@pytest.mark.parametrize(
    ("overrides", "bad"),
    [
        ({"algo": "pso"}, "pso"),
        ({"robot": "XX"}, "XX"),
        ({"mazes": ["M0_5x5_Q"]}, "Q"),
        ({"fitness": "speed"}, "speed"),
        ({"budget_steps": -5}, "-5"),
        ({"budget_seconds": 0}, "budget_seconds"),
        ({"seed": "one"}, "one"),
        ({"algorithm": {"population_size": 16, "sigma": 2}}, "sigma"),
        ({"colour": "red"}, "colour"),
    ],
)
def test_bad_config_names_the_value(tmp_path: Path, overrides: dict, bad: str) -> None:
    with pytest.raises(EvolutionConfigError, match=bad):
        evolve({**_config("cmaes"), **overrides}, tmp_path / "run")
    assert not (tmp_path / "run" / "config.json").exists()


def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--algo", "cmaes", "--mazes", "M0_5x5_Q", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "Q" in err[0]
    assert main(["--resume", str(tmp_path / "nothing")]) == 2
    assert main(["--algo", "ga"]) == 2


def test_cli_with_a_config_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "neat.json"
    config.write_text(json.dumps({"population_size": 12}))  # the algorithm's options alone
    argv = ["--algo", "neat", "--mazes", ",".join(SMALL_MAZES), "--max-generations", "2"]
    assert main([*argv, "--config", str(config), "--out", str(tmp_path / "r")]) == 0
    assert "run folder" in capsys.readouterr().out
    saved = EvolveConfig.from_dict(json.loads((tmp_path / "r" / "config.json").read_text()))
    assert saved.algorithm["population_size"] == 12 and saved.max_generations == 2
    assert saved.algorithm["tournament_size"] == 2  # config.json records every option used


def _kill_when(process: subprocess.Popen, out: Path, generations: int) -> None:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        checkpoint = out / "checkpoints" / "state.npz"
        if checkpoint.exists() and (out / "progress.csv").exists():
            if len(_rows(out)) >= generations:
                break
        if process.poll() is not None:
            pytest.fail("the run ended before it could be killed")
        time.sleep(0.02)
    assert process.poll() is None, "the run ended before it could be killed"
    os.kill(process.pid, signal.SIGKILL)
    process.wait()


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["cmaes", "neat"])
def test_resume_after_a_kill_reaches_the_same_champion(tmp_path: Path, algo: str) -> None:
    config = _config(algo, max_generations=120, mazes=["M3_10x10_C1", "M4_8x8_C1"])
    config["algorithm"] = {"population_size": 24}
    whole = evolve(config, tmp_path / "whole")

    (tmp_path / "config.json").write_text(json.dumps(config))
    out = tmp_path / "killed"
    command = [sys.executable, "-m", "evolution.cli", "--config", str(tmp_path / "config.json")]
    process = subprocess.Popen(
        [*command, "--out", str(out), "--no-progress"],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    _kill_when(process, out, generations=15)  # past two anytime points (every 6 generations)
    assert not (out / "summary.json").exists()
    resumed = resume(out)

    assert _without_time(_rows(out)) == _without_time(_rows(tmp_path / "whole"))
    # the anytime evaluations too: the same points, the same agents, the same scores
    evaluations = _without_time(_evaluations(out))
    assert len(evaluations) == 20
    assert evaluations == _without_time(_evaluations(tmp_path / "whole"))
    assert (
        resumed.summary["champion_fitness"] == whole.summary["champion_fitness"]
        and resumed.env_steps == whole.env_steps
    )
    a, _ = read_agent(out / "agent.npz")
    b, _ = read_agent(tmp_path / "whole" / "agent.npz")
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success_rate"] == whole.summary["success_rate"]
    assert summary["normalized_reward"] == whole.summary["normalized_reward"]


def test_a_generation_starts_only_if_the_budget_pays_its_least_cost(tmp_path: Path) -> None:
    with pytest.raises(EvolutionConfigError, match="budget_steps 100 cannot pay one generation"):
        evolve(_config("cmaes", budget_steps=100, max_generations=None), tmp_path / "small")
    assert not (tmp_path / "small").exists()
    config = _config("neat", budget_steps=20_000, max_generations=None)
    evolve(config, tmp_path / "r")
    rows = _rows(tmp_path / "r")
    run = EvolutionRun(tmp_path / "r", EvolveConfig.from_dict(config))
    run.state = read_checkpoint(
        tmp_path / "r/checkpoints/state.npz", evolution_codec(_State), EvolutionConfigError, _State
    )
    least, _ = run.generation_steps()
    assert 20_000 - int(rows[-1]["steps"]) < least  # no budget left for another generation
    assert 20_000 - int(rows[-2]["steps"]) >= least  # the last one started with its least cost paid


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--seed", "3", "--stages", "4"], "--seed, --stages would be ignored"),
        (["--budget-steps", "9"], "--budget-steps would be ignored"),
        (["--out", "elsewhere"], "--out would be ignored"),
        (["--config", "c.json"], "--config would be ignored"),
    ],
)
def test_resume_refuses_the_options_it_would_ignore(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], words: str
) -> None:
    assert main(["--resume", str(tmp_path), *argv]) == 2
    assert words in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--seed", "4294967296"], "seed 4294967296 is not an integer in [0, 4294967295]"),
        (["--seed", "4294967295", "--replicates", "2"], "reaches seed 4294967296"),
        (["--regime", "interpolation", "--stages", "1"], "stages 1: an interpolation"),
        (["--replay", "x", "--seed", "2"], "--replay reruns the replayed run's config.json"),
    ],
)
def test_options_out_of_range_are_refused_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], words: str
) -> None:
    assert main([*argv, "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "run").exists()


def test_a_run_of_the_other_trainer_is_named_with_its_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "config.json").write_text(json.dumps({"algo": "ppo", "hyperparameters": {}}))
    assert main(["--resume", str(tmp_path)]) == 2
    assert "holds a run of amaze-train" in capsys.readouterr().err
    assert main(["--replay", str(tmp_path), "--out", str(tmp_path / "new")]) == 2
    assert "use amaze-train for it" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sent", "status", "words"),
    [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")],
)
def test_an_interrupted_run_says_what_is_saved_and_how_to_resume(
    tmp_path: Path, sent: int, status: int, words: str
) -> None:
    out = tmp_path / "run"
    # a budget far longer than the wait below: the signal always finds the run training
    config = _config("cmaes", max_generations=None, budget_seconds=900)
    (tmp_path / "config.json").write_text(json.dumps(config))
    command = [sys.executable, "-m", "evolution.cli", "--config", str(tmp_path / "config.json")]
    process = subprocess.Popen(
        [*command, "--out", str(out), "--checkpoint-seconds", "0"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # a shell's background job ignores SIGINT, and a child inherits that: restore it
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + 120
    while not (out / "checkpoints" / "state.npz").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert process.poll() is None, "the run ended before it could be interrupted"
    process.send_signal(sent)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == status
    assert stderr.strip().splitlines() == [
        f"{words}{' (SIGTERM)' if sent == signal.SIGTERM else ''}: {out} keeps what its last"
        f" checkpoint saved; resume with: amaze-evolve --resume {out}"
    ]
    # not a terminal: plain progress lines on standard output
    assert "cmaes direct seed 0: 0% of 900 s; 0.0s elapsed; started" in stdout.replace(
        "0.1s", "0.0s"
    )


@pytest.mark.parametrize(
    ("interrupt", "status", "words"),
    [(KeyboardInterrupt, 130, "interrupted"), (Terminated, 143, "terminated (SIGTERM)")],
)
def test_an_interrupt_inside_a_library_write_still_ends_the_run_as_an_interrupt(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    interrupt: type[KeyboardInterrupt],
    status: int,
    words: str,
) -> None:
    # A signal inside numpy's savez made its zip clean-up raise a ValueError
    # of its own: the run ended with exit status 1 and a traceback.
    def interrupted_save(self: EvolutionRun) -> None:
        try:
            raise interrupt
        finally:
            raise ValueError("Can't close the ZIP file while there is an open writing handle")

    monkeypatch.setattr(EvolutionRun, "save_checkpoint", interrupted_save)
    (tmp_path / "config.json").write_text(json.dumps(_config("cmaes")))
    out = tmp_path / "run"
    assert main(["--config", str(tmp_path / "config.json"), "--out", str(out)]) == status
    assert capsys.readouterr().err.strip().splitlines() == [
        f"{words}: {out} keeps what its last checkpoint saved;"
        f" resume with: amaze-evolve --resume {out}"
    ]


def test_an_error_raised_with_no_interrupt_behind_it_is_not_taken_for_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def failing_save(self: EvolutionRun) -> None:
        raise ValueError("a bug in the save")

    monkeypatch.setattr(EvolutionRun, "save_checkpoint", failing_save)
    (tmp_path / "config.json").write_text(json.dumps(_config("cmaes")))
    with pytest.raises(ValueError, match="a bug in the save"):
        main(["--config", str(tmp_path / "config.json"), "--out", str(tmp_path / "run")])


def test_resuming_a_finished_run_says_so_and_changes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    evolve(_config("cmaes"), out)
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert main(["--resume", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"{out} holds a finished run (its summary.json): nothing was changed" in printed
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
