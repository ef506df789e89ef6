"""The JAX learners' modules in :mod:`rl_baselines.jax`, and their old names for one release.

``rl_baselines.jax_run``, ``rl_baselines.jax_learner`` and
``rl_baselines.jax_coevolution`` became ``rl_baselines.jax.run``,
``rl_baselines.jax.learner`` and ``rl_baselines.jax.coevolution``: the old
names warn and give the new modules' names (the only test importing them),
and a coevolution checkpoint naming the old module is read as the new one's.
"""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rl_baselines
from amaze.curriculum.maze_population import MazePopulation, MazePopulationConfig, MazeResult
from amaze.curriculum.validation import reserved_seeds
from amaze.runs.checkpoint import read_checkpoint, write_checkpoint
from rl_baselines import RLConfigError
from rl_baselines.jax.coevolution import JaxCoevolutionRun
from rl_baselines.train import TrainConfig
from tests.run_folders import retagged_checkpoint

#: Old module -> new module.
MOVED = {
    "rl_baselines.jax_run": "rl_baselines.jax.run",
    "rl_baselines.jax_learner": "rl_baselines.jax.learner",
    "rl_baselines.jax_coevolution": "rl_baselines.jax.coevolution",
}
ROOT = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize(("old_name", "new_name"), MOVED.items())
def test_the_old_module_name_warns_and_gives_the_new_modules_names(
    old_name: str, new_name: str
) -> None:
    saved = sys.modules.pop(old_name, None)
    attribute = old_name.rpartition(".")[2]
    try:
        with pytest.warns(DeprecationWarning, match=rf"{old_name} is now {new_name};"):
            old = importlib.import_module(old_name)
        new = importlib.import_module(new_name)
        assert set(old.__all__) == set(new.__all__)
        for public in old.__all__:
            assert getattr(old, public) is getattr(new, public), public
    finally:
        sys.modules.pop(old_name, None)
        if saved is not None:
            sys.modules[old_name] = saved
        elif hasattr(rl_baselines, attribute):
            delattr(rl_baselines, attribute)


@pytest.mark.parametrize(
    "code",
    [
        "import rl_baselines.config",
        *(f"import {name}" for name in MOVED.values()),
    ],
)
def test_each_module_imports_first_in_a_fresh_interpreter(code: str) -> None:
    """No import circle (``rl_baselines.jax`` never imports the runs it holds), no old name."""
    done = subprocess.run(
        [sys.executable, "-W", "error:rl_baselines.jax_:DeprecationWarning", "-c", code],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr


def _state(tmp_path: Path) -> tuple[JaxCoevolutionRun, object]:
    """A JAX coevolution run (no trainer) and a state of six rounds of its maze population."""
    config = TrainConfig.from_dict(
        {"framework": "jax", "algo": "a2c", "regime": "coevolution", "budget_steps": 1000}
    )
    run = JaxCoevolutionRun(tmp_path / "run", config)
    population = MazePopulation(
        "M4_5x5_C1", MazePopulationConfig(capacity=4, batch=2), seed=3, reserved=reserved_seeds()
    )
    for k in range(6):
        batch = population.propose()
        success = np.zeros((8, 4))
        success[: k + 1] = 1
        result = MazeResult.of(success, np.where(success > 0, 0.5, -1.0))
        population.update(batch, [result] * len(batch))
    state = run.state_class(population, round=6, steps=480, trainer_folder="trainer-6")
    return run, state


def test_a_checkpoint_naming_the_old_module_is_read(tmp_path: Path) -> None:
    """A run folder written before the move names ``rl_baselines.jax_coevolution:_JaxState``."""
    run, state = _state(tmp_path)
    codec, state_class = run.state_codec(), run.state_class
    path = write_checkpoint(tmp_path / "state.npz", state, codec)
    new = "rl_baselines.jax.coevolution"
    old = retagged_checkpoint(path, new, "rl_baselines.jax_coevolution", tmp_path / "old.npz")
    copy = read_checkpoint(old, codec, RLConfigError, state_class)
    assert type(copy) is state_class
    assert (copy.round, copy.steps, copy.trainer_folder) == (6, 480, "trainer-6")
    assert [r.to_row() for r in copy.mazes.records] == [r.to_row() for r in state.mazes.records]
    assert [b.maze for b in copy.mazes.propose()] == [b.maze for b in state.mazes.propose()]
    # an old tag of another module is still refused
    other = retagged_checkpoint(path, new, "rl_baselines.jax_elsewhere", tmp_path / "other.npz")
    with pytest.raises(RLConfigError, match="jax_elsewhere:_JaxState"):
        read_checkpoint(other, codec, RLConfigError, state_class)
