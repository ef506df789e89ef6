"""The JAX trainer's settings and state are bounded and checked before anything is built.

* network sizes (``net_arch``, ``features_dim``), rollout sizes (``n_steps``,
  ``n_envs``, their product, ``batch_size``), an update's epochs and
  ``chunk_steps`` are refused past their bounds, naming the value; the
  bounds themselves are accepted;
* the state arrays refuse NaN or infinite parameters, optimizer moments and
  observations, and negative second moments, naming the array;
* a saved trainer whose ``trainer.json`` asks for a huge network, or whose
  ``state.npz`` holds NaN parameters, is refused by :func:`load_trainer`
  naming the file, before a network is built;
* ``amaze-train --resume`` of a real run whose saved trainer was so edited
  prints one ``error:`` line naming the file and exits 2.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from amaze.validation import MAX_HIDDEN_LAYERS, MAX_LAYER_WIDTH  # noqa: E402
from rl_baselines import RLConfigError  # noqa: E402
from rl_baselines.cli import main  # noqa: E402
from rl_baselines.jax import JaxTrainer  # noqa: E402
from rl_baselines.jax import trainer as jax_trainer  # noqa: E402
from rl_baselines.jax.hyperparameters import (  # noqa: E402
    MAX_EPOCH_SAMPLES,
    MAX_ROLLOUT_SIZE,
    checked_hyperparameters,
)
from rl_baselines.jax.trainer import MAX_CHUNK_STEPS, load_trainer  # noqa: E402
from tests.run_folders import refused_resume  # noqa: E402

MAZE = "M1_5x5_U"
PPO = {"n_steps": 16, "batch_size": 32, "n_epochs": 2}
TRAINER = "checkpoints/latest/trainer"


def _refused(words: str, algo: str = "ppo", images: bool = False, n_envs: int = 4, **hps: object):
    with pytest.raises(RLConfigError, match=re.escape(words)):
        checked_hyperparameters(algo, hps, robot_images=images, n_envs=n_envs)


@pytest.mark.parametrize(
    ("net_arch", "words"),
    [
        ([1_000_000, 1_000_000], "net_arch layer 1000000 is not an integer in [1, 4096]"),
        ([64] * (MAX_HIDDEN_LAYERS + 1), f"net_arch has 17 layers, more than {MAX_HIDDEN_LAYERS}"),
        ({"pi": [64], "vf": [MAX_LAYER_WIDTH + 1]}, "net_arch vf layer 4097"),
        ({"pi": "64"}, "net_arch pi '64' is not a list of layer widths"),
        ([0], "net_arch layer 0 is not an integer in [1, 4096]"),
    ],
)
def test_network_sizes_are_bounded(net_arch: object, words: str) -> None:
    _refused(words, policy_kwargs={"net_arch": net_arch})


def test_features_dim_is_bounded() -> None:
    kwargs = {"features_extractor_kwargs": {"features_dim": MAX_LAYER_WIDTH + 1}}
    _refused("features_dim 4097 is not an integer in [1, 4096]", images=True, policy_kwargs=kwargs)


def test_rollout_sizes_are_bounded() -> None:
    _refused("'n_steps' 4611686018427387904 is not an integer in [1, 4194304]", n_steps=2**62)
    _refused("n_envs 4194305 is not an integer in [1, 4194304]", n_envs=MAX_ROLLOUT_SIZE + 1)
    _refused("n_steps * n_envs = 2097152 * 4 = 8,388,608 samples", n_steps=2**21)
    _refused("'batch_size' 4194305 is not an integer", batch_size=MAX_ROLLOUT_SIZE + 1)
    _refused("n_epochs * n_steps * n_envs = 268,435,520 samples", n_steps=16, n_epochs=2**22 + 1)
    _refused("n_steps * n_envs = 2097152 * 4", algo="a2c", n_steps=2**21)


def test_the_bounds_themselves_are_accepted() -> None:
    wide = {"net_arch": [MAX_LAYER_WIDTH] * MAX_HIDDEN_LAYERS}
    hp = checked_hyperparameters(
        "ppo",
        {
            "n_steps": MAX_ROLLOUT_SIZE // 4,
            "batch_size": MAX_ROLLOUT_SIZE,
            "n_epochs": MAX_EPOCH_SAMPLES // MAX_ROLLOUT_SIZE,
            "policy_kwargs": wide,
        },
        robot_images=False,
        n_envs=4,
    )
    assert hp.rollout_size == MAX_ROLLOUT_SIZE and hp.net_pi == (MAX_LAYER_WIDTH,) * 16
    images = {"features_extractor_kwargs": {"features_dim": MAX_LAYER_WIDTH}}
    hp = checked_hyperparameters("a2c", {"policy_kwargs": images}, robot_images=True)
    assert hp.features_dim == MAX_LAYER_WIDTH


def test_chunk_steps_is_bounded() -> None:
    with pytest.raises(RLConfigError, match=r"chunk_steps 4611686018427387904 is not an integer"):
        JaxTrainer("ppo", "DD", [MAZE], PPO, chunk_steps=2**62)
    trainer = JaxTrainer("ppo", "DD", [MAZE], PPO, chunk_steps=MAX_CHUNK_STEPS)
    assert trainer.settings()["chunk_steps"] == MAX_CHUNK_STEPS


@pytest.fixture(scope="module")
def trained() -> JaxTrainer:
    trainer = JaxTrainer("ppo", "DD", [MAZE], PPO, seed=1)
    trainer.learn(2 * 64)
    return trainer


@pytest.mark.parametrize(
    ("name", "value", "words"),
    [
        ("params/action_net/bias", np.nan, "holds NaN or infinity"),
        ("params/mlp_extractor.policy_net.0/weight", np.inf, "holds NaN or infinity"),
        ("opt_state/exp_avg/value_net/bias", -np.inf, "holds NaN or infinity"),
        ("opt_state/exp_avg_sq/value_net/weight", np.nan, "holds NaN or infinity"),
        ("opt_state/exp_avg_sq/action_net/bias", -1.0, "holds negative moments"),
        ("envs/observations", np.nan, "holds NaN or infinity"),
    ],
)
def test_state_arrays_refuse_non_finite_floats(
    trained: JaxTrainer, name: str, value: float, words: str
) -> None:
    arrays = trained.state_arrays()
    damaged = arrays[name].copy()
    damaged.flat[0] = value
    with pytest.raises(RLConfigError, match=re.escape(f"array {name!r} {words}")):
        trained.load_state_arrays({**arrays, name: damaged})
    trained.load_state_arrays(arrays)  # the intact arrays are still accepted


def test_a2c_square_avg_is_checked_too() -> None:
    trainer = JaxTrainer("a2c", "DD", [MAZE], {"n_steps": 5})
    arrays = trainer.state_arrays()
    name = "opt_state/square_avg/action_net/weight"
    with pytest.raises(RLConfigError, match="negative moments"):
        trainer.load_state_arrays({**arrays, name: np.full_like(arrays[name], -1.0)})


def _edit_settings(folder: Path, **changes: object) -> Path:
    path = folder / "trainer.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), **changes}))
    return path


def test_load_trainer_refuses_a_huge_network_before_building_it(
    trained: JaxTrainer, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = trained.save(tmp_path / "trainer")
    huge = {**trained.settings()["hyperparameters"], "policy_kwargs": {"net_arch": [10**6] * 2}}
    path = _edit_settings(folder, hyperparameters=huge)

    def never(*args: object, **kwargs: object) -> None:
        raise AssertionError("a network was built")

    monkeypatch.setattr(jax_trainer, "init_params", never)
    with pytest.raises(RLConfigError, match=re.escape(f"{path}: policy_kwargs net_arch layer")):
        load_trainer(folder)


def test_load_trainer_refuses_a_huge_chunk_and_nan_parameters(
    trained: JaxTrainer, tmp_path: Path
) -> None:
    folder = trained.save(tmp_path / "trainer")
    settings = (folder / "trainer.json").read_text()
    path = _edit_settings(folder, chunk_steps=2**62)
    with pytest.raises(RLConfigError, match=re.escape(f"{path}: chunk_steps 4611686018427387904")):
        JaxTrainer.load(folder)
    path.write_text(settings)
    arrays = {
        name: np.full_like(a, np.nan) if name.startswith("params/") else a
        for name, a in trained.state_arrays().items()
    }
    with open(folder / "state.npz", "wb") as stream:
        np.savez(stream, **arrays)
    with pytest.raises(RLConfigError, match=re.escape(f"{folder / 'state.npz'}: training state")):
        JaxTrainer.load(folder)


@pytest.fixture(scope="module")
def jax_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real tiny run of ``amaze-train --framework jax``, with its checkpoint."""
    folder = tmp_path_factory.mktemp("jax")
    options = folder / "options.json"
    options.write_text(json.dumps(PPO))
    out = folder / "run"
    argv = ["--framework", "jax", "--algo", "ppo", "--config", str(options)]
    argv += ["--mazes", MAZE, "--eval-mazes", MAZE, "--budget-steps", "256"]
    argv += ["--eval-every", "128", "--evaluation-points", "2", "--evaluation-family", "1"]
    assert main([*argv, "--no-progress", "--out", str(out)]) == 0
    return out


