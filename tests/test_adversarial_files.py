"""Agent files and checkpoints written by an attacker, through every command that reads them.

Each case builds a hostile file (an SB3 zip whose ``data`` names a module or
sets a method, an ``.npz`` whose header or zip entry declares gigabytes, a
damaged or crafted JAX trainer state) and checks the contract: one ``error:``
line naming the file and the bad value, exit status 2, no code run (a marker
file that a module creates on import never appears), and no allocation on
the file's word (the memory the reader takes stays far below what the file
declares; ``tracemalloc`` sees numpy's and zipfile's buffers).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tracemalloc
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from amaze.agents.robot import as_robot
from amaze.cli.main import main as amaze_main
from tests.run_folders import edit_sb3_data, load_tool

hostile_files = load_tool("hostile_files")

MAZE = "M0_5x5_C1"
#: Most memory one refused case may take while it is read (the files declare gigabytes).
CEILING = 64 << 20


def _agent_commands(path: Path) -> list[list[str]]:
    """Every ``amaze`` command line that loads the agent file ``path``."""
    return [
        ["evaluate", str(path), MAZE],
        ["run", MAZE, "--controller", str(path)],
        ["suite", "--evaluate", str(path)],
        ["inputs", "--controller", str(path)],
    ]


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """The one ``error:`` line of a command that must refuse its input with exit status 2."""
    tracemalloc.start()
    try:
        code = amaze_main(argv)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2, (argv, err)
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert "Traceback" not in err[0]
    assert peak < CEILING, f"{argv}: {peak:,} bytes allocated while refusing"
    return err[0]


@pytest.fixture(scope="module")
def sb3_agent(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A saved PPO agent for DD robots (zip and metadata)."""
    from rl_baselines.agent import SB3Agent, algorithm_class
    from rl_baselines.vec_env import SB3VecEnv

    env = SB3VecEnv(["M1_5x5_U"], "DD", 2)
    model = algorithm_class("ppo")("MlpPolicy", env, device="cpu", n_steps=8, batch_size=8)
    return SB3Agent(model, "DD", "ppo").save(tmp_path_factory.mktemp("sb3") / "agent")


def _hostile_sb3(source: Path, folder: Path, **changes: object) -> Path:
    """A copy of the SB3 agent ``source`` whose ``data`` has ``changes``."""
    target = folder / "hostile.zip"
    shutil.copy(source, target)
    shutil.copy(source.with_suffix(".json"), target.with_suffix(".json"))
    edit_sb3_data(**changes)(target)
    return target


@pytest.fixture
def marker_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[str, Path]:
    """An importable module that creates a marker file when imported: (name, marker)."""
    name = f"amaze_hostile_{tmp_path.name.replace('-', '_')}"
    marker = tmp_path / "code-ran"
    (tmp_path / f"{name}.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    return name, marker


def test_an_sb3_zip_naming_a_module_imports_nothing_in_any_command(
    sb3_agent: Path, tmp_path: Path, marker_module: tuple[str, Path], capsys
) -> None:
    name, marker = marker_module
    hostile = _hostile_sb3(sb3_agent, tmp_path, env=f"{name}:AMaze-v0")
    for argv in _agent_commands(hostile):
        line = _refused(argv, capsys)
        assert "hostile.zip" in line and "'env'" in line, line
    assert not marker.exists()
    assert name not in sys.modules


def test_an_sb3_zip_naming_an_installed_module_imports_nothing(
    sb3_agent: Path, tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delitem(sys.modules, "this", raising=False)
    hostile = _hostile_sb3(sb3_agent, tmp_path, env="this:NoSuchEnv-v0")
    line = _refused(["evaluate", str(hostile), MAZE], capsys)
    assert "'env'" in line
    assert "this" not in sys.modules  # importing it prints the Zen of Python


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"predict": 5}, "data 'predict'"),
        ({"__class__": "x"}, "data '__class__'"),
        ({"device": "cuda"}, "data 'device'"),
        ({"policy": {":type:": "x", ":serialized:": "gASVAAAA"}}, "data 'policy'"),
        ({"n_steps": 2**40}, "'n_steps' 1099511627776"),
        ({"n_envs": 2**20, "n_steps": 2**20}, "'n_envs' 1048576"),
        ({"n_envs": 4096, "n_steps": 4096}, "16,777,216 samples"),
        ({"batch_size": -1}, "'batch_size' -1"),
        ({"policy_kwargs": {"net_arch": [10**6, 10**6]}}, "net_arch layer 1000000"),
        ({"policy_kwargs": {"net_arch": [4] * 100}}, "net_arch has 100 layers"),
        ({"policy_kwargs": {"net_arch": {"pi": [8], "qf": [8]}}}, "keys ['qf']"),
        ({"policy_kwargs": {"features_extractor_kwargs": {"features_dim": 10**9}}}, "10000000"),
        ({"policy_kwargs": {"optimizer_class": "os.system"}}, "'optimizer_class'"),
        ({"policy_kwargs": {"callback": 1}}, "policy_kwargs 'callback'"),
        ({"learning_rate": float("nan")}, "'learning_rate' nan"),
        ({"gamma": "high"}, "'gamma' 'high'"),
        ({"use_sde": True}, "'use_sde' True"),
        ({"action_noise": {"sigma": 1}}, "'action_noise'"),
        ({"rollout_buffer_kwargs": {"handle_timeout_termination": 1}}, "rollout_buffer_kwargs"),
        ({"verbose": 10**400}, "'verbose'"),
    ],
)
def test_an_sb3_zip_with_values_no_model_takes_is_refused_by_name(
    sb3_agent: Path, tmp_path: Path, capsys, changes: dict, words: str
) -> None:
    hostile = _hostile_sb3(sb3_agent, tmp_path, **changes)
    line = _refused(["evaluate", str(hostile), MAZE], capsys)
    assert "hostile.zip" in line and words in line, line


