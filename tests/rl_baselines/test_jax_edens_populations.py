"""``amaze-train --framework jax --regime edens-populations``: EDEnS over co-evolved maze
populations with a JAX learner.

* a run plays epochs of alternatives (each a copy of the parent's learner and
  population), records the picks, and counts every alternative's env steps in
  its budget (the trainer's own counter goes back with every copy);
* killed in the middle of an epoch (the parent's and a finished
  alternative's training states in its checkpoint) and resumed, it ends with
  the very agent, picks and progress of a run never interrupted;
* SB3, whose model is not data, is refused in this regime by name.
"""

from __future__ import annotations

import csv
import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("jax")

from rl_baselines import RLConfigError
from rl_baselines.cli import main
from rl_baselines.jax.agent import NetworkAgent
from rl_baselines.jax.edens_populations import JaxEdensPopulationsRun
from rl_baselines.train import SB3Run, TrainConfig, resume
from tests.rl_baselines.jax_kill import Killed

pytestmark = pytest.mark.slow

ARGV = ["--framework", "jax", "--algo", "a2c", "--regime", "edens-populations"]
ARGV += ["--target", "M4_6x6_C1", "--budget-steps", "4800", "--eval-every", "40"]
ARGV += ["--evaluation-points", "2", "--evaluation-family", "1", "--seed", "5", "--no-progress"]
#: epochs of 2 alternatives x 2 rounds; rounds on one maze of 5 or 6 cells a side
OPTIONS = {
    "n_envs": 4,
    "hyperparameters": {"n_steps": 5},
    "network": {"hidden": [8], "symmetry": "rotations"},
    "coevolution": {"validation": 2, "validation_every": 1, "min_size": 5},
    "selector": {"alternatives": 2, "epoch": 2},
}


def _argv(tmp_path: Path, out: Path) -> list[str]:
    path = tmp_path / "options.json"
    path.write_text(json.dumps(OPTIONS))
    return [*ARGV, "--config", str(path), "--out", str(out)]


def _rows(path: Path, columns: tuple[str, ...]) -> list[tuple[str, ...]]:
    with path.open(newline="") as stream:
        return [tuple(row[c] for c in columns) for row in csv.DictReader(stream)]


def test_the_regime_runs_with_jax_and_refuses_sb3() -> None:
    config = TrainConfig.from_dict({"regime": "edens-populations", "framework": "jax"})
    assert SB3Run.run_class_for(config) is JaxEdensPopulationsRun
    with pytest.raises(RLConfigError, match="edens-populations with framework sb3: its"):
        TrainConfig.from_dict({"regime": "edens-populations"})


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("jax-edens-populations")
    out = folder / "run"
    assert main(_argv(folder, out)) == 0
    return out


def test_a_run_plays_epochs_of_alternatives_and_counts_all_their_steps(finished: Path) -> None:
    summary = json.loads((finished / "summary.json").read_text())
    assert summary["regime"] == "edens-populations" and summary["framework"] == "jax"
    assert summary["epochs"] >= 2 and summary["agent"] == "agent.npz"
    rows = _rows(finished / "progress.csv", ("round", "steps", "epoch", "alternative"))
    steps = [int(s) for _, s, _, _ in rows]
    # every alternative's rounds add to the run's steps: never back to the parent's count
    assert all(b > a for a, b in itertools.pairwise(steps)), steps
    assert steps[-1] == summary["env_steps"] <= 4800
    assert [(int(e), int(a)) for _, _, e, a in rows[:8]] == [
        (0, 0), (0, 0), (0, 1), (0, 1), (1, 0), (1, 0), (1, 1), (1, 1),
    ]  # fmt: skip
    epochs = [json.loads(line) for line in (finished / "epochs.jsonl").read_text().splitlines()]
    assert [e["epoch"] for e in epochs] == list(range(summary["epochs"]))
    assert all(len(e["alternatives"]) == 2 and e["chosen"] in (0, 1) for e in epochs)
    assert (finished / "epochs.png").stat().st_size > 0
    agent = NetworkAgent.load(finished / "agent.npz")
    assert agent.robot.to_string() == "DD"


def test_a_run_killed_mid_epoch_resumes_to_the_same_agent_and_picks(
    finished: Path, tmp_path: Path, kill_at: Any
) -> None:
    cut = tmp_path / "cut"
    kill_at(7)  # round 7: epoch 1's second alternative, the first one's state in the checkpoint
    with pytest.raises(Killed):
        main(_argv(tmp_path, cut))
    assert not (cut / "summary.json").exists()
    resume(cut)
    with np.load(finished / "agent.npz") as a, np.load(cut / "agent.npz") as b:
        assert np.array_equal(a["params"], b["params"])
    assert (finished / "epochs.jsonl").read_text() == (cut / "epochs.jsonl").read_text()
    columns = ("round", "steps", "epoch", "alternative", "validation", "members")
    assert _rows(finished / "progress.csv", columns) == _rows(cut / "progress.csv", columns)
