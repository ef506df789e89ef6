"""``amaze-train --framework jax``: the JAX learners in the direct, curriculum and
co-evolution regimes.

* a direct run writes the SB3 run's folder (progress, anytime evaluations,
  summary, checkpoint, ``agent.zip`` + ``agent.json``), and its ``agent.zip``
  is read by ``amaze evaluate`` with the summary's figures;
* a direct run killed mid-training (an exception after its checkpoints) and
  resumed ends with the very agent, bit for bit, of one never interrupted;
* an EDHuCAT run (careful curator, 2 stages) does the same, through the
  learner protocol (:class:`~rl_baselines.jax.learner.JaxLearner`);
* a co-evolution run writes its folder, compiles once for mazes of every
  size, and killed and resumed ends with the very agent, population and
  progress of one never interrupted;
* options without effect with jax are refused in one line (exit 2):
  ``--tensorboard``, continuous robots, SB3-only hyperparameters.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("jax")

from amaze.cli.main import main as amaze_main
from rl_baselines.agent import SB3Agent
from rl_baselines.cli import main
from rl_baselines.curriculum import JaxCurriculumRun
from rl_baselines.jax.coevolution import JaxCoevolutionRun
from rl_baselines.jax.run import JaxRun
from rl_baselines.jax.trainer import JaxTrainer, run_rollouts
from rl_baselines.train import SB3Run, TrainConfig, resume
from tests.rl_baselines.jax_kill import Killed

pytestmark = pytest.mark.slow

MAZE = "M1_5x5_C1"
DIRECT = ["--framework", "jax", "--algo", "ppo", "--mazes", MAZE, "--eval-mazes", MAZE]
DIRECT += ["--budget-steps", "640", "--eval-every", "128", "--evaluation-points", "4"]
DIRECT += ["--evaluation-family", "1", "--seed", "3", "--no-progress"]
CURRICULUM = ["--framework", "jax", "--algo", "ppo", "--regime", "edhucat", "--curator"]
CURRICULUM += ["careful", "--stages", "2", "--branches", "2", "--target", MAZE]
CURRICULUM += ["--budget-steps", "768", "--eval-every", "64", "--evaluation-points", "4"]
CURRICULUM += ["--evaluation-family", "1", "--seed", "2", "--no-progress"]
COEVOLUTION = ["--framework", "jax", "--algo", "a2c", "--regime", "coevolution"]
COEVOLUTION += ["--target", "M4_6x6_C1", "--budget-steps", "8000", "--eval-every", "40"]
COEVOLUTION += ["--evaluation-points", "3", "--evaluation-family", "1", "--seed", "4"]
COEVOLUTION += ["--no-progress"]
PPO = {"n_steps": 16, "batch_size": 32, "n_epochs": 2}


def _options(tmp_path: Path, **extra: Any) -> list[str]:
    path = tmp_path / "options.json"
    path.write_text(json.dumps({**PPO, **extra}))
    return ["--config", str(path)]


def _params(zip_path: Path) -> dict[str, np.ndarray]:
    model = SB3Agent.load(zip_path).model
    return {name: value.numpy() for name, value in model.policy.state_dict().items()}


def _same_params(a: Path, b: Path) -> bool:
    x, y = _params(a), _params(b)
    return x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)


def _same_arrays(a: Path, b: Path) -> bool:
    with np.load(a) as x, np.load(b) as y:
        return set(x.files) == set(y.files) and all(np.array_equal(x[k], y[k]) for k in x.files)


def _rows(path: Path, columns: tuple[str, ...]) -> list[tuple[str, ...]]:
    with path.open(newline="") as stream:
        return [tuple(row[c] for c in columns) for row in csv.DictReader(stream)]


def test_the_jax_framework_picks_the_jax_runs() -> None:
    for regime, run_class in [
        ("direct", JaxRun),
        ("edhucat", JaxCurriculumRun),
        ("coevolution", JaxCoevolutionRun),
    ]:
        config = TrainConfig.from_dict({"regime": regime, "framework": "jax"})
        assert SB3Run.run_class_for(config) is run_class
        assert config.tensorboard is False
    assert TrainConfig.from_dict({}).framework == "sb3" and TrainConfig.from_dict({}).tensorboard


def test_a_direct_jax_run_writes_the_sb3_folder_and_an_sb3_agent(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    assert main([*DIRECT, *_options(tmp_path), "--out", str(out)]) == 0
    for name in ("config.json", "progress.csv", "evaluations.csv", "summary.json", "agent.json"):
        assert (out / name).is_file(), name
    assert (out / "checkpoints" / "latest" / "trainer" / "state.npz").is_file()
    assert not (out / "tensorboard").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["framework"] == "jax" and summary["env_steps"] == 640
    assert summary["agent"] == "agent.zip" and summary["anytime"]["points"] == 4
    steps = [int(row[0]) for row in _rows(out / "progress.csv", ("steps",))]
    assert steps == [0, 128, 256, 384, 512, 640]
    capsys.readouterr()
    assert amaze_main(["evaluate", str(out / "agent.zip"), "suite", "--json"]) == 0
    evaluated = json.loads(capsys.readouterr().out)
    assert evaluated["success_rate"] == summary["success_rate"]
    assert evaluated["normalized_reward"] == pytest.approx(summary["normalized_reward"])
    assert amaze_main(["run", MAZE, "--controller", str(out / "agent.zip"), "--json"]) == 0


def test_a_killed_direct_jax_run_resumes_to_the_same_agent_bit_for_bit(
    tmp_path: Path, kill_at: Any
) -> None:
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert main([*DIRECT, *_options(tmp_path), "--out", str(whole)]) == 0
    kill_at(4)  # mid-run: after the checkpoints of 0, 128 and 256 steps
    with pytest.raises(Killed):
        main([*DIRECT, *_options(tmp_path), "--out", str(cut)])
    assert not (cut / "summary.json").exists()
    resume(cut)
    assert _same_params(whole / "agent.zip", cut / "agent.zip")
    latest = Path("checkpoints/latest/trainer/state.npz")
    assert _same_arrays(whole / latest, cut / latest)
    scores = ("steps", "eval_success_rate", "eval_normalized_reward")
    assert _rows(whole / "progress.csv", scores) == _rows(cut / "progress.csv", scores)
    anytime = ("point", "env_steps", "success_rate", "normalized_reward")
    assert _rows(whole / "evaluations.csv", anytime) == _rows(cut / "evaluations.csv", anytime)


def test_a_killed_jax_curriculum_resumes_to_the_same_agents_bit_for_bit(
    tmp_path: Path, kill_at: Any
) -> None:
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert main([*CURRICULUM, *_options(tmp_path), "--out", str(whole)]) == 0
    summary = json.loads((whole / "summary.json").read_text())
    assert summary["framework"] == "jax" and summary["agent"] == "agent.zip"
    assert SB3Agent.load(whole / "agent.zip").robot.to_string() == "DD"
    kill_at(5)  # inside stage 1's first branch, after its first checkpoint
    with pytest.raises(Killed):
        main([*CURRICULUM, *_options(tmp_path), "--out", str(cut)])
    assert list(cut.glob("stages/stage-1/branch-0/checkpoint/learner.json"))
    resume(cut)
    assert _same_params(whole / "agent.zip", cut / "agent.zip")
    states = sorted(p.relative_to(whole) for p in whole.glob("stages/*/*/agent/trainer/state.npz"))
    assert len(states) == 3  # stage 0: one branch; stage 1: two
    for state in states:
        assert _same_arrays(whole / state, cut / state), state
    assert (whole / "decisions.jsonl").read_text().count("\n") == 4
    columns = ("branches", "steps", "success_rate", "normalized_reward", "maze")
    assert _rows(whole / "progress.csv", columns) == _rows(cut / "progress.csv", columns)


def _coevolution_options(tmp_path: Path) -> list[str]:
    """Small population options: rounds on one maze of 5 or 6 cells a side, validation every 2."""
    path = tmp_path / "coevolution.json"
    options = {"validation": 2, "validation_every": 2, "min_size": 5}
    path.write_text(json.dumps({"coevolution": options}))
    return ["--config", str(path)]


def test_a_jax_coevolution_run_writes_its_folder_and_compiles_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "run"
    sizes: set[str] = set()
    set_mazes = JaxTrainer.set_mazes

    def recording(self: JaxTrainer, mazes: Any) -> None:
        set_mazes(self, mazes)
        sizes.update(maze.split("_")[1] for maze in self.mazes)

    monkeypatch.setattr(JaxTrainer, "set_mazes", recording)
    compiled = run_rollouts._cache_size()
    assert main([*COEVOLUTION, *_coevolution_options(tmp_path), "--out", str(out)]) == 0
    for name in ("progress.csv", "mazes.csv", "evaluations.csv", "agent.zip", "summary.json"):
        assert (out / name).is_file(), name
    assert not (out / "tensorboard").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["framework"] == "jax" and summary["max_cells"] == 36
    assert summary["env_steps"] <= 8000 and summary["scoring_steps"] > 0
    assert summary["mazes_ever"] >= 1
    rows = _rows(out / "progress.csv", ("round", "steps", "members"))
    assert len(rows) >= 3 and all(int(steps) % 20 == 0 for _, steps, _ in rows)
    assert sizes <= {"5x5", "5x6", "6x5", "6x6"} and len(sizes) >= 2, sizes  # mazes of two sizes
    assert run_rollouts._cache_size() - compiled == 1  # ...one compiled training function
    trainers = [p.name for p in (out / "checkpoints").glob("trainer-*")]
    assert trainers == [f"trainer-{summary['rounds']}"]
    capsys.readouterr()
    assert amaze_main(["evaluate", str(out / "agent.zip"), "suite", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["success_rate"] == summary["success_rate"]


def test_a_round_stops_where_the_seconds_budget_runs_out(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Under a seconds budget a round is learnt a piece at a time, and stops once the seconds
    are spent: here after its first rollout, of the 4 or more the round asked for."""
    asked: list[int] = []
    within = JaxCoevolutionRun._train_within_seconds

    def recording(self: JaxCoevolutionRun, rollouts: int) -> Any:
        asked.append(rollouts)
        return within(self, rollouts)

    monkeypatch.setattr(JaxCoevolutionRun, "_train_within_seconds", recording)
    monkeypatch.setattr(JaxCoevolutionRun, "rollouts_per_piece", lambda self: 1)
    out = tmp_path / "run"
    seconds = [a if a != "8000" else "1e-6" for a in COEVOLUTION]
    seconds[seconds.index("--budget-steps")] = "--budget-seconds"
    assert main([*seconds, *_coevolution_options(tmp_path), "--out", str(out)]) == 0
    assert asked[0] >= 4  # a whole round: rollouts of n_steps 5 x 4 envs until episodes end
    assert _rows(out / "progress.csv", ("round", "steps")) == [("1", "20")]  # one rollout


