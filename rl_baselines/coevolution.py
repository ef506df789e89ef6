"""Reinforcement learning in the ``coevolution`` regime: an SB3 agent and a maze population.

``amaze-train --algo ppo --regime coevolution --budget-steps 300000 --out runs/co``
trains one SB3 model on a :class:`~amaze.curriculum.coevolution.MazePopulation`
that evolves beside it, in *rounds*:

1. the population proposes a batch of ``n_envs / 4`` mazes (one environment
   per rotation; ``coevolution.batch`` defaults to that and must match it);
2. the model learns one rollout (``n_steps x n_envs`` env steps) on them;
3. the agent (acting deterministically) plays the batch's rotations once:
   its results score each maze (``learnability`` uses the share of the 4
   rotations it solved, as the single-agent score of Rutherford et al.'s
   SFL; ``regret`` the best R̄ it ever had there minus its R̄ now) and the
   population admits, replays and retires mazes as in the evolution regime;
4. every ``coevolution.validation_every`` rounds the agent plays the
   validation mazes (16 family mazes, never the suite's seeds); the best
   there so far is the champion (``checkpoints/champion.zip``), the run's
   agent (``agent.zip`` at the end), which ``summary.json`` also reports on
   32 unseen family mazes.

The budget is ``budget_steps`` training steps (spent in whole rollouts, as in
the other regimes: a round starts only if its rollout fits in what is left, a
budget that cannot pay one is refused before the folder is written) and/or
``budget_seconds`` seconds of the run (everything it does, over every resumed
part; a run may end up to one round past it); it plays at least one round
(its agent is a champion of the validations). The steps of the scoring and
validation episodes are reported apart (``scoring_steps``,
``validation_steps``).

**Run folder**: ``config.json``; ``progress.csv`` (a row per round);
``checkpoints/model-<round>.zip`` and ``checkpoints/state.npz`` (the maze
population with its generator, counters and champion, naming the model file;
the model is written first, the state last, each atomically, so a kill
between the two leaves the previous pair) and ``champion.zip`` + ``.json``;
``agent.zip`` + ``agent.json``; ``mazes.csv``; ``population.png``; ``summary.json``;
``trajectories/``; ``tensorboard/`` (SB3's losses and returns, and
``coevolution/validation_success_rate``, ``coevolution/population_difficulty``...).
A resumed run continues from the last checkpoint with the population as it
was; SB3 does not save its random state, so it is a faithful continuation,
not a bit-identical replay. Where a run on a seconds budget ends depends on
the machine's speed as well.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm

from amaze.agents.engine import BatchEngine
from amaze.curriculum.coevolution import (
    MazePopulation,
    MazePopulationConfig,
    MazeResult,
    mazes_csv,
)
from amaze.curriculum.picture import save_population_png
from amaze.curriculum.validation import unseen_mazes, validation_mazes
from amaze.evaluation.policy import EpisodeResults, run_episodes
from amaze.maze import Maze, as_mazes, rotations
from amaze.runs.checkpoint import (
    StateCodec,
    curriculum_classes,
    read_checkpoint,
    write_checkpoint,
)
from amaze.runs.folder import write_bytes
from amaze.runs.lifecycle import Run
from amaze.runs.progress import Progress
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent, load_sb3_model
from rl_baselines.config import TrainConfig, check_rollout_fits
from rl_baselines.learner import new_sb3_model
from rl_baselines.vec_env import SB3VecEnv

__all__ = ["SB3CoevolutionRun"]

PROGRESS_FIELDS = (
    "round", "steps", "seconds", "batch_success_rate", "validation", "validation_success_rate",
    "champion_success_rate", "members", "admitted", "batch_difficulty", "population_difficulty",
)  # fmt: skip
CHECKPOINT_VERSION = 2


@dataclass
class _State:
    """The run state of ``checkpoints/state.npz`` (the model is in ``model_file``)."""

    mazes: MazePopulation
    round: int = 0
    steps: int = 0
    seconds: float = 0.0
    scoring_steps: int = 0
    validation_steps: int = 0
    champion_fitness: float = -np.inf
    champion_success_rate: float = 0.0
    champion_round: int = 0
    #: Training steps when the champion was found.
    champion_steps: int = 0
    model_file: str = ""
    version: int = CHECKPOINT_VERSION
    #: The SHA-256 of the run's ``config.json`` (:attr:`~amaze.runs.lifecycle.Run.config_digest`).
    config_sha256: str | None = None


def _codec() -> StateCodec:
    """What ``state.npz`` may hold: the run state and the maze population's classes."""
    return StateCodec([_State, *curriculum_classes()])


