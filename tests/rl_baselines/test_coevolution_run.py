"""``amaze-train`` in the coevolution regime: rounds on a co-evolving maze population."""

from __future__ import annotations

import csv
import itertools
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from amaze.curriculum.maze_population import MAZES_CSV_FIELDS
from amaze.maze import as_mazes, rotations
from amaze.runs.checkpoint import StateCodec, curriculum_classes, read_checkpoint, write_checkpoint
from rl_baselines import RLConfigError
from rl_baselines.cli import main
from rl_baselines.coevolution import RoundEpisodes, SB3CoevolutionRun
from rl_baselines.train import SB3Run, TrainConfig
from rl_baselines.vec_env import SB3VecEnv

#: A2C rollouts of 5 x 4 = 20 steps, rounds on one 5 x 5 maze (as many rollouts as its longest
#: episode may last), validated every 2 rounds, checkpoints every round.
ARGS = ["--algo", "a2c", "--regime", "coevolution", "--budget-steps", "1200"]
ARGS += ["--eval-every", "20", "--no-progress", "--target", "M4_5x5_C1"]


def _round_steps(rows: list[dict[str, str]]) -> list[int]:
    steps = [0, *(int(r["steps"]) for r in rows)]
    return [after - before for before, after in itertools.pairwise(steps)]


def _rows(out: Path, name: str) -> list[dict[str, str]]:
    with (out / name).open(newline="") as stream:
        return list(csv.DictReader(stream))


def _config(folder: Path) -> Path:
    path = folder / "config-in.json"
    path.write_text(json.dumps({"coevolution": {"validation": 2, "validation_every": 2}}))
    return path


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("coevolution")
    out = folder / "run"
    assert main([*ARGS, "--config", str(_config(folder)), "--out", str(out)]) == 0
    return out


def test_a_coevolution_run_writes_its_folder(finished: Path) -> None:
    for name in ("progress.csv", "mazes.csv", "population.png", "agent.zip", "summary.json"):
        assert (finished / name).stat().st_size > 0, name
    assert any((finished / "tensorboard").rglob("events.out.tfevents.*"))
    rows = _rows(finished, "progress.csv")
    rounds = len(rows)
    assert rounds >= 3 and [int(r["round"]) for r in rows] == list(range(1, rounds + 1))
    # whole rollouts, several a round (enough for an episode of a 5 x 5 maze to end)
    assert all(steps % 20 == 0 and steps > 20 for steps in _round_steps(rows)[:-1])
    assert [r["validation"] != "nan" for r in rows] == [k % 2 == 0 for k in range(rounds)]
    summary = json.loads((finished / "summary.json").read_text())
    assert summary["regime"] == "coevolution" and summary["rounds"] == rounds
    assert summary["env_steps"] == int(rows[-1]["steps"]) <= 1200
    assert summary["validation_steps"] > 0
    assert 0 <= summary["unseen_success_rate"] <= 1
    config = json.loads((finished / "config.json").read_text())
    assert config["coevolution"]["batch"] == 1  # n_envs 4: one maze per round
    mazes = _rows(finished, "mazes.csv")
    assert not mazes or list(mazes[0]) == MAZES_CSV_FIELDS
    models = [p.name for p in (finished / "checkpoints").glob("model-*.zip")]
    assert models == [f"model-{rounds}.zip"]


def test_a_resumed_run_goes_on_with_its_population(tmp_path: Path) -> None:
    out = tmp_path / "run"
    short = [*ARGS[:5], "600", *ARGS[6:]]
    assert main([*short, "--config", str(_config(tmp_path)), "--out", str(out)]) == 0
    before, rounds_before = _rows(out, "mazes.csv"), len(_rows(out, "progress.csv"))
    # as if killed after the last round's checkpoint, in a run of twice the budget
    (out / "summary.json").unlink()
    config = json.loads((out / "config.json").read_text())
    (out / "config.json").write_text(json.dumps({**config, "budget_steps": 1200}))
    assert main(["--resume", str(out), "--no-progress"]) == 0
    rows = _rows(out, "progress.csv")
    assert len(rows) > rounds_before and [int(r["round"]) for r in rows] == list(
        range(1, len(rows) + 1)
    )
    after = _rows(out, "mazes.csv")
    kept = ("id", "maze", "origin", "parent", "birth")
    assert [{k: r[k] for k in kept} for r in after[: len(before)]] == [
        {k: r[k] for k in kept} for r in before
    ]
    assert json.loads((out / "summary.json").read_text())["rounds"] == len(rows)