def test_a_killed_jax_coevolution_run_resumes_to_the_same_agent_bit_for_bit(
    tmp_path: Path, kill_at: Any
) -> None:
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    options = _coevolution_options(tmp_path)
    assert main([*COEVOLUTION, *options, "--out", str(whole)]) == 0
    kill_at(20)  # in round 20, after the checkpoints of rounds 1 to 19 (eval_every 40)
    with pytest.raises(Killed):
        main([*COEVOLUTION, *options, "--out", str(cut)])
    assert not (cut / "summary.json").exists()
    resume(cut)
    assert _same_params(whole / "agent.zip", cut / "agent.zip")
    columns = ("round", "steps", "validation", "champion_success_rate", "members", "admitted")
    assert _rows(whole / "progress.csv", columns) == _rows(cut / "progress.csv", columns)
    mazes = ("id", "maze", "origin", "parent", "birth", "difficulty")
    assert _rows(whole / "mazes.csv", mazes) == _rows(cut / "mazes.csv", mazes)
    anytime = ("point", "env_steps", "success_rate", "normalized_reward")
    assert _rows(whole / "evaluations.csv", anytime) == _rows(cut / "evaluations.csv", anytime)


@pytest.mark.parametrize(
    ("argv", "options", "words"),
    [
        (["--tensorboard"], {}, "tensorboard (--tensorboard) True has no effect with framework"),
        (["--robot", "CC15"], {}, "robot CC15 has continuous actions"),
        ([], {"use_sde": True}, "framework jax: hyperparameter 'use_sde' = True is refused"),
        ([], {"stats_window_size": 10}, "'stats_window_size' = 10 is refused"),
        ([], {"policy_kwargs": {"ortho_init": False}}, "'ortho_init' = False is not supported"),
        ([], {"n_step": 5}, "hyperparameter 'n_step' is not one of PPO's"),
        ([], {"gamma": 2.0}, "framework jax: hyperparameter 'gamma'"),
        (["--progress-reward", "1"], {}, "progress_reward 1.0 has no effect with robot DD"),
        (["--progress-reward", "-1"], {}, "progress_reward -1"),
        (
            ["--framework", "sb3", "--progress-reward", "1"],
            {},
            "progress_reward 1.0 has no effect with framework sb3",
        ),
    ],
)
def test_what_the_jax_framework_does_not_do_is_refused_in_one_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    options: dict[str, Any],
    words: str,
) -> None:
    out = tmp_path / "run"
    base = ["--framework", "jax", "--budget-steps", "640", "--no-progress"]
    assert main([*base, *argv, *_options(tmp_path, **options), "--out", str(out)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not out.exists()
