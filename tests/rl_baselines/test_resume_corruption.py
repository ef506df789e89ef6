"""``amaze-train --resume`` on damaged run folders: one ``error:`` line naming the file, exit 2,
and nothing in the folder changed (every file is checked before anything is written).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from rl_baselines.cli import main
from rl_baselines.train import train
from tests.run_folders import (
    RANDOM,
    directory,
    edit_json,
    edit_sb3_data,
    missing,
    refused_resume,
    snapshot,
    truncate,
    write,
)

CONFIG = {"algo": "a2c", "budget_steps": 40, "eval_every": 20, "tensorboard": False}


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("train") / "run"
    train(CONFIG, out)
    (out / "summary.json").unlink()  # as if killed after its last checkpoint
    return out


STATE = "checkpoints/latest/state.json"
MODEL = "checkpoints/latest/model.zip"

CASES = {
    "config missing": ("config.json", missing, "holds no run"),
    "config empty": ("config.json", write(b""), "is not JSON"),
    "config random bytes": ("config.json", write(RANDOM), "is not UTF-8 text"),
    "config directory": ("config.json", directory, "is a directory"),
    "config wrong type": ("config.json", edit_json(n_envs="four"), "n_envs 'four'"),
    "config bad hyperparameter": (
        "config.json",
        edit_json(hyperparameters={"learning_rate": "x"}),
        "'learning_rate' 'x'",
    ),
    "progress missing": ("progress.csv", missing, "no row at steps 40"),
    "progress empty": ("progress.csv", write(b""), "header"),
    "progress random bytes": ("progress.csv", write(RANDOM), "not text"),
    "progress directory": ("progress.csv", directory, "is a directory"),
    "progress wrong header": ("progress.csv", write(b"a,b\n1,2\n"), "header"),
    "progress bad steps": (
        "progress.csv",
        write(b"steps,seconds,eval_success_rate,eval_normalized_reward\nmany,0,0,0\n"),
        "steps 'many'",
    ),
    "model missing": (MODEL, missing, "is missing"),
    "model empty": (MODEL, write(b""), "model.zip"),
    "model truncated": (MODEL, truncate, "model.zip"),
    "model random bytes": (MODEL, write(RANDOM), "model.zip"),
    "model directory": (MODEL, directory, "model.zip"),
    "state missing": (STATE, missing, "is missing"),
    "state empty": (STATE, write(b""), "is not JSON"),
    "state random bytes": (STATE, write(RANDOM), "is not UTF-8 text"),
    "state directory": (STATE, directory, "is a directory"),
    "state not an object": (STATE, write(b"[]"), "does not hold a JSON object"),
    "state wrong steps": (STATE, edit_json(num_timesteps="x"), "num_timesteps 'x'"),
    "state wrong seconds": (STATE, edit_json(seconds=-1), "seconds -1"),
    "state wrong best": (STATE, edit_json(best="good"), "best 'good'"),
    "state wrong converged": (STATE, edit_json(converged="no"), "converged 'no'"),
    "state wrong last evaluation": (STATE, edit_json(last_eval_steps=-2), "last_eval_steps -2"),
    "model names a module": (MODEL, edit_sb3_data(env="this:NoSuchEnv-v0"), "data 'env'"),
    "model sets a method": (MODEL, edit_sb3_data(predict=5), "data 'predict'"),
    "model huge network": (
        MODEL,
        edit_sb3_data(policy_kwargs={"net_arch": [10**6, 10**6]}),
        "net_arch layer 1000000",
    ),
    "model huge rollout": (MODEL, edit_sb3_data(n_steps=2**40), "'n_steps' 1099511627776"),
    "champion names a module": (
        "checkpoints/champion.zip",
        edit_sb3_data(env="this:NoSuchEnv-v0"),
        "data 'env'",
    ),
    "champion empty": ("checkpoints/champion.zip", write(b""), "champion.zip"),
    "champion truncated": ("checkpoints/champion.zip", truncate, "champion.zip"),
    "champion random bytes": ("checkpoints/champion.zip", write(RANDOM), "champion.zip"),
    "champion directory": ("checkpoints/champion.zip", directory, "champion.zip"),
    "champion sidecar wrong algo": ("checkpoints/champion.json", edit_json(algo="dqn"), "dqn"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_damaged_file_is_refused_by_name_and_nothing_changes(
    finished_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    name, damage, words = CASES[case]
    line = refused_resume(main, finished_run, tmp_path / "run", name, damage, capsys)
    assert words in line, line
    if "missing" not in case or name != "config.json":
        assert Path(name).name in line, line


def test_an_intact_folder_resumes(finished_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    shutil.copytree(finished_run, out)
    assert main(["--resume", str(out), "--no-progress"]) == 0
    assert json.loads((out / "summary.json").read_text())["env_steps"] == 40


@pytest.mark.parametrize(
    ("hyperparameters", "words"),
    [
        ({"learning_rate": "x"}, "'learning_rate' 'x' is not a number"),
        ({"n_steps": 0}, "'n_steps' 0 is not a positive integer"),
        ({"gamma": "high"}, "'gamma' 'high' is not a number"),
        ({"ent_coef": [1]}, "'ent_coef' [1] is not a number"),
        ({"normalize_advantage": 1}, "'normalize_advantage' 1 is not true or false"),
        ({"policy_kwargs": "big"}, "'policy_kwargs' 'big' is not a JSON object"),
        ({"rollout_buffer_class": "X"}, "names a class"),
        ({"tensorboard_log": "elsewhere"}, "set by the trainer"),
        ({"n_stepz": 3}, "'n_stepz' is not one of PPO's"),
    ],
)
def test_bad_hyperparameters_are_one_error_line_before_the_run_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], hyperparameters: dict, words: str
) -> None:
    config = tmp_path / "config.json"
    config.write_text(json.dumps(hyperparameters))
    argv = ["--algo", "ppo", "--config", str(config), "--out", str(tmp_path / "run")]
    assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "run").exists()


def test_an_old_run_without_its_config_is_never_written_over(
    finished_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "old"
    shutil.copytree(finished_run, out)
    (out / "config.json").unlink()
    before = snapshot(out)
    assert main(["--algo", "a2c", "--budget-steps", "40", "--out", str(out)]) == 2
    assert "not empty and holds no run" in capsys.readouterr().err
    assert snapshot(out) == before
