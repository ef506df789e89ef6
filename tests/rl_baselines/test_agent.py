"""SB3Agent: the shared policy protocol, save/load round trip, evaluation."""

from __future__ import annotations

import base64
import contextlib
import copy
import json
import os
import pickle
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch
from stable_baselines3 import A2C
from stable_baselines3.common import save_util

from amaze.agents.robot import as_robot
from amaze.evaluation.protocol import evaluate
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent, algorithm_class, load_sb3_model
from rl_baselines.networks import small_cnn_kwargs
from rl_baselines.train import train
from rl_baselines.vec_env import SB3VecEnv

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def agent() -> SB3Agent:
    env = SB3VecEnv(["M1_5x5_U", "M2_6x5_C1"], "DD", 4, seed=0)
    model = A2C("MlpPolicy", env, seed=0, device="cpu")
    model.learn(200)
    return SB3Agent(model, "DD")


def test_actions_follow_the_protocol(agent: SB3Agent) -> None:
    obs = np.random.default_rng(0).uniform(-1, 1, size=(7, 8)).astype(np.float32)
    actions = agent(obs)
    assert actions.shape == (7,) and actions.dtype == np.int64
    assert ((actions >= 0) & (actions <= 3)).all()
    np.testing.assert_array_equal(actions, agent(obs))  # deterministic


def test_save_load_gives_identical_actions(agent: SB3Agent, tmp_path: Path) -> None:
    path = agent.save(tmp_path / "agent")
    assert path.name == "agent.zip"
    meta = json.loads((tmp_path / "agent.json").read_text())
    assert meta["robot"] == "DD" and meta["algo"] == "a2c"
    loaded = SB3Agent.load(tmp_path / "agent.zip")
    obs = np.random.default_rng(1).uniform(-1, 1, size=(256, 8)).astype(np.float32)
    np.testing.assert_array_equal(loaded(obs), agent(obs))
    with torch.no_grad():
        for a, b in zip(
            agent.model.policy.state_dict().values(),
            loaded.model.policy.state_dict().values(),
            strict=True,
        ):
            assert torch.equal(a, b)
    assert not list(tmp_path.glob(".*tmp*"))  # no temporary file left behind


def test_shared_evaluation(agent: SB3Agent) -> None:
    summary = evaluate(agent, "DD").summary()
    assert summary["episodes"] == 72
    assert 0.0 <= summary["success_rate"] <= 1.0
    assert summary["input_recognition"] is not None


def test_bad_names(tmp_path: Path) -> None:
    with pytest.raises(RLConfigError, match="'dqn'"):
        algorithm_class("dqn")
    with pytest.raises(RLConfigError, match=r"missing\.zip"):
        SB3Agent.load(tmp_path / "missing")


def test_amaze_run_loads_saved_sb3_agents(agent: SB3Agent, tmp_path: Path, capsys) -> None:
    """`amaze run --controller agent.zip` finds the loader through its entry point."""
    from amaze.cli.main import main

    path = agent.save(tmp_path / "agent")
    assert main(["run", "M1_5x5_U", "--controller", str(path), "--json"]) == 0
    outcome = json.loads(capsys.readouterr().out)
    assert outcome["robot"] == "DD" and outcome["steps"] > 0
    assert main(["run", "M1_5x5_U", "--controller", str(path), "--robot", "H7"]) == 2
    assert "drives DD robots" in capsys.readouterr().err


# -----------------------------------------------------------------------------
# Loading without unpickling


class _CreatesFile:
    """Unpickling this creates ``path``: a stand-in for any code a crafted file could run."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self) -> tuple:
        return (open, (str(self.path), "w"))


def _pickled(path: Path) -> dict[str, str]:
    """A ``data`` value as SB3 writes a pickled object, whose payload creates ``path``."""
    payload = base64.b64encode(pickle.dumps(_CreatesFile(path))).decode()
    return {":type:": "<class 'object'>", ":serialized:": payload}


def _rewrite(source: Path, target: Path, change: Callable[[dict], object]) -> Path:
    """A copy of an agent (zip and metadata) whose ``data`` entry ``change`` edited."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for info in old.infolist():
            content = old.read(info.filename)
            if info.filename == "data":
                data = json.loads(content)
                change(data)
                content = json.dumps(data).encode()
            new.writestr(info, content)
    if source.with_suffix(".json").exists():
        target.with_suffix(".json").write_text(source.with_suffix(".json").read_text())
    return target