def test_an_sb3_zip_with_an_entry_sb3_never_writes_is_refused(
    sb3_agent: Path, tmp_path: Path, capsys
) -> None:
    hostile = _hostile_sb3(sb3_agent, tmp_path)
    with zipfile.ZipFile(hostile, "a") as archive:
        archive.writestr("evil.pth", b"x")
    assert "'evil.pth'" in _refused(["evaluate", str(hostile), MAZE], capsys)


def test_the_tensorboard_folder_of_a_file_is_never_used(sb3_agent: Path, tmp_path: Path) -> None:
    from rl_baselines.agent import SB3Agent

    hostile = _hostile_sb3(sb3_agent, tmp_path, tensorboard_log=str(tmp_path / "elsewhere"))
    assert SB3Agent.load(hostile).model.tensorboard_log is None


def test_an_intact_sb3_agent_is_still_scored(sb3_agent: Path, capsys) -> None:
    assert amaze_main(["evaluate", str(sb3_agent), MAZE]) == 0
    assert MAZE in capsys.readouterr().out


# -- .npz agent files -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def npz_agent(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A saved evolved agent (a fixed network for DD robots)."""
    from evolution.agent_file import save_network_agent
    from evolution.networks import NetworkSpec

    spec = NetworkSpec("DD", (4,))
    return save_network_agent(
        tmp_path_factory.mktemp("npz") / "agent", spec, np.zeros(spec.n_params)
    )


def test_an_npz_declaring_a_terabyte_array_is_refused_unread(
    npz_agent: Path, tmp_path: Path, capsys
) -> None:
    hostile = hostile_files.with_entry(
        npz_agent, tmp_path / "big.npz", "params.npy", hostile_files.npy_header((2**40,))
    )
    for argv in _agent_commands(hostile):
        line = _refused(argv, capsys)
        assert "big.npz" in line and "(1099511627776,)" in line, line


@pytest.mark.parametrize(
    ("entry", "words"),
    [
        (hostile_files.npy_header((2**62, 2**62)), "'params'"),
        (hostile_files.npy_header((36,), "|O") + bytes(288), "Python objects"),
        (hostile_files.npy_header((36,), "<U100000000"), "<U100000000"),
    ],
)
def test_an_npz_whose_header_lies_is_refused(
    npz_agent: Path, tmp_path: Path, capsys, entry: bytes, words: str
) -> None:
    hostile = hostile_files.with_entry(npz_agent, tmp_path / "bad.npz", "params.npy", entry)
    line = _refused(["evaluate", str(hostile), MAZE], capsys)
    assert "bad.npz" in line and words in line, line


def test_an_npz_metadata_declaring_gigabytes_is_refused(
    npz_agent: Path, tmp_path: Path, capsys
) -> None:
    header = hostile_files.npy_header((), "<U500000000")
    hostile = hostile_files.with_entry(npz_agent, tmp_path / "meta.npz", "metadata.npy", header)
    assert "'metadata'" in _refused(["evaluate", str(hostile), MAZE], capsys)


@pytest.mark.parametrize("declared", [None, 4096], ids=["honest size", "lying size"])
def test_a_zip_bomb_is_refused_before_it_inflates(
    npz_agent: Path, tmp_path: Path, capsys, declared: int | None
) -> None:
    """A few hundred kB on disk, 512 MiB once inflated: refused on its declared size, or
    (when the entry lies about its size) on its header, never inflated whole."""
    hostile = hostile_files.bomb_npz(npz_agent, tmp_path / "bomb.npz", 512 << 20, declared)
    assert hostile.stat().st_size < 2 << 20
    line = _refused(["evaluate", str(hostile), MAZE], capsys)
    assert "bomb.npz" in line and "params" in line, line


