"""The co-evolution loop of amaze.runs.coevolution, with a toy trainer: folder, budgets, resume.

The toy trainer's "agents" are random controllers with the round's seeds: it
learns nothing, but it is cheap and deterministic, which is all the loop's
bookkeeping (population rounds, champion, checkpoints, budgets, resume, the
config check) needs. The real trainers are tested in ``tests/evolution`` and
``tests/rl_baselines``.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.curriculum.maze_population import MAZES_CSV_FIELDS, MazePopulation, MazePopulationConfig
from amaze.errors import AmazeError
from amaze.evaluation.controllers import RandomController
from amaze.evaluation.policy import run_episodes
from amaze.maze import Maze, as_mazes, rotations
from amaze.runs.branches import Clock
from amaze.runs.checkpoint import StateCodec, curriculum_classes, read_checkpoint, write_checkpoint
from amaze.runs.coevolution import (
    POPULATION_FIELDS,
    BatchResults,
    CoevolutionRun,
    CoevolutionState,
    Validation,
)
from amaze.runs.config import option
from amaze.runs.regime import RegimeConfig

TARGET = "M0_6x6_C1"
CONFIG = {
    "regime": "coevolution",
    "target": TARGET,
    "budget_steps": None,
    "max_generations": 9,  # the lifecycle's name of a budget of rounds
    "coevolution": {"capacity": 4, "batch": 2, "validation": 2, "validation_every": 2},
}


class ToyError(AmazeError):
    pass


@dataclass
class ToyConfig(RegimeConfig):
    error = ToyError
    supported_regimes = ("direct", "coevolution")

    algo: str = option("toy", "the toy trainer")
    budget_steps: int | None = option(None, "environment steps")
    budget_seconds: float | None = option(None, "seconds")
    max_generations: int | None = option(None, "rounds")
    agents: int = option(3, "random agents a round")

    def coevolution_defaults(self) -> dict[str, Any]:
        return {"validation_every": 2}

    def check_coevolution_options(self, options: MazePopulationConfig) -> None:
        if options.batch == 7:
            raise ToyError("a toy cannot play a batch of 7")


@dataclass(kw_only=True)
class _ToyState(CoevolutionState):
    VERSION: ClassVar[int] = 2

    champion_seed: int = -1

    @classmethod
    def upgrade(cls, attributes: dict[str, Any]) -> dict[str, Any]:
        if attributes.get("version") == 1:  # version 1 called rounds "epochs"
            attributes["round"] = attributes.pop("epoch")
            attributes["version"] = cls.VERSION
        return attributes


def _codec() -> StateCodec:
    return StateCodec([_ToyState, *curriculum_classes()])


class ToyRun(CoevolutionRun):
    config_class = ToyConfig
    state_class = _ToyState
    agent_file = "agent.json"
    position_field = "epoch"
    progress_fields = ("epoch", "steps", "seconds", "batch_success_rate", *POPULATION_FIELDS)
    time_parts = ("playing",)

    def new_state(self, mazes: MazePopulation) -> _ToyState:
        return _ToyState(mazes)

    def state_codec(self) -> StateCodec:
        return _codec()

    def restore_learner(self, state: CoevolutionState) -> None:
        pass

    def smallest_unit(self) -> tuple[int, str, str]:
        episodes = 4 * self.options.batch
        return self.config.agents * episodes, "epoch", f"{episodes} episodes"

    def round_limit(self) -> int | None:
        return self.config.max_generations

    def checkpoint_due(self, steps: int, seconds: float) -> bool:
        return self.state.round % 3 == 0

    def _agents(self) -> list[RandomController]:
        first = 100 * self.state.round
        return [RandomController("DD", seed=first + k) for k in range(self.config.agents)]

    def learn(self, mazes: list[Maze], clock: Clock) -> BatchResults:
        agents = self._agents()
        played = [run_episodes(BatchEngine(mazes, "DD", len(mazes)), a) for a in agents]
        self.state.steps += sum(int(p.steps.sum()) for p in played)
        clock.lap("playing")
        success = np.array([p.success for p in played])
        figures = {"batch_success_rate": float(success.mean())}
        reward = np.array([p.normalized_reward for p in played])
        return BatchResults(success, reward, agents, figures)

    def validate(self, candidates: Sequence[Any]) -> Validation:
        mazes = as_mazes(rotations(self.validation_mazes))
        played = [run_episodes(BatchEngine(mazes, "DD", len(mazes)), a) for a in candidates]
        return Validation(
            np.array([p.normalized_reward.mean() for p in played]),
            np.array([p.success.mean() for p in played]),
            sum(int(p.steps.sum()) for p in played),
        )

    def keep_champion(self, candidates: Sequence[Any], index: int) -> None:
        self.state.champion_seed = candidates[index].seed

    def own_figures(self) -> dict[str, Any]:
        return {"champion_seed": self.state.champion_seed}

    def final_agent(self) -> RandomController:
        return RandomController("DD", seed=self.state.champion_seed)

    def save_agent(self, agent: RandomController, path: Path) -> None:
        path.write_text(json.dumps({"controller": "random", "seed": agent.seed}))


class Killed(Exception):
    pass


def _rows(out: Path, name: str) -> list[dict[str, str]]:
    with (out / name).open(newline="") as stream:
        rows = list(csv.DictReader(stream))
    for row in rows:
        row.pop("seconds", None)
    return rows


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("coevolution") / "run"
    ToyRun.fresh(CONFIG, out)
    return out


def test_a_run_writes_the_regimes_folder(finished: Path) -> None:
    for name in ("mazes.csv", "population.png", "coevolution.png", "checkpoints/state.npz"):
        assert (finished / name).stat().st_size > 0, name
    assert len(list((finished / "trajectories").glob("target-rotation-*.png"))) == 4
    rows = _rows(finished, "progress.csv")
    assert [int(r["epoch"]) for r in rows] == list(range(1, 10))
    assert [r["validation"] != "nan" for r in rows] == [True, False] * 4 + [True]
    mazes = _rows(finished, "mazes.csv")
    assert not mazes or list(mazes[0]) == MAZES_CSV_FIELDS
    assert sum(int(r["admitted"]) for r in rows) == len(mazes)
    summary = json.loads((finished / "summary.json").read_text())
    # the trainer's word for a round names its keys
    assert summary["epochs"] == 9 and summary["agent_epoch"] == summary["champion_epoch"]
    assert summary["agent_rule"] == "best-validation" and summary["agent_untrained"] is False
    assert summary["champion_seed"] % 100 < 3 and summary["champion_seed"] // 100 < 9
    assert 0 <= summary["unseen_success_rate"] <= 1 and summary["validation_steps"] > 0
    assert set(summary["time"]) == {"playing", "mazes", "validation", "logging_and_checkpoints"}
    assert sum(summary["time"].values()) == pytest.approx(summary["seconds"], abs=0.01)
    assert summary["stopped_early"] is None  # the round limit was reached


def test_a_killed_run_resumes_where_its_checkpoint_is(
    finished: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "run"
    original = ToyRun.play_round

    def killed_in_round_5(self: ToyRun) -> dict[str, Any]:
        if self.state.round == 4:
            raise Killed
        return original(self)

    monkeypatch.setattr(ToyRun, "play_round", killed_in_round_5)
    with pytest.raises(Killed):
        ToyRun.fresh(CONFIG, out)
    monkeypatch.undo()
    # checkpoints after the first epoch and every third one: row 4 is dropped on resume
    state = read_checkpoint(out / "checkpoints" / "state.npz", _codec(), ToyError, _ToyState)
    assert state.round == 3 and len(_rows(out, "progress.csv")) == 4
    ToyRun.resume(out)
    assert _rows(out, "progress.csv") == _rows(finished, "progress.csv")
    assert _rows(out, "mazes.csv") == _rows(finished, "mazes.csv")
    ours, theirs = (json.loads((o / "summary.json").read_text()) for o in (out, finished))
    assert ours["champion_seed"] == theirs["champion_seed"]


def test_an_older_state_layout_is_upgraded_when_read(finished: Path, tmp_path: Path) -> None:
    codec = _codec()
    state = read_checkpoint(finished / "checkpoints/state.npz", codec, ToyError, _ToyState)
    attributes = state.__dict__
    attributes["epoch"], attributes["version"] = attributes.pop("round"), 1
    write_checkpoint(tmp_path / "old.npz", state, codec)
    again = read_checkpoint(tmp_path / "old.npz", codec, ToyError, _ToyState)
    assert again.round == 9 and again.version == 2 and "epoch" not in again.__dict__


def test_budgets_are_hard_limits(tmp_path: Path) -> None:
    # 3 agents x 2 mazes x 4 rotations, a step each at least: 24 steps
    with pytest.raises(ToyError, match=r"budget_steps 20 cannot pay one epoch \(24 steps"):
        ToyRun.fresh({**CONFIG, "budget_steps": 20}, tmp_path / "small")
    assert not (tmp_path / "small").exists()
    out = tmp_path / "run"
    result = ToyRun.fresh({**CONFIG, "max_generations": None, "budget_steps": 5000}, out)
    steps = [0, *(int(r["steps"]) for r in _rows(out, "progress.csv"))]
    assert all(before <= 5000 - 24 for before in steps[:-1])  # each epoch's unit was left
    assert 5000 - steps[-1] < 24 and result.summary["stopped_early"] is None


def test_the_config_is_checked_in_one_place() -> None:
    assert ToyConfig.from_dict({"regime": "coevolution"}).coevolution == {"validation_every": 2}
    with pytest.raises(ToyError, match="capacity 2 is smaller than batch 3"):
        ToyConfig.from_dict({**CONFIG, "coevolution": {"capacity": 2, "batch": 3}})
    with pytest.raises(ToyError, match="a toy cannot play a batch of 7"):
        ToyConfig.from_dict({**CONFIG, "coevolution": {"batch": 7}})
    with pytest.raises(ToyError, match=r"coevolution .* has no effect in the direct regime"):
        ToyConfig.from_dict({"coevolution": {"batch": 2}})