@pytest.mark.parametrize(
    "key", ["policy_class", "observation_space", "lr_schedule", "ep_info_buffer", "surprise"]
)
def test_sb3_zip_with_a_pickle_payload_runs_no_code(
    agent: SB3Agent, tmp_path: Path, key: str
) -> None:
    """A pickled ``data`` value is never unpickled: replaced when known, else the file refused."""
    marker = tmp_path / "code-ran"
    saved = agent.save(tmp_path / "agent")
    crafted = _rewrite(saved, tmp_path / "crafted.zip", lambda d: d.update({key: _pickled(marker)}))
    if key == "surprise":
        with pytest.raises(RLConfigError, match="'surprise'") as caught:
            SB3Agent.load(crafted)
        assert "crafted.zip" in str(caught.value)
    else:
        loaded = SB3Agent.load(crafted)
        obs = np.random.default_rng(2).uniform(-1, 1, size=(64, 8)).astype(np.float32)
        np.testing.assert_array_equal(loaded(obs), agent(obs))
    assert not marker.exists()
    # the payload is live: SB3's own loading runs it
    with contextlib.suppress(Exception):
        A2C.load(crafted, device="cpu")
    assert marker.exists()


def _model(algo: str, robot: str, **hyperparameters) -> object:
    """A model of ``algo`` for ``robot`` after a little training (as the trainer builds it)."""
    env = SB3VecEnv(["M1_5x5_U", "M2_6x5_C1"], robot, 4, seed=0)
    kwargs = {"n_steps": 16, "batch_size": 16} if algo == "ppo" else {}
    kwargs.update(hyperparameters)
    policy = "MlpPolicy"
    if not as_robot(robot).discrete_inputs:
        policy = "CnnPolicy"
        kwargs["policy_kwargs"] = {**small_cnn_kwargs(), **kwargs.get("policy_kwargs", {})}
    model = algorithm_class(algo)(policy, env, seed=3, device="cpu", **kwargs)
    model.learn(96)
    return model