# -- checkpoints ------------------------------------------------------------------------------


def test_a_checkpoint_array_declaring_a_terabyte_is_refused_unread(tmp_path: Path) -> None:
    from amaze.errors import AmazeError
    from amaze.runs.checkpoint import StateCodec, read_checkpoint, write_checkpoint

    path = write_checkpoint(tmp_path / "state.npz", {"x": np.zeros(3)}, StateCodec([]))
    hostile_files.with_entry(path, path, "a0.npy", hostile_files.npy_header((2**40,)))
    tracemalloc.start()
    with pytest.raises(AmazeError, match=r"'a0' declares shape \(1099511627776,\)"):
        read_checkpoint(path, StateCodec([]), AmazeError, dict)
    assert tracemalloc.get_traced_memory()[1] < CEILING
    tracemalloc.stop()


@pytest.fixture(scope="module")
def jax_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished direct JAX run of 2 rollouts, as if killed after its last checkpoint."""
    from rl_baselines.train import train

    out = tmp_path_factory.mktemp("jax") / "run"
    train(hostile_files.TINY_JAX_RUN, out)
    (out / "summary.json").unlink()
    return out


STATE = "checkpoints/latest/trainer/state.npz"


def _state_entry(name: str, content: bytes) -> Callable[[Path], None]:
    return lambda path: hostile_files.with_entry(path, path, name, content)


@pytest.mark.parametrize(
    ("damage", "words"),
    [
        (lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]), "state.npz"),
        (lambda p: p.write_bytes(b""), "state.npz"),
        (_state_entry("key.npy", hostile_files.npy_header((2**40,), "<u4")), "'key'"),
        (
            _state_entry("intruder.npy", hostile_files.npy_header((4,)) + bytes(32)),
            "'intruder' is not part",
        ),
    ],
    ids=["truncated", "empty", "huge array", "extra array"],
)
def test_a_damaged_jax_trainer_state_refuses_the_resume(
    jax_run: Path, tmp_path: Path, capsys, damage: Callable[[Path], None], words: str
) -> None:
    from rl_baselines.cli import main

    out = tmp_path / "run"
    shutil.copytree(jax_run, out)
    damage(out / STATE)
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    code = main(["--resume", str(out), "--no-progress"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error")]
    assert code == 2 and len(err) == 1, err
    assert words in err[0], err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_the_jax_run_resumes_when_intact(jax_run: Path, tmp_path: Path) -> None:
    from rl_baselines.cli import main

    out = tmp_path / "run"
    shutil.copytree(jax_run, out)
    assert main(["--resume", str(out), "--no-progress"]) == 0
    assert json.loads((out / "summary.json").read_text())["env_steps"] == 64


def test_a_hostile_sb3_zip_is_refused_before_torch_is_imported(
    sb3_agent: Path, tmp_path: Path
) -> None:
    """The refusal costs no torch import: a fraction of a second, no more memory than amaze."""
    hostile = _hostile_sb3(sb3_agent, tmp_path, env="this:NoSuchEnv-v0")
    code = (
        "import sys\n"
        "from amaze.cli.main import main\n"
        f"status = main(['evaluate', {str(hostile)!r}, {MAZE!r}])\n"
        "print(status, 'torch' in sys.modules, 'stable_baselines3' in sys.modules)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert done.stdout.split() == ["2", "False", "False"], (done.stdout, done.stderr)
    assert done.stderr.count("error: ") == 1 and "'env'" in done.stderr


def test_the_torch_free_reader_and_the_loader_know_the_same_classes() -> None:
    from rl_baselines.agent import _POLICY_KWARGS_CLASSES
    from rl_baselines.sb3_file import POLICY_KWARGS_CLASS_NAMES

    assert set(_POLICY_KWARGS_CLASSES) == POLICY_KWARGS_CLASS_NAMES


def test_a_rollout_too_large_for_its_robots_images_is_refused_by_both_frameworks() -> None:
    """2**20 samples pass the sample bound, but not as 65 x 65 images (17 GB of floats)."""
    from rl_baselines import RLConfigError
    from rl_baselines.jax.trainer import JaxTrainer
    from rl_baselines.sb3_file import checked_data

    with pytest.raises(RLConfigError, match="bytes of observations"):
        JaxTrainer("ppo", "H65", ["M1_20x20_U"], {"n_steps": 4096}, n_envs=256)
    schedule = {":type:": "x", ":serialized:": "", "value_schedule": "ConstantSchedule(val=0.2)"}
    data = {"n_steps": 4096, "n_envs": 256, "clip_range": schedule}
    with pytest.raises(RLConfigError, match="bytes of observations"):
        checked_data(data, "ppo", as_robot("H65"), {}, "model 'x.zip'")
    assert checked_data(data, "ppo", as_robot("DD"), {}, "model 'x.zip'")["n_envs"] == 256
