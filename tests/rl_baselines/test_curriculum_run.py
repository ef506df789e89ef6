"""``amaze-train`` in the curriculum regimes: the EDHuCAT loop with an SB3 learner."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

import amaze.runs.curriculum as curriculum_module
from rl_baselines.cli import main
from rl_baselines.curriculum import SB3CurriculumRun
from rl_baselines.train import SB3Run, TrainConfig, train
from tests.run_folders import FakeClock

#: Two stages of two branches; A2C's default rollout (20 steps) fits the 150-step allowance.
A2C = ["--algo", "a2c", "--regime", "edhucat", "--curator", "random", "--stages", "2"]
A2C += ["--branches", "2", "--budget-steps", "600", "--eval-every", "40", "--no-progress"]


def _decisions(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "decisions.jsonl").read_text().splitlines()]


def _choices(out: Path) -> list:
    return [(d["stage"], d["kind"], d.get("mazes"), d.get("choice")) for d in _decisions(out)]


def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "progress.csv").open(newline="") as stream:
        return list(csv.DictReader(stream))


def _learner_steps(folder: Path) -> int:
    return json.loads((folder / "agent" / "learner.json").read_text())["num_timesteps"]


@pytest.fixture(scope="module")
def a2c_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("edhucat") / "a2c"
    assert main([*A2C, "--seed", "1", "--out", str(out)]) == 0
    return out


def test_the_curriculum_regimes_run_as_the_curriculum_loop() -> None:
    for regime, run_class in [("direct", SB3Run), ("edhucat", SB3CurriculumRun)]:
        config = TrainConfig.from_dict({"regime": regime})
        assert SB3Run.run_class_for(config) is run_class
    assert SB3Run.run_class_for(TrainConfig.from_dict({"regime": "interpolation"})) is (
        SB3CurriculumRun
    )


def test_an_edhucat_run_writes_the_curriculum_folder(a2c_run: Path) -> None:
    out = a2c_run
    for name in ("config.json", "decisions.jsonl", "curriculum.png", "summary.json"):
        assert (out / name).is_file(), name
    assert [(d["stage"], d["kind"]) for d in _decisions(out)] == [
        (0, "generate"),
        (1, "select"),
        (1, "generate"),
        (2, "select"),
    ]
    branches = sorted(p.relative_to(out / "stages") for p in out.glob("stages/*/branch-*"))
    assert [str(b) for b in branches] == [
        "stage-0/branch-0",
        "stage-1/branch-0",
        "stage-1/branch-1",
    ]
    for branch in branches:
        folder = out / "stages" / branch
        assert {"agent", "result.json", "trajectory.png"} <= {p.name for p in folder.iterdir()}
        assert not (folder / "checkpoint").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["algo"] == "a2c" and summary["curator"] == "random"
    assert summary["hyperparameters_used"]["n_steps"] == 5
    assert len(summary["curriculum"]) == 2 and len(summary["final_lineage"]) == 2
    # stage 0: 7 rollouts of 20 within 600 // 4; stage 1: 11 within (600 - 140) // 2
    assert [int(r["steps"]) for r in _rows(out)] == [140, 360, 580]
    assert summary["env_steps"] == 580 <= 600
    logs = {p.parent.name for p in (out / "tensorboard").rglob("events.out.tfevents.*")}
    assert logs == {"stage-0-branch-0_0", "stage-1-branch-0_0", "stage-1-branch-1_0"}
    # each branch continues its parent's model
    assert _learner_steps(out / "stages/stage-1/branch-1") == 140 + 220


def _fake_clock(monkeypatch: pytest.MonkeyPatch) -> FakeClock:
    """The runs' clocks, moving with the code's steps instead of the machine's speed."""
    import amaze.runs.anytime
    import amaze.runs.branches
    import amaze.runs.decisions
    import rl_baselines.learner

    modules = (rl_baselines.learner, amaze.runs.branches, amaze.runs.anytime, amaze.runs.decisions)
    return FakeClock().install(monkeypatch, *modules)