def _settings_edit(**changes: object):
    def edit(path: Path) -> None:
        data = json.loads(path.read_text())
        for key, value in changes.items():
            if key == "policy_kwargs":
                data["hyperparameters"]["policy_kwargs"] = value
            else:
                data[key] = value
        path.write_text(json.dumps(data))

    return edit


def _nan_params(path: Path) -> None:
    with np.load(path) as stored:
        arrays = {name: stored[name] for name in stored.files}
    for name in arrays:
        if name.startswith("params/"):
            arrays[name] = np.full_like(arrays[name], np.nan)
    with open(path, "wb") as stream:
        np.savez(stream, **arrays)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "damage", "words"),
    [
        (
            "trainer.json",
            _settings_edit(policy_kwargs={"net_arch": [1_000_000, 1_000_000]}),
            "policy_kwargs net_arch layer 1000000 is not an integer in [1, 4096]",
        ),
        (
            "trainer.json",
            _settings_edit(chunk_steps=2**62),
            "chunk_steps 4611686018427387904 is not an integer",
        ),
        ("trainer.json", _settings_edit(n_envs=2**40), "n_envs 1099511627776 is not an integer"),
        ("state.npz", _nan_params, "array 'params/action_net/bias' holds NaN or infinity"),
    ],
)
def test_resume_refuses_an_edited_saved_trainer_in_one_line(
    jax_run: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    name: str,
    damage: object,
    words: str,
) -> None:
    out = tmp_path / "run"
    line = refused_resume(main, jax_run, out, f"{TRAINER}/{name}", damage, capsys)
    assert f"{out / TRAINER / name}: " in line and words in line, line