@pytest.mark.slow
def test_a_coevolution_run_on_seconds_alone_stops_once_they_are_spent(tmp_path: Path) -> None:
    out = tmp_path / "run"
    seconds = [*ARGS[:4], "--budget-seconds", "3", *ARGS[6:]]
    assert main([*seconds, "--config", str(_config(tmp_path)), "--out", str(out)]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["budget_steps"] is None and config["budget_seconds"] == 3.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["budget_seconds"] == 3.0 and summary["rounds"] >= 1
    rows = _rows(out, "progress.csv")
    assert [int(r["round"]) for r in rows] == list(range(1, summary["rounds"] + 1))
    # the last round is the first to find the seconds spent, and it is checkpointed
    assert 3 <= summary["seconds"] < 3 + 30
    # (progress.csv rounds seconds to 3 decimals: a round that ended at 2.9996 s reads 3.0)
    assert len(rows) == 1 or float(rows[-2]["seconds"]) <= 3.0
    models = [p.name for p in (out / "checkpoints").glob("model-*.zip")]
    assert models == [f"model-{summary['rounds']}.zip"]


def test_the_regime_chooses_the_run_class() -> None:
    config = TrainConfig.from_dict({"regime": "coevolution"})
    assert SB3Run.run_class_for(config) is SB3CoevolutionRun


@pytest.mark.parametrize(
    ("changes", "bad"),
    [
        ({"coevolution": {"batch": 2}}, "coevolution batch 2 needs n_envs = 4 x batch"),
        ({"n_envs": 8, "coevolution": {"batch": 1}}, "not 8"),
        ({"coevolution": {"score": "fun"}}, "score 'fun'"),
    ],
)
def test_coevolution_config_refusals(changes: dict, bad: str) -> None:
    with pytest.raises(RLConfigError, match=bad):
        TrainConfig.from_dict({"regime": "coevolution", **changes})


def test_eight_environments_take_batches_of_two_mazes() -> None:
    config = TrainConfig.from_dict({"regime": "coevolution", "n_envs": 8})
    assert config.coevolution == {"batch": 2}


def test_a_run_checkpoints_its_first_round_and_never_passes_its_budget(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # a budget that cannot pay one rollout (20 steps) is refused before the folder is written
    small = [*ARGS[:5], "19", *ARGS[6:]]
    assert main([*small, "--out", str(tmp_path / "small")]) == 2
    assert "cannot pay one rollout (20 steps" in capsys.readouterr().err
    assert not (tmp_path / "small").exists()
    # killed right after round 1 (eval_every 1000: no checkpoint due by steps), resumed
    out = tmp_path / "run"
    argv = [*ARGS[:5], "300", "--eval-every", "1000", "--no-progress", "--no-tensorboard"]
    argv += ARGS[-2:]

    class Killed(Exception):
        pass

    def round_then_die(self):
        if self.state.round == 1:
            raise Killed
        return original(self)

    original = SB3CoevolutionRun.play_round
    monkeypatch.setattr(SB3CoevolutionRun, "play_round", round_then_die)
    with pytest.raises(Killed):
        main([*argv, "--config", str(_config(tmp_path)), "--out", str(out)])
    assert (out / "checkpoints" / "state.npz").is_file()
    monkeypatch.setattr(SB3CoevolutionRun, "play_round", original)
    assert main(["--resume", str(out), "--no-progress"]) == 0
    rows = _rows(out, "progress.csv")
    # round 2 was cut to the whole rollouts the budget still paid, and ended the run on it
    assert len(rows) == 2 and int(rows[0]["steps"]) % 20 == 0 and int(rows[1]["steps"]) == 300


def test_a_checkpoint_of_the_older_layout_resumes(tmp_path: Path) -> None:
    """A version 2 state (no time breakdown) is read and goes on."""
    out = tmp_path / "run"
    short = [*ARGS[:5], "600", *ARGS[6:]]
    assert main([*short, "--config", str(_config(tmp_path)), "--out", str(out)]) == 0
    rounds_before = len(_rows(out, "progress.csv"))
    path, state_class = out / "checkpoints" / "state.npz", SB3CoevolutionRun.state_class
    codec = StateCodec([state_class, *curriculum_classes()])
    state = read_checkpoint(path, codec, RLConfigError, state_class)
    del state.__dict__["time"]
    state.version = 2
    write_checkpoint(path, state, codec)
    (out / "summary.json").unlink()
    config = json.loads((out / "config.json").read_text())
    (out / "config.json").write_text(json.dumps({**config, "budget_steps": 1200}))
    assert main(["--resume", str(out), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["rounds"] > rounds_before and summary["time"]["learning"] > 0


def test_a_round_lasts_as_long_as_the_longest_episode_of_its_mazes(tmp_path: Path) -> None:
    config = TrainConfig.from_dict({"algo": "a2c", "regime": "coevolution", "budget_steps": 100})
    run = SB3CoevolutionRun(tmp_path / "run", config)
    run.new_state(None)  # the model; no population needed here
    deadline = run.set_round_mazes(as_mazes(rotations("M4_5x5_C1")))
    engine = SB3VecEnv(rotations("M4_5x5_C1"), "DD", 4).engine
    assert deadline == int(np.ceil(engine.tables.deadline.max())) > 5
    assert run.round_rollouts(deadline) == -(-deadline // 5)


def test_a_rounds_episodes_score_its_mazes_and_fill_in_for_those_without() -> None:
    """PLR's way: the model's own (stochastic) episodes of the round, not one greedy episode."""
    episodes = RoundEpisodes(4)
    ended = [
        {"success": True, "normalized_reward": 1.0},
        {},
        {"success": False, "normalized_reward": -3.0},
        {},
    ]
    for infos in (ended, [{}, {}, {"success": True, "normalized_reward": 0.0}, {}]):
        episodes.locals = {"infos": infos}
        assert episodes._on_step()
    greedy = SimpleNamespace(  # the deterministic episodes, as EpisodeResults gives them
        success=np.array([False, True, False, False]),
        normalized_reward=np.array([-9.0, 0.5, -9.0, -7.0]),
    )
    success, reward = episodes.ended().scores(greedy)
    np.testing.assert_array_equal(success, [[1.0, 1.0, 0.5, 0.0]])
    np.testing.assert_array_equal(reward, [[1.0, 0.5, -1.5, -7.0]])