@pytest.mark.parametrize(
    ("algo", "robot", "hyperparameters"),
    [
        ("ppo", "DD", {}),
        ("a2c", "DD", {}),
        ("ppo", "H15", {}),
        ("a2c", "H15", {}),
        ("ppo", "DD", {"clip_range": 0.1, "clip_range_vf": 0.3, "learning_rate": 1e-4}),
    ],
)
def test_models_load_without_unpickling_as_sb3_loads_them(
    algo: str, robot: str, hyperparameters: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Same actions, parameters and optimizer state as SB3's own load; training goes on alike."""
    path = tmp_path / "model.zip"
    _model(algo, robot, **hyperparameters).save(path)
    obs = np.stack(
        [SB3VecEnv(["M1_5x5_U"], robot, 1).observation_space.sample() for _ in range(64)]
    )

    def env() -> SB3VecEnv:
        return SB3VecEnv(["M1_5x5_U", "M2_6x5_C1"], robot, 4, seed=0)

    theirs = algorithm_class(algo).load(path, env=env(), device="cpu")
    expected = theirs.predict(obs, deterministic=True)[0]
    names = ("learning_rate", "gamma", "n_steps", "num_timesteps", "policy_kwargs", "seed")
    settings = {name: getattr(theirs, name) for name in names}
    optimizer = copy.deepcopy(theirs.policy.optimizer.state_dict())
    theirs.learn(64, reset_num_timesteps=False)
    trained = {k: v.clone() for k, v in theirs.policy.state_dict().items()}

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("cloudpickle.loads was called")

    monkeypatch.setattr(save_util.cloudpickle, "loads", refuse)
    ours = load_sb3_model(path, algo, robot, env=env(), device="cpu")
    np.testing.assert_array_equal(ours.predict(obs, deterministic=True)[0], expected)
    ours_optimizer = ours.policy.optimizer.state_dict()
    assert ours_optimizer["param_groups"] == optimizer["param_groups"]
    for index, state in optimizer["state"].items():
        for name, value in state.items():
            assert torch.equal(torch.as_tensor(ours_optimizer["state"][index][name]), value)
    assert {name: getattr(ours, name) for name in names} == settings
    ours.learn(64, reset_num_timesteps=False)
    for name, value in ours.policy.state_dict().items():
        assert torch.equal(value, trained[name]), name


def test_a_training_checkpoint_loads_and_trains_on(tmp_path: Path) -> None:
    """The trainer's ``checkpoints/model.zip`` loads as its resume will load it, and learns."""
    train({"algo": "a2c", "budget_steps": 200, "eval_every": 100, "seed": 1}, tmp_path / "run")
    env = SB3VecEnv(["M1_5x5_U"], "DD", 4, seed=1)
    model = load_sb3_model(
        tmp_path / "run" / "checkpoints" / "latest" / "model.zip",
        "a2c",
        "DD",
        env=env,
        device="cpu",
        tensorboard_log=str(tmp_path / "tensorboard"),
    )
    before = {k: v.clone() for k, v in model.policy.state_dict().items()}
    steps = model.num_timesteps
    model.learn(40, reset_num_timesteps=False)
    assert model.num_timesteps > steps
    assert any(not torch.equal(v, before[k]) for k, v in model.policy.state_dict().items())


def _entries(source: Path, target: Path, change: Callable[[dict[str, bytes]], object]) -> Path:
    """A copy of an agent whose zip entries (name: bytes) ``change`` edited."""
    with zipfile.ZipFile(source) as old:
        entries = {name: old.read(name) for name in old.namelist()}
    change(entries)
    with zipfile.ZipFile(target, "w") as new:
        for name, content in entries.items():
            new.writestr(name, content)
    target.with_suffix(".json").write_text(source.with_suffix(".json").read_text())
    return target


def _side(text: str) -> Callable[[Path, Path], Path]:
    def make(saved: Path, target: Path) -> Path:
        target.write_bytes(saved.read_bytes())
        target.with_suffix(".json").write_text(text)
        return target

    return make


def _raw(content: bytes) -> Callable[[Path, Path], Path]:
    def make(saved: Path, target: Path) -> Path:
        target.write_bytes(content)
        target.with_suffix(".json").write_text(saved.with_suffix(".json").read_text())
        return target

    return make


def _data(change: Callable[[dict], object]) -> Callable[[Path, Path], Path]:
    return lambda saved, target: _rewrite(saved, target, change)


def _zip_entries(change: Callable[[dict], object]) -> Callable[[Path, Path], Path]:
    return lambda saved, target: _entries(saved, target, change)


@pytest.mark.parametrize(("algo", "robot"), [("ppo", "DD"), ("a2c", "H5"), ("ppo", "CC5")])
def test_a_zip_saved_by_sb3_itself_is_read_with_its_algorithm_and_robot(
    tmp_path: Path, algo: str, robot: str
) -> None:
    """``model.save`` writes no metadata: the algorithm and robot come from the zip."""
    from rl_baselines.vec_env import SB3VecEnv

    images = robot != "DD"
    env = SB3VecEnv(["M1_10x10_U"], robot, 4)
    kwargs = {"policy_kwargs": small_cnn_kwargs()} if images else {}
    model = algorithm_class(algo)("CnnPolicy" if images else "MlpPolicy", env, **kwargs)
    model.save(tmp_path / "plain")
    agent = SB3Agent.load(tmp_path / "plain.zip")
    assert (agent.algo, agent.robot) == (algo, as_robot(robot))
    observations = np.zeros((3, *env.observation_space.shape), env.observation_space.dtype)
    expected, _ = model.predict(observations, deterministic=True)
    np.testing.assert_array_equal(agent(observations).reshape(expected.shape), expected)


def _truncated(saved: Path, target: Path) -> Path:
    return _raw(saved.read_bytes()[: saved.stat().st_size // 2])(saved, target)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (_raw(b""), "not a readable zip archive"),
        (_truncated, "truncated"),
        (_raw(os.urandom(1000)), "not a readable zip archive"),
        (_zip_entries(lambda e: e.pop("data")), "no 'data' entry"),
        (_zip_entries(lambda e: e.update(data=b"{not json")), "'data' entry is not"),
        (_zip_entries(lambda e: e.update(data=b"[1]")), "'data' entry is not a JSON object"),
        (_zip_entries(lambda e: e.update(data=b"\xff")), "'data' entry is not"),
        (_zip_entries(lambda e: e.update({"policy.pth": b"junk"})), "'policy.pth'"),
        (_zip_entries(lambda e: e.pop("policy.pth")), "cannot be loaded by A2C for DD robots"),
        (_side(json.dumps({"robot": "DD", "algo": "dqn"})), "'algo' 'dqn'"),
        (_side(json.dumps({"robot": "DD", "algo": 3})), "'algo' 3"),
        (_side(json.dumps({"robot": "DD"})), "'algo' None"),
        (_side(json.dumps({"robot": 7, "algo": "a2c"})), "'robot'"),
        (_side(json.dumps({"robot": "DD", "algo": "a2c", "format": "x"})), "'format' 'x'"),
        (_side("{not json"), "is not valid JSON"),
        (_side("[1, 2]"), "is not a JSON object"),
        (_side(json.dumps({"robot": "H15", "algo": "a2c"})), r"shape \(8,\).*\(1, 15, 15\)"),
        (_side(json.dumps({"robot": "DD", "algo": "ppo"})), "saved by A2C, not PPO"),
        (_data(lambda d: d.update(learning_rate="fast")), "'learning_rate' 'fast'"),
        (
            _data(lambda d: d["policy_kwargs"].update(optimizer_class="<class 'os.system'>")),
            r"policy_kwargs\['optimizer_class'\]",
        ),
    ],
)
def test_bad_sb3_agent_files_are_one_clear_error(
    agent: SB3Agent, tmp_path: Path, make: Callable[[Path, Path], Path], message: str
) -> None:
    saved = agent.save(tmp_path / "agent")
    path = make(saved, tmp_path / "bad.zip")
    with pytest.raises(RLConfigError, match=message) as caught:
        SB3Agent.load(path)
    assert "bad.zip" in str(caught.value)
    assert len(str(caught.value).splitlines()) == 1


@pytest.mark.parametrize("entry", ["policy.pth", "pytorch_variables.pth", "extra.pth"])
def test_sb3_zip_with_a_pickled_tensor_entry_runs_no_code(
    agent: SB3Agent, tmp_path: Path, entry: str
) -> None:
    """``.pth`` entries are read weights-only: a pickled object in one refuses the file."""
    marker = tmp_path / "code-ran"
    payload = pickle.dumps(_CreatesFile(marker), protocol=2)
    saved = agent.save(tmp_path / "agent")
    crafted = _entries(saved, tmp_path / "crafted.zip", lambda e: e.update({entry: payload}))
    with pytest.raises(RLConfigError, match=f"'{entry}'") as caught:
        SB3Agent.load(crafted)
    assert "crafted.zip" in str(caught.value)
    assert not marker.exists()


def test_ppo_clip_ranges_that_are_not_constants_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "model.zip"
    _model("ppo", "DD").save(path)
    linear = "LinearSchedule(start=0.2, end=0.0, end_fraction=1.0)"
    crafted = _rewrite(
        path, tmp_path / "linear.zip", lambda d: d["clip_range"].update(value_schedule=linear)
    )
    with pytest.raises(RLConfigError, match="'clip_range' is not a constant schedule"):
        load_sb3_model(crafted, "ppo", "DD")
    assert load_sb3_model(crafted, "ppo", "DD", clip_range=0.2).clip_range(1.0) == 0.2