@pytest.mark.slow
def test_an_edhucat_run_on_seconds_alone_shares_them_between_stages_and_branches(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import rl_baselines.learner

    # never optimal: every branch trains until its seconds are spent
    monkeypatch.setattr(rl_baselines.learner, "OPTIMAL", 2.0)
    _fake_clock(monkeypatch)
    out = tmp_path / "seconds"
    argv = [*A2C[: A2C.index("--budget-steps")], "--budget-seconds", "4"]
    argv += ["--eval-every", "200", "--no-progress", "--no-tensorboard", "--seed", "3"]
    assert main([*argv, "--out", str(out)]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["budget_steps"] is None and config["budget_seconds"] == 4.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["budget_seconds"] == 4.0 and summary["hyperparameters_used"]["n_steps"] == 5
    results = {
        str(path.parent.relative_to(out / "stages")): json.loads(path.read_text())
        for path in sorted(out.glob("stages/*/branch-*/result.json"))
    }
    assert list(results) == ["stage-0/branch-0", "stage-1/branch-0", "stage-1/branch-1"]
    assert all(r["env_steps"] > 0 for r in results.values())
    # each branch trains its share of what is left: stage 0's one 4 s / (K x S),
    # stage 1's two what stage 0 left (its training, evaluation and picture) / K
    first = results["stage-0/branch-0"]
    allowances = {"stage-0/branch-0": 4 / 4}
    for branch in ("stage-1/branch-0", "stage-1/branch-1"):
        allowances[branch] = (4 - first["seconds"]) / 2
    for branch, allowance in allowances.items():
        training = results[branch]["time"]["training"]  # rounded to the millisecond
        assert allowance - 1e-3 <= training < allowance + 30, (branch, training, allowance)
    assert summary["env_steps"] == sum(r["env_steps"] for r in results.values())


def test_ppo_fits_its_rollout_to_a_tiny_budget(tmp_path: Path) -> None:
    out = tmp_path / "ppo"
    argv = ["--algo", "ppo", "--regime", "edhucat", "--curator", "random", "--stages", "2"]
    argv += ["--branches", "2", "--budget-steps", "2000", "--eval-every", "256"]
    assert main([*argv, "--no-tensorboard", "--no-progress", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    # 2000 // 4 = 500 steps per branch: 64 steps x 4 environments (256) fits, 128 x 4 does not
    used = summary["hyperparameters_used"]
    assert (used["n_steps"], used["batch_size"]) == (64, 64)
    # config.json records every hyperparameter used, SB3's defaults and the fitted rollout
    recorded = json.loads((out / "config.json").read_text())["hyperparameters"]
    assert recorded == used and recorded["learning_rate"] == 3e-4
    assert int(_rows(out)[0]["steps"]) == 256
    assert summary["env_steps"] <= 2000 and not (out / "tensorboard").exists()


@pytest.mark.slow
def test_the_edens_regime_runs_open_ended_epochs_of_the_papers_size(tmp_path: Path) -> None:
    config = TrainConfig.from_dict({"regime": "edens"})
    assert (config.stages, config.epochs, config.rehearsal) == (0, 10, 7)
    out = tmp_path / "edens"
    argv = ["--algo", "a2c", "--regime", "edens", "--budget-steps", "1200", "--eval-every", "40"]
    assert main([*argv, "--no-tensorboard", "--no-progress", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    # 1200 // (3 * 10) = 40 steps a branch: two of A2C's rollouts (5 steps x 4 envs)
    assert summary["stages_played"] >= 5 and summary["epochs"] == 10
    # spent to the last whole rollout it could pay: a budget is a hard limit
    assert 1200 - 20 <= summary["env_steps"] <= 1200
    assert _decisions(out)[-1]["kind"] == "select"


def test_the_interpolation_regime_is_the_loop_with_one_branch(tmp_path: Path) -> None:
    out = tmp_path / "interpolation"
    config = {"algo": "a2c", "regime": "interpolation", "stages": 3, "budget_steps": 300}
    result = train({**config, "tensorboard": False}, out)
    decisions = _decisions(out)
    assert {d["curator"] for d in decisions} == {"interpolation"}
    assert result.summary["branches"] == 1 and result.summary["regime"] == "interpolation"
    assert [int(r["stage"]) for r in _rows(out)] == [0, 1, 2]
    final = [d["mazes"] for d in decisions if d["kind"] == "generate"][-1]
    assert final == [result.summary["target"]]


def test_a_replay_makes_the_same_decisions(a2c_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "replay"
    assert main(["--replay", str(a2c_run), "--out", str(out), "--no-progress"]) == 0
    assert _choices(out) == _choices(a2c_run)
    assert all(d.get("replayed") for d in _decisions(out))
    assert json.loads((out / "config.json").read_text())["replay"] == str(a2c_run)


class _Killed(Exception):
    pass


def _killing_save(at: int):
    """The curriculum's ``write_folder`` raising :class:`_Killed` once stage 1's ``at``-th
    checkpoint is in place (as a kill right after it would)."""
    write = curriculum_module.write_folder
    saves = 0

    def killing_write(folder: Path, fill) -> Path:
        nonlocal saves
        written = write(folder, fill)
        if Path(folder).name == "checkpoint" and Path(folder).parent.parent.name == "stage-1":
            saves += 1
            if saves == at:
                raise _Killed
        return written

    return killing_write


@pytest.mark.slow
def test_resume_after_a_kill_mid_stage_continues_the_branch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "run"
    # killed at the 3rd checkpoint of stage 1: at 80 of the branch's 220 steps
    monkeypatch.setattr(curriculum_module, "write_folder", _killing_save(3))
    with pytest.raises(_Killed):
        main([*A2C, "--seed", "2", "--out", str(out)])
    monkeypatch.undo()
    checkpoint = out / "stages/stage-1/branch-0/checkpoint"
    assert checkpoint.is_dir() and not (out / "summary.json").exists()
    session = json.loads((checkpoint / "learner.json").read_text())["session"]
    assert session["steps"] == 80
    before = (out / "decisions.jsonl").read_text()
    assert main(["--resume", str(out), "--no-progress"]) == 0
    assert (out / "decisions.jsonl").read_text().startswith(before)
    assert len(_decisions(out)) == 4 and not checkpoint.exists()
    result = json.loads((out / "stages/stage-1/branch-0/result.json").read_text())
    assert result["env_steps"] == 220
    # the session went on from its checkpoint: 140 (stage 0) + 220, not 140 + 80 + 220
    assert _learner_steps(out / "stages/stage-1/branch-0") == 360
    assert [int(r["branches"]) for r in _rows(out)] == [1, 2, 3]


@pytest.mark.slow
def test_resume_mid_stage_of_a_seconds_run_continues_the_session(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import rl_baselines.learner

    monkeypatch.setattr(rl_baselines.learner, "OPTIMAL", 2.0)  # only the clock ends a branch
    _fake_clock(monkeypatch)
    out = tmp_path / "run"
    argv = [*A2C[: A2C.index("--budget-steps")], "--budget-seconds", "3"]
    argv += ["--eval-every", "40", "--no-progress", "--no-tensorboard", "--seed", "4"]
    write = curriculum_module.write_folder
    # killed at the 2nd checkpoint of stage 1: 40 steps into its first branch
    monkeypatch.setattr(curriculum_module, "write_folder", _killing_save(2))
    with pytest.raises(_Killed):
        main([*argv, "--out", str(out)])
    monkeypatch.setattr(curriculum_module, "write_folder", write)
    checkpoint = out / "stages/stage-1/branch-0/checkpoint"
    session = json.loads((checkpoint / "learner.json").read_text())["session"]
    first = json.loads((out / "stages/stage-0/branch-0/result.json").read_text())
    # the session records its allowance of seconds, which the resumed run computes again
    assert session["budget"] is None and session["steps"] == 40
    assert session["budget_seconds"] == (3 - first["seconds"]) / 2
    assert main(["--resume", str(out), "--no-progress"]) == 0
    result = json.loads((out / "stages/stage-1/branch-0/result.json").read_text())
    assert result["env_steps"] > 40 and not checkpoint.exists()
    # the session went on from its checkpoint: stage 0's steps + the session's, no more
    steps = _learner_steps(out / "stages/stage-1/branch-0")
    assert steps == first["env_steps"] + result["env_steps"]


def test_a_damaged_checkpoint_is_refused_by_name(
    a2c_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    shutil.copytree(a2c_run, out)
    (out / "summary.json").unlink()
    branch = out / "stages/stage-1/branch-1"
    shutil.rmtree(branch)
    (branch / "checkpoint").mkdir(parents=True)
    (branch / "checkpoint" / "learner.json").write_text("{}")
    assert main(["--resume", str(out)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "learner.json" in err[0], err


def test_a_bad_curator_is_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    argv = ["--regime", "edhucat", "--curator", "nobody", "--out", str(tmp_path / "run")]
    assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "'nobody'" in err[0], err
    assert not (tmp_path / "run").exists()


def test_bad_hyperparameters_fail_before_the_folder_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    config = tmp_path / "hyper.json"
    config.write_text(json.dumps({"batch_size": 1}))  # PPO asserts batch_size > 1
    argv = ["--algo", "ppo", "--regime", "edhucat", "--curator", "random", "--stages", "2"]
    assert main([*argv, "--config", str(config), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "bad hyperparameters for ppo" in err[0], err
    assert not (tmp_path / "run").exists()
