"""Training runs: config checks, the run folder, kill-and-resume, and a small PPO run."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

import rl_baselines.direct as direct_module
import rl_baselines.train as train_module
from amaze.errors import UsageError
from rl_baselines import RLConfigError
from rl_baselines.cli import COMMAND, main
from rl_baselines.train import TrainConfig, train

SUMMARY_KEYS = {"success_rate", "normalized_reward", "input_recognition", "env_steps", "seconds"}


def _progress(out: Path) -> list[dict[str, str]]:
    with (out / "progress.csv").open(newline="") as stream:
        return list(csv.DictReader(stream))


@pytest.mark.parametrize(
    ("data", "bad"),
    [
        ({"algo": "dqn"}, "'dqn'"),
        ({"n_envs": 6}, "6"),
        ({"budget_steps": 0}, "budget_steps 0"),
        ({"robot": "Z"}, "'Z'"),
        ({"regime": "sideways"}, "'sideways'"),
        ({"regime": "edhucat", "curator": "nobody"}, "'nobody'"),
        ({"stages": 3}, "stages .* 3 has no effect in the direct regime"),
        ({"colour": 1}, "'colour'"),
        ({"hyperparameters": {"seed": 3}}, "'seed'"),
        ({"budget_seconds": 0}, "budget_seconds 0 is not a number > 0"),
        ({"budget_seconds": -1}, "budget_seconds -1 is not a number > 0"),
        ({"budget_seconds": "x"}, "budget_seconds 'x' is not a number"),
        ({"budget_seconds": True}, "budget_seconds True is not a number"),
        ({"budget_seconds": float("inf")}, "budget_seconds inf is not a finite number"),
        ({"budget_steps": None}, "budget_steps None and budget_seconds None"),
        ({"budget_steps": None, "budget_seconds": None}, "needs at least one budget"),
        ({"budget_steps": 2.5, "budget_seconds": 10}, "budget_steps 2.5"),
    ],
)
def test_bad_config_names_the_value(data: dict, bad: str) -> None:
    with pytest.raises(RLConfigError, match=bad):
        TrainConfig.from_dict(data)


def test_budgets_of_steps_seconds_or_both() -> None:
    assert (TrainConfig.from_dict({}).budget_steps, TrainConfig().budget_seconds) == (
        3_000_000,
        None,
    )
    seconds = TrainConfig.from_dict({"budget_steps": None, "budget_seconds": 90})
    assert (seconds.budget_steps, seconds.budget_seconds) == (None, 90.0)
    both = TrainConfig.from_dict({"budget_steps": 500, "budget_seconds": 1.5})
    assert (both.budget_steps, both.budget_seconds) == (500, 1.5)


def test_a_config_written_before_seconds_budgets_loads_unchanged() -> None:
    old = TrainConfig.from_dict({}).to_dict()  # a checked config, as config.json holds
    del old["budget_seconds"]
    old["budget_steps"] = 12_345
    config = TrainConfig.from_dict(old)
    assert config.budget_steps == 12_345 and config.budget_seconds is None
    assert config.to_dict() == {**old, "budget_seconds": None}


def test_budget_seconds_alone_on_the_command_line_has_no_step_limit(tmp_path: Path) -> None:
    parser = COMMAND.parser()

    def config(*argv: str, file: str | None = None) -> TrainConfig:
        args = parser.parse_args([*argv, "--out", str(tmp_path / "unused")])
        return TrainConfig.from_dict(TrainConfig.from_file_and_arguments(args, file))

    alone = config("--budget-seconds", "60")
    assert (alone.budget_steps, alone.budget_seconds) == (None, 60.0)
    both = config("--budget-seconds", "60", "--budget-steps", "800")
    assert (both.budget_steps, both.budget_seconds) == (800, 60.0)
    assert config("--budget-steps", "800").budget_seconds is None
    # a whole config file that sets budget_steps keeps it: both budgets apply
    whole = _write(tmp_path / "whole.json", {"budget_steps": 900})
    assert config("--budget-seconds", "60", file=whole).budget_steps == 900
    with pytest.raises(UsageError, match="'x'"):
        config("--budget-seconds", "x")


def test_cli_refuses_a_zero_seconds_budget(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--budget-seconds", "0", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "budget_seconds 0.0" in err and err.count("\n") == 1
    assert not (tmp_path / "r").exists()


def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--algo", "ppo", "--n-envs", "5", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "5" in err and err.count("\n") == 1
    assert main(["--resume", str(tmp_path / "nothing")]) == 2
    assert main(["--algo", "sac"]) == 2
    capsys.readouterr()
    # one RL run has nothing to put on Ray (its replicates do): refused before Ray starts
    assert main(["--backend", "ray", "--out", str(tmp_path / "r")]) == 2
    assert "runs replicates on Ray (--replicates K)" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_run_folder_and_refusal_to_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "run"
    config = {"algo": "a2c", "budget_steps": 400, "eval_every": 200, "n_envs": 4, "seed": 1}
    result = train(config, out)
    assert result.env_steps == 400
    for name in ("config.json", "progress.csv", "summary.json", "agent.zip", "agent.json"):
        assert (out / name).exists(), name
    assert (out / "checkpoints" / "latest" / "model.zip").exists()
    assert len(list((out / "trajectories").glob("*.png"))) == 4
    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary) and summary["env_steps"] == 400
    assert [int(r["steps"]) for r in _progress(out)] == [0, 200, 400]
    with pytest.raises(RLConfigError, match="already holds a run"):
        train(config, out)


@pytest.mark.slow
def test_kill_and_resume_counts_the_budget_once(tmp_path: Path) -> None:
    out = tmp_path / "run"
    budget = 12_000
    command = [sys.executable, "-m", "rl_baselines.cli", "--algo", "a2c", "--seed", "0"]
    args = ["--budget-steps", str(budget), "--eval-every", "3000", "--out", str(out)]
    process = subprocess.Popen([*command, *args], stderr=subprocess.PIPE)
    state = out / "checkpoints" / "latest" / "state.json"
    deadline = time.monotonic() + 60
    killed_at = None
    try:
        while time.monotonic() < deadline and process.poll() is None:
            if state.exists():
                steps = json.loads(state.read_text())["num_timesteps"]
                if steps > 0:
                    killed_at = steps
                    break
            time.sleep(0.05)
        assert process.poll() is None, "the run ended before it could be killed"
    finally:
        process.kill()
        process.wait()
    assert killed_at is not None and 0 < killed_at < budget
    assert not (out / "summary.json").exists()
    resumed = subprocess.run(
        [sys.executable, "-m", "rl_baselines.cli", "--resume", str(out)],
        capture_output=True,
        text=True,
        timeout=600,  # a safety net for a hung process (about 30 s on a busy 2-core machine)
    )
    assert resumed.returncode == 0, resumed.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["env_steps"] == budget
    steps = [int(r["steps"]) for r in _progress(out)]
    assert steps == sorted(set(steps)) and steps[0] == 0 and steps[-1] == budget
    assert json.loads(state.read_text())["num_timesteps"] == budget


@pytest.mark.slow
def test_ppo_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "ppo"
    config = {
        "algo": "ppo",
        "budget_steps": 2048,
        "eval_every": 1024,
        "n_envs": 4,
        "hyperparameters": {"n_steps": 128, "batch_size": 128, "n_epochs": 2},
    }
    code = main(["--config", _write(tmp_path / "c.json", config), "--out", str(out), "--seed", "2"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["env_steps"] == 2048 and summary["algo"] == "ppo" and summary["seed"] == 2
    assert json.loads((out / "config.json").read_text())["hyperparameters"]["n_steps"] == 128


def _write(path: Path, data: dict) -> str:
    path.write_text(json.dumps(data))
    return str(path)


def test_early_stop_when_every_evaluation_episode_is_optimal(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(direct_module, "OPTIMAL", -1e9)  # any episode counts as optimal
    config = {"algo": "a2c", "budget_steps": 4000, "eval_every": 100, "n_envs": 4}
    result = train(config, tmp_path / "run")
    assert result.summary["converged"] and result.env_steps < 100
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["converged"] is True


def test_replicates_run_one_process_per_seed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import amaze.runs.replicates

    plans: list[tuple[list, int | None]] = []
    monkeypatch.setattr(
        amaze.runs.replicates,
        "run_replicates",
        lambda plan, workers: plans.append((plan, workers)) or 0,
    )
    argv = ["--algo", "a2c", "--seed=7", "--replicates", "3", "--workers", "2"]
    assert main([*argv, "--out", str(tmp_path), "--n-envs", "8"]) == 0
    ((plan, workers),) = plans
    assert workers == 2 and [r.seed for r in plan] == [7, 8, 9]
    for seed, replicate in zip((7, 8, 9), plan, strict=True):
        command = replicate.command
        assert command[command.index("-m") + 1] == "rl_baselines.cli"
        assert command[command.index("--seed") + 1] == str(seed)
        assert command[command.index("--out") + 1] == str(tmp_path / f"seed-{seed}")
        assert command.count("--seed") == 1 and "--replicates" not in command
        # no --no-progress: a replicate prints plain progress lines into its log
        assert "--workers" not in command and "--no-progress" not in command
        assert command[command.index("--n-envs") + 1] == "8"


def test_tensorboard_logs_in_the_run_folder(tmp_path: Path) -> None:
    out = tmp_path / "run"
    train({"algo": "a2c", "budget_steps": 40, "eval_every": 20}, out)
    logs = list((out / "tensorboard").rglob("events.out.tfevents.*"))
    assert logs and all(p.stat().st_size > 0 for p in logs)
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(logs[0].parent))
    events.Reload()
    assert "eval/success_rate" in events.Tags()["scalars"]
    steps = [e.step for e in events.Scalars("eval/normalized_reward")]
    assert steps == sorted(steps) and steps[0] == 0


def test_unknown_hyperparameter_is_refused_before_the_run_starts(tmp_path: Path) -> None:
    config = {"algo": "ppo", "hyperparameters": {"n_stepz": 8}}
    with pytest.raises(RLConfigError, match="n_stepz"):
        train(config, tmp_path / "run")
    assert not (tmp_path / "run").exists()


#: PPO with 32-step rollouts (128 env steps) and two short epochs: many rollouts a second.
QUICK_PPO = {"n_steps": 32, "batch_size": 64, "n_epochs": 2}
#: Generous: the run stops at a step; only a very slow machine adds seconds after it.
SLACK = 30


@pytest.mark.slow
def test_a_direct_run_on_seconds_alone_stops_at_its_budget(tmp_path: Path) -> None:
    out = tmp_path / "ppo"
    config = {
        "algo": "ppo",
        "budget_steps": None,
        "budget_seconds": 3,
        "eval_every": 1024,
        "tensorboard": False,
        "hyperparameters": QUICK_PPO,
    }
    result = train(config, out)
    summary = result.summary
    assert summary["budget_seconds"] == 3.0 and summary["budget_steps"] is None
    assert not summary["converged"] and summary["env_steps"] > 0
    state = json.loads((out / "checkpoints" / "latest" / "state.json").read_text())
    # stopped by the clock: the training seconds reached the budget, and not long after
    assert 3 <= state["seconds"] < 3 + SLACK
    assert 3 <= summary["seconds"] < 3 + SLACK
    rows = _progress(out)
    steps = [int(r["steps"]) for r in rows]
    assert steps == sorted(set(steps)) and steps[0] == 0
    # the final agent is evaluated: progress.csv and the checkpoint are at its steps
    assert steps[-1] == summary["env_steps"] == state["num_timesteps"]


@pytest.mark.slow
def test_amaze_train_budget_seconds_alone(tmp_path: Path) -> None:
    out = tmp_path / "a2c"
    argv = ["--algo", "a2c", "--budget-seconds", "2", "--eval-every", "2000"]
    assert main([*argv, "--no-tensorboard", "--progress", "--out", str(out)]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["budget_steps"] is None and config["budget_seconds"] == 2.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["env_steps"] > 0 and 2 <= summary["seconds"] < 2 + SLACK


@pytest.mark.slow
@pytest.mark.parametrize(
    ("budgets", "by_steps"),
    [({"budget_steps": 200, "budget_seconds": 600}, True), ({"budget_seconds": 2}, False)],
)
def test_with_both_budgets_the_first_reached_ends_the_run(
    tmp_path: Path, budgets: dict, by_steps: bool
) -> None:
    # A2C's rollouts are 5 steps x 4 environments; 10 ** 9 steps is never reached here.
    config = {"algo": "a2c", "budget_steps": 10**9, "eval_every": 2000, "tensorboard": False}
    summary = train({**config, **budgets}, tmp_path / "run").summary
    if by_steps:
        assert summary["env_steps"] == 200 and summary["seconds"] < 600
    else:
        assert 0 < summary["env_steps"] < 10**9 and 2 <= summary["seconds"] < 2 + SLACK


@pytest.mark.slow
def test_a_resumed_seconds_run_counts_the_seconds_already_spent(tmp_path: Path) -> None:
    out = tmp_path / "run"
    config = {"algo": "a2c", "budget_steps": None, "budget_seconds": 1.5, "eval_every": 1000}
    train({**config, "tensorboard": False}, out)
    before = json.loads((out / "summary.json").read_text())
    # as if killed after its last checkpoint, in a run of 3 seconds
    (out / "summary.json").unlink()
    data = json.loads((out / "config.json").read_text())
    (out / "config.json").write_text(json.dumps({**data, "budget_seconds": 3}))
    summary = train_module.resume(out).summary
    assert summary["env_steps"] > before["env_steps"] and 3 <= summary["seconds"] < 3 + SLACK
    seconds = [float(r["seconds"]) for r in _progress(out)]
    # the resumed part goes on from the checkpoint's seconds, not from zero
    assert seconds == sorted(seconds) and seconds[-1] >= 3


@pytest.mark.slow
def test_a_run_folder_of_a_config_without_budget_seconds_resumes_as_before(
    tmp_path: Path,
) -> None:
    out = tmp_path / "run"
    train({"algo": "a2c", "budget_steps": 40, "eval_every": 20, "tensorboard": False}, out)
    (out / "summary.json").unlink()
    data = json.loads((out / "config.json").read_text())
    del data["budget_seconds"]  # as written before seconds budgets existed
    (out / "config.json").write_text(json.dumps(data))
    summary = train_module.resume(out).summary
    assert summary["env_steps"] == 40 and summary["budget_seconds"] is None
    assert [int(r["steps"]) for r in _progress(out)] == [0, 20, 40]


def test_a_direct_run_learns_whole_rollouts_within_its_budget(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["--algo", "a2c", "--no-tensorboard", "--no-progress"]
    assert main([*args, "--budget-steps", "19", "--out", str(tmp_path / "small")]) == 2
    assert "cannot pay one rollout (20 steps: n_steps 5 x n_envs 4)" in capsys.readouterr().err
    assert not (tmp_path / "small").exists()
    summary = train({"algo": "a2c", "budget_steps": 50, "tensorboard": False}, tmp_path / "r")
    assert summary.env_steps == 40  # two rollouts of 20: a third would pass 50