def _play(mazes: list[Maze], agent: SB3Agent) -> EpisodeResults:
    """One episode of ``agent`` in each of ``mazes``."""
    return run_episodes(BatchEngine(mazes, agent.robot, len(mazes)), agent)


class SB3CoevolutionRun(Run):
    """Rounds of one rollout on a batch of a co-evolving maze population."""

    config_class = TrainConfig
    progress_fields = PROGRESS_FIELDS
    position_field = "round"
    checkpoint_files = ("state.npz",)
    agent_file = "agent.zip"
    outputs: ClassVar[tuple[str, ...]] = (
        "agent.zip", "summary.json", "progress.csv", "mazes.csv", "population.png",
        "tensorboard/",
    )  # fmt: skip
    config: TrainConfig

    def __init__(self, out: str | os.PathLike, config: TrainConfig) -> None:
        super().__init__(out, config)
        torch.set_num_threads(1)
        self.model: BaseAlgorithm | None = None
        self.state: _State
        self.started = time.monotonic()
        self.seconds_before = 0.0

    @cached_property
    def options(self) -> MazePopulationConfig:
        return MazePopulationConfig.from_dict(self.config.coevolution)

    @cached_property
    def validation(self) -> list[Maze]:
        """The validation mazes in their rotations (the champion is chosen there)."""
        c = self.config
        return as_mazes(rotations(validation_mazes(c.target, self.options.validation, c.seed)))

    def seconds(self) -> float:
        """Wall-clock seconds of the run, over every resumed part of it."""
        return self.seconds_before + (time.monotonic() - self.started)

    def budget_spent(self) -> bool:
        """True once the steps left cannot pay a rollout, or the seconds are spent."""
        c, s = self.config, self.state
        return (c.budget_steps is not None and c.budget_steps - s.steps < self.rollout) or (
            c.budget_seconds is not None and self.seconds() >= c.budget_seconds
        )

    def _env(self, mazes: list[Maze]) -> SB3VecEnv:
        c = self.config
        return SB3VecEnv(mazes, c.robot, c.n_envs, c.seed)

    def _first_env(self) -> SB3VecEnv:
        """The environment a model is built with: the target's rotations (replaced every round)."""
        return self._env(as_mazes(rotations(self.config.target)) * (self.config.n_envs // 4))

    def _tensorboard_dir(self) -> str | None:
        return str(self.out / "tensorboard") if self.config.tensorboard else None

    # -- the lifecycle's hooks --------------------------------------------------------

    def start(self) -> None:
        c = self.config
        validation = validation_mazes(c.target, self.options.validation, c.seed)
        self.state = _State(MazePopulation.for_run(c.target, self.options, c.seed, validation))
        self.model = new_sb3_model(
            c.algo, c.robot, self._first_env(), c.seed, c.hyperparameters, self._tensorboard_dir()
        )
        check_rollout_fits(c, self.rollout, "learns one rollout a round")

    @property
    def rollout(self) -> int:
        """Env steps of a round's rollout (``n_steps x n_envs``)."""
        assert self.model is not None
        return int(self.model.n_steps) * self.config.n_envs

    def restore(self) -> int | None:
        path = self.checkpoints / "state.npz"
        if not path.exists():
            return None
        state = read_checkpoint(path, _codec(), RLConfigError, expected=_State)
        if state.version != CHECKPOINT_VERSION:
            raise RLConfigError(f"checkpoint {str(path)!r} is of version {state.version!r}")
        self.check_config_digest(state.config_sha256, f"checkpoint {str(path)!r}")
        model_file = self.checkpoints / state.model_file
        if not state.model_file or model_file.parent != self.checkpoints:
            raise RLConfigError(f"checkpoint {str(path)!r} names no model file of its folder")
        if not model_file.exists():
            raise RLConfigError(f"checkpoint file {str(model_file)!r} is missing")
        self.model = load_sb3_model(
            model_file,
            self.config.algo,
            self.config.robot,
            env=self._first_env(),
            tensorboard_log=self._tensorboard_dir(),
        )
        self.model.num_timesteps = state.steps
        if self.champion_file.exists() or self.champion_file.is_symlink():
            SB3Agent.load(self.champion_file)  # a damaged champion is refused here, by name
        self.state = state
        self.seconds_before = state.seconds
        self.started = time.monotonic()
        return state.round

    def train(self, progress: str) -> None:
        """Rounds until a budget is spent (at least one), checkpointing every ``eval_every`` steps.

        The budget is looked at once after each round, so the round that
        spends it is also the one checkpointed last.
        """
        c, s = self.config, self.state
        last_checkpoint = s.steps
        spent = s.round > 0 and self.budget_spent()
        total, unit = (c.budget_steps, "steps") if c.budget_steps else (c.budget_seconds, "s")
        desc = f"{c.algo} coevolution seed {c.seed}"
        with Progress(total, unit, desc, mode=progress) as shown:
            while not spent:
                row = self.round()
                self.progress.append(row)
                spent = self.budget_spent()
                # after the first round too: a run killed later always has a checkpoint
                if s.round == 1 or s.steps - last_checkpoint >= c.eval_every or spent:
                    self.save_checkpoint()
                    last_checkpoint = s.steps
                done = s.steps if c.budget_steps else self.seconds()
                shown.update(
                    done, round=s.round, champion_success_rate=f"{s.champion_success_rate:.2f}"
                )
        if s.round == 0 or not self.champion_file.exists():
            raise RLConfigError("the run played no round")

    @property
    def champion_file(self) -> Path:
        """The best agent on the validation mazes so far (at the top in older run folders)."""
        legacy = self.out / "champion.zip"
        return legacy if legacy.exists() else self.checkpoints / "champion.zip"

    def final_agent(self) -> SB3Agent:
        return SB3Agent.load(self.champion_file)

    def save_agent(self, agent: SB3Agent, path: Path) -> None:
        agent.save(path)

    def agent_figures(self) -> dict[str, Any]:
        s = self.state
        return {
            "agent_rule": "best-validation",
            "agent_steps": s.champion_steps,
            "agent_round": s.champion_round,
            "agent_untrained": False,  # validated after its round's rollout was learnt
        }

    def stop_reason(self) -> str:
        c, s = self.config, self.state
        if c.budget_steps is not None and c.budget_steps - s.steps < self.rollout:
            left = c.budget_steps - s.steps
            return f"the {left:,} steps left cannot pay another round's rollout ({self.rollout:,})"
        return ""

    def figures(self) -> dict[str, Any]:
        c, s = self.config, self.state
        agent = self.final_agent()
        unseen = _play(as_mazes(rotations(unseen_mazes(c.target, c.seed))), agent)
        return {
            "algo": c.algo,
            "regime": c.regime,
            "robot": c.robot,
            "seed": c.seed,
            "target": c.target,
            "rounds": s.round,
            "env_steps": s.steps,
            "scoring_steps": s.scoring_steps,
            "validation_steps": s.validation_steps,
            "seconds": round(self.seconds(), 3),
            "budget_steps": c.budget_steps,
            "budget_seconds": c.budget_seconds,
            "champion_validation_normalized_reward": s.champion_fitness,
            "champion_validation_success_rate": s.champion_success_rate,
            "champion_round": s.champion_round,
            "unseen_success_rate": float(unseen.success.mean()),
            "unseen_normalized_reward": float(unseen.normalized_reward.mean()),
            "mazes_ever": len(s.mazes.records),
            "members": len(s.mazes.members),
            "coevolution": self.options.to_dict(),
        }

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        """The champion in the target's 4 rotations."""
        return [(f"target-rotation-{i}", m) for i, m in enumerate(rotations(self.config.target))]

    def extra_outputs(self) -> None:
        s = self.state
        self.write_mazes_csv()
        title = f"maze population after {s.round} rounds ({len(s.mazes.records)} ever)"
        save_population_png(s.mazes, self.out / "population.png", title)

    # -- one round ------------------------------------------------------------------

    def round(self) -> dict[str, Any]:
        """Learn one rollout on a batch, score its mazes, validate when due."""
        c, s, model = self.config, self.state, self.model
        assert model is not None
        batch = s.mazes.propose()
        mazes = [rotated for item in batch for rotated in s.mazes.generated(item.maze)]
        model.set_env(self._env(mazes))
        rollout = int(model.n_steps) * c.n_envs
        model.learn(total_timesteps=rollout, reset_num_timesteps=False, tb_log_name="coevolution")
        s.steps = int(model.num_timesteps)
        agent = SB3Agent(model, c.robot, c.algo)
        played = _play(mazes, agent)
        s.scoring_steps += int(played.steps.sum())
        shape = (len(batch), 4)
        success = played.success.reshape(shape).astype(float)
        reward = played.normalized_reward.reshape(shape)
        report = s.mazes.update(
            batch, [MazeResult.of(success[b][None], reward[b][None]) for b in range(len(batch))]
        )
        s.round += 1
        validation = validation_success_rate = float("nan")
        if (s.round - 1) % self.options.validation_every == 0:
            checked = _play(self.validation, agent)
            s.validation_steps += int(checked.steps.sum())
            validation = float(checked.normalized_reward.mean())
            validation_success_rate = float(checked.success.mean())
            if validation > s.champion_fitness:
                s.champion_fitness, s.champion_success_rate = validation, validation_success_rate
                s.champion_round, s.champion_steps = s.round, s.steps
                agent.save(self.champion_file)
        members, difficulty = len(s.mazes.members), s.mazes.mean_difficulty()
        logger = model.logger
        for key, value in (
            ("validation_success_rate", validation_success_rate),
            ("champion_success_rate", s.champion_success_rate),
            ("batch_success_rate", float(success.mean())),
            ("batch_difficulty", report.batch_difficulty),
            ("population_difficulty", difficulty),
            ("members", members),
        ):
            if not np.isnan(value):
                logger.record(f"coevolution/{key}", value)
        logger.dump(s.steps)
        s.seconds = self.seconds()
        return {
            "round": s.round,
            "steps": s.steps,
            "seconds": round(s.seconds, 3),
            "batch_success_rate": float(success.mean()),
            "validation": validation,
            "validation_success_rate": validation_success_rate,
            "champion_success_rate": s.champion_success_rate,
            "members": members,
            "admitted": report.admitted,
            "batch_difficulty": round(report.batch_difficulty, 4),
            "population_difficulty": round(difficulty, 4),
        }

    # -- checkpoints ------------------------------------------------------------------

    def save_checkpoint(self) -> None:
        """The model as ``model-<round>.zip``, then the state naming it; older models go."""
        s, model = self.state, self.model
        assert model is not None
        self.checkpoints.mkdir(parents=True, exist_ok=True)
        name = f"model-{s.round}.zip"
        tmp = self.checkpoints / f".{name}.tmp.zip"
        model.save(tmp)
        os.replace(tmp, self.checkpoints / name)
        s.model_file, s.seconds = name, self.seconds()
        s.config_sha256 = self.config_digest
        write_checkpoint(self.checkpoints / "state.npz", s, _codec())
        for old in self.checkpoints.glob("model-*.zip"):
            if old.name != name:
                old.unlink()
        self.write_mazes_csv()

    def write_mazes_csv(self) -> Path:
        """``mazes.csv``: every maze that was ever a member, written atomically."""
        text = mazes_csv(self.state.mazes.records)
        return write_bytes(self.out / "mazes.csv", text.encode("utf-8"))
