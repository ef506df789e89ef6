"""Reinforcement learning in the ``coevolution`` regime: an RL agent and a maze population.

``amaze-train --algo ppo --regime coevolution --budget-steps 300000 --out runs/co``
runs the shared co-evolution loop (:class:`~amaze.runs.coevolution.CoevolutionRun`:
the population, the champion on validation mazes, budgets, checkpoints,
``mazes.csv``, ``population.png``, ``coevolution.png``) with one RL model as
its learner (:class:`RLCoevolutionRun`; SB3's here, :class:`SB3CoevolutionRun`;
the JAX learners' in :mod:`rl_baselines.jax.coevolution`), in *rounds*:

1. the population proposes a batch of ``n_envs / 4`` mazes (one environment
   per rotation; ``coevolution.batch`` defaults to that and must match it);
2. the model learns on them, from a fresh start in every environment, for as
   many rollouts (``n_steps x n_envs`` env steps each) as its longest episode
   may last: ``ceil(deadline / n_steps)``, where ``deadline`` is the longest
   deadline of the batch's mazes in steps (:meth:`SB3CoevolutionRun.round_rollouts`).
   A round shorter than an episode would cut every episode before it could
   end: the environments restart on the next batch's mazes each round, so an
   agent learning from rollouts of a few steps (A2C's 5) would never see the
   end of an episode, nor the goal, and never learn (what A2C co-evolution
   did with rounds of one rollout);
3. the round's own episodes score each maze, as PLR and ACCEL score levels
   from the student's training trajectories: the share of the episodes the
   model (acting stochastically, as it learns) ended at the goal in each
   rotation, and their mean R̄ (``learnability`` is ``p (1 - p)`` of that
   share; ``regret`` the best R̄ ever had there minus the R̄ now). A single
   deterministic agent rarely solves a fresh maze early in training, so
   scoring it alone left the population empty, nothing admitted (MCC's
   criterion: solved at least once), and the regime a domain randomisation
   too hard to learn from (A2C co-evolution learned nothing at 150 k steps,
   suite success 0). The agent also plays each rotation once, acting
   deterministically: ``batch_success_rate`` (and the score of a rotation
   whose every episode of the round was still running at its end);
4. every ``coevolution.validation_every`` rounds the agent plays the
   validation mazes; the best there so far is the champion
   (``checkpoints/champion.zip``), the run's agent (``agent.zip`` at the end).

What is RL's own here: the rollout on a batch and the scoring episodes,
the model in the checkpoint, the champion as an SB3 zip (either framework),
SB3's TensorBoard logs and the figures ``framework``, ``scoring_steps`` and
``champion_validation_normalized_reward``. The budget counts training steps
only (spent in whole rollouts: a round starts only if its rollout fits in
what is left); the steps of the scoring and validation episodes are reported
apart (``scoring_steps``, ``validation_steps``). Under a seconds budget a
round is learnt a piece at a time (a rollout with SB3, one compiled call of
rollouts with JAX) and stops once the seconds are spent: a slow network's
round on large mazes lasts minutes, and played whole it would overrun the
budget by as much. A checkpoint is written every ``eval_every`` training
steps.

**Run folder** (SB3): the loop's, and ``checkpoints/model-<round>.zip`` (the
model; the state names it, the model is written first and the state last,
each atomically, so a kill between the two leaves the previous pair),
``checkpoints/champion.zip`` + ``.json``; ``agent.zip`` + ``agent.json``;
``tensorboard/`` (SB3's losses and returns, and
``coevolution/validation_success_rate``, ``coevolution/population_difficulty``...).
SB3 does not save its random state, so a resumed run is a faithful
continuation, not a bit-identical replay.
"""

from __future__ import annotations

import os
from abc import abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback

from amaze.agents.engine import BatchEngine
from amaze.curriculum.maze_population import MazePopulation
from amaze.evaluation.policy import EpisodeResults, run_episodes
from amaze.maze import Maze, as_mazes, rotations
from amaze.runs.branches import Clock
from amaze.runs.checkpoint import StateCodec, curriculum_classes
from amaze.runs.coevolution import BatchResults, CoevolutionRun, CoevolutionState, Validation
from amaze.runs.coevolution_picture import Curve
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent, load_sb3_model
from rl_baselines.config import TrainConfig
from rl_baselines.learner import new_sb3_model
from rl_baselines.vec_env import SB3VecEnv

__all__ = ["EndedEpisodes", "RLCoevolutionRun", "SB3CoevolutionRun", "named_checkpoint"]

PROGRESS_FIELDS = (
    "round", "steps", "seconds", "batch_success_rate", *CoevolutionRun.population_fields,
)  # fmt: skip
#: The ``progress.csv`` columns also logged to TensorBoard (as ``coevolution/<key>``).
TENSORBOARD_KEYS = (
    "validation_success_rate", "champion_success_rate", "batch_success_rate",
    "batch_difficulty", "population_difficulty", "members",
)  # fmt: skip


@dataclass(kw_only=True)
class _State(CoevolutionState):
    """The run state of ``checkpoints/state.npz``: the loop's, and the model file it names."""

    #: Version 3 adds the loop's time breakdown.
    VERSION: ClassVar[int] = 3

    #: Env steps of the episodes that scored the batches.
    scoring_steps: int = 0
    model_file: str = ""

    @classmethod
    def upgrade(cls, attributes: dict[str, Any]) -> dict[str, Any]:
        """A version 2 state kept no time breakdown."""
        if attributes.get("version") == 2:
            attributes.setdefault("time", {})
            attributes["version"] = cls.VERSION
        return attributes


def _play(mazes: list[Maze], agent: Any) -> EpisodeResults:
    """One episode of ``agent`` in each of ``mazes``."""
    return run_episodes(BatchEngine(mazes, agent.robot, len(mazes)), agent)


@dataclass(frozen=True)
class EndedEpisodes:
    """The episodes each environment ended while the learner learned on a round's mazes.

    ``count``, ``successes`` and ``normalized_reward`` (their sum) are
    ``(n_envs,)``; environment ``k`` plays maze ``k`` of the round (one per
    rotation), so its episodes are that maze's.
    """

    count: np.ndarray
    successes: np.ndarray
    normalized_reward: np.ndarray

    def merged(self, other: EndedEpisodes) -> EndedEpisodes:
        """The episodes of both (two pieces of one round)."""
        return EndedEpisodes(
            self.count + other.count,
            self.successes + other.successes,
            self.normalized_reward + other.normalized_reward,
        )

    def scores(self, played: EpisodeResults) -> tuple[np.ndarray, np.ndarray]:
        """``(1, mazes)`` success shares and mean R̄: of the round's episodes where a
        maze has some, else of the deterministic episode ``played``."""
        success = played.success.astype(np.float64)
        reward = played.normalized_reward.astype(np.float64)
        ended = self.count > 0
        success[ended] = self.successes[ended] / self.count[ended]
        reward[ended] = self.normalized_reward[ended] / self.count[ended]
        return success[None], reward[None]


class RoundEpisodes(BaseCallback):
    """The episodes each environment ended while an SB3 model learned (from SB3's ``infos``)."""

    def __init__(self, n_envs: int) -> None:
        super().__init__()
        self.count = np.zeros(n_envs, dtype=np.int64)
        self.successes = np.zeros(n_envs)
        self.normalized_reward = np.zeros(n_envs)

    def _on_step(self) -> bool:
        for env, info in enumerate(self.locals["infos"]):
            if "success" in info:  # an episode ended
                self.count[env] += 1
                self.successes[env] += float(info["success"])
                self.normalized_reward[env] += float(info["normalized_reward"])
        return True

    def ended(self) -> EndedEpisodes:
        return EndedEpisodes(self.count, self.successes, self.normalized_reward)


class RLCoevolutionRun(CoevolutionRun):
    """Rounds of rollouts on a batch of a co-evolving maze population, whatever the framework.

    A framework supplies its learner (:meth:`new_state`, :meth:`restore_learner`,
    :meth:`save_learner`), the rollout size, and a round's training
    (:meth:`set_round_mazes`, :meth:`train_round`, :meth:`agent_now`); this
    class sizes the rounds, scores the batch, validates and keeps the champion.
    """

    config_class = TrainConfig
    config: TrainConfig
    agent_file = "agent.zip"
    position_field = "round"
    progress_fields = PROGRESS_FIELDS
    time_parts = ("learning", "scoring")
    validation_spends_budget = False  # the budget is training steps
    batch_plot = ("success on the batch", (Curve("batch_success_rate", "the agent"),))

    # -- the framework's part ---------------------------------------------------

    @property
    @abstractmethod
    def rollout(self) -> int:
        """Env steps of a round's rollout (``n_steps x n_envs``)."""

    @property
    @abstractmethod
    def n_steps(self) -> int:
        """Steps of each environment in a rollout."""

    @abstractmethod
    def set_round_mazes(self, mazes: list[Maze]) -> int:
        """Put the environments in ``mazes`` (one each, from a fresh start); their
        longest deadline in whole steps."""

    @abstractmethod
    def train_round(self, rollouts: int) -> EndedEpisodes:
        """Learn from ``rollouts`` rollouts on the round's mazes; the episodes they ended.

        The learner's env steps are then in ``state.steps``.
        """

    @abstractmethod
    def agent_now(self) -> Any:
        """The policy now, acting deterministically (``save`` writes an SB3 agent)."""

    # -- the loop's hooks ---------------------------------------------------------

    @cached_property
    def validation(self) -> list[Maze]:
        """The validation mazes in their rotations."""
        return as_mazes(rotations(self.validation_mazes))

    @property
    def champion_file(self) -> Path:
        """The best agent on the validation mazes so far (at the top in older run folders)."""
        legacy = self.out / "champion.zip"
        return legacy if legacy.exists() else self.checkpoints / "champion.zip"

    def round_rollouts(self, deadline: int) -> int:
        """The rollouts of a round whose longest episode may last ``deadline`` steps:
        enough for it to end."""
        return max(1, -(-int(deadline) // self.n_steps))

    def smallest_unit(self) -> tuple[int, str, str]:
        """One rollout: ``n_steps x n_envs`` env steps."""
        rollout, n_envs = self.rollout, self.config.n_envs
        return rollout, "rollout", f"n_steps {rollout // n_envs} x n_envs {n_envs}"

    def checkpoint_due(self, steps: int, seconds: float) -> bool:
        return steps >= self.config.eval_every

    def learn(self, mazes: list[Maze], clock: Clock) -> BatchResults:
        """Rollouts on the batch (their episodes score it), then the agent plays each maze once."""
        c, s = self.config, self.state
        rollouts = self.round_rollouts(self.set_round_mazes(mazes))
        if c.budget_steps is not None:  # whole rollouts, never past the budget
            rollouts = min(rollouts, (c.budget_steps - s.steps) // self.rollout)
        ended = self._train_within_seconds(rollouts)
        clock.lap("learning")
        agent = self.agent_now()
        played = _play(mazes, agent)
        s.scoring_steps += int(played.steps.sum())
        clock.lap("scoring")
        success, reward = ended.scores(played)
        figures = {"batch_success_rate": float(played.success.mean())}
        return BatchResults(success, reward, [agent], figures)

    def rollouts_per_piece(self) -> int:
        """Rollouts learnt between two looks at the clock under a seconds budget."""
        return 1

    def _train_within_seconds(self, rollouts: int) -> EndedEpisodes:
        """The round's ``rollouts``; under a seconds budget, in pieces of
        :meth:`rollouts_per_piece`, stopping once the budget's seconds are spent.

        A round lasts until its longest episode can end (:meth:`round_rollouts`):
        on 20x20 mazes and a continuous robot's deadlines, a slow network's round
        takes minutes, and a round played whole would run past the budget by
        as much.
        """
        c = self.config
        if c.budget_seconds is None:
            return self.train_round(rollouts)
        ended, done = None, 0
        while done < rollouts:
            count = min(self.rollouts_per_piece(), rollouts - done)
            piece = self.train_round(count)
            ended = piece if ended is None else ended.merged(piece)
            done += count
            self._tick()
            if self.state.seconds >= c.budget_seconds:
                break
        assert ended is not None
        return ended

    def validate(self, candidates: Sequence[Any]) -> Validation:
        """The agent on the validation mazes; its fitness is its mean R̄ there."""
        checked = _play(self.validation, candidates[0])
        return Validation(
            np.array([checked.normalized_reward.mean()]),
            np.array([checked.success.mean()]),
            int(checked.steps.sum()),
        )

    def keep_champion(self, candidates: Sequence[Any], index: int) -> None:
        candidates[index].save(self.champion_file)

    def check_champion(self) -> None:
        """A damaged champion of a resumed run is refused here, by name."""
        if self.champion_file.exists() or self.champion_file.is_symlink():
            self.load_agent(self.champion_file)

    def load_agent(self, path: Path) -> Any:
        """The agent saved at ``path`` (the champion), checked: an SB3 agent here."""
        return SB3Agent.load(path)

    # -- the lifecycle's hooks ------------------------------------------------

    def final_agent(self) -> Any:
        if not self.champion_file.exists():
            raise RLConfigError("the run played no round: it has no champion")
        return self.load_agent(self.champion_file)

    def save_agent(self, agent: SB3Agent, path: Path) -> None:
        agent.save(path)

    def own_figures(self) -> dict[str, Any]:
        s = self.state
        return {
            "framework": self.config.framework,
            "scoring_steps": s.scoring_steps,
            "champion_validation_normalized_reward": s.champion_fitness,
        }


class SB3CoevolutionRun(RLCoevolutionRun):
    """The co-evolution rounds of an SB3 model."""

    state: _State
    state_class = _State
    outputs: ClassVar[tuple[str, ...]] = ("agent.zip", *CoevolutionRun.outputs, "tensorboard/")

    def __init__(self, out: str | os.PathLike, config: TrainConfig) -> None:
        super().__init__(out, config)
        torch.set_num_threads(1)
        self.model: BaseAlgorithm | None = None
        self._env: SB3VecEnv | None = None

    @property
    def rollout(self) -> int:
        return self.n_steps * self.config.n_envs

    @property
    def n_steps(self) -> int:
        assert self.model is not None
        return int(self.model.n_steps)

    def _new_env(self, mazes: list[Maze]) -> SB3VecEnv:
        c = self.config
        return SB3VecEnv(mazes, c.robot, c.n_envs, c.seed)

    def _first_env(self) -> SB3VecEnv:
        """The environment a model is built with: the target's rotations (replaced every round)."""
        return self._new_env(as_mazes(rotations(self.config.target)) * (self.config.n_envs // 4))

    def _tensorboard_dir(self) -> str | None:
        return str(self.out / "tensorboard") if self.config.tensorboard else None

    # -- the framework's part ---------------------------------------------------

    def new_state(self, mazes: MazePopulation) -> _State:
        c = self.config
        self.model = new_sb3_model(
            c.algo, c.robot, self._first_env(), c.seed, c.hyperparameters, self._tensorboard_dir()
        )
        return _State(mazes)

    def state_codec(self) -> StateCodec:
        """The run state and the maze population's classes."""
        return StateCodec([_State, *curriculum_classes()])

    def restore_learner(self, state: CoevolutionState) -> None:
        """The model the state names, and a look at the champion (a damaged one is refused)."""
        assert isinstance(state, _State)
        model_file = named_checkpoint(self, state.model_file)
        self.model = load_sb3_model(
            model_file,
            self.config.algo,
            self.config.robot,
            env=self._first_env(),
            tensorboard_log=self._tensorboard_dir(),
        )
        self.model.num_timesteps = state.steps
        self.check_champion()

    def set_round_mazes(self, mazes: list[Maze]) -> int:
        assert self.model is not None
        self._env = self._new_env(mazes)
        self.model.set_env(self._env)
        return int(np.ceil(self._env.engine.tables.deadline.max()))

    def train_round(self, rollouts: int) -> EndedEpisodes:
        model, env = self.model, self._env
        assert model is not None and env is not None
        episodes = RoundEpisodes(env.num_envs)
        model.learn(
            total_timesteps=rollouts * self.rollout,
            callback=episodes,
            reset_num_timesteps=False,
            tb_log_name="coevolution",
        )
        self.state.steps = int(model.num_timesteps)
        return episodes.ended()

    def agent_now(self) -> SB3Agent:
        assert self.model is not None
        return SB3Agent(self.model, self.config.robot, self.config.algo)

    def round_done(self, row: Mapping[str, Any]) -> None:
        """The round's figures in TensorBoard (``coevolution/<key>``), beside SB3's."""
        assert self.model is not None
        logger = self.model.logger
        for key in TENSORBOARD_KEYS:
            if not np.isnan(row[key]):
                logger.record(f"coevolution/{key}", row[key])
        logger.dump(self.state.steps)

    def save_learner(self) -> None:
        """The model as ``model-<round>.zip``, which the state then names."""
        assert self.model is not None
        self.checkpoints.mkdir(parents=True, exist_ok=True)
        name = f"model-{self.state.round}.zip"
        tmp = self.checkpoints / f".{name}.tmp.zip"
        self.model.save(tmp)
        os.replace(tmp, self.checkpoints / name)
        self.state.model_file = name

    def learner_saved(self) -> None:
        """The models the state no longer names go."""
        for old in self.checkpoints.glob("model-*.zip"):
            if old.name != self.state.model_file:
                old.unlink()


def named_checkpoint(run: CoevolutionRun, name: str) -> Path:
    """The file or folder of ``run``'s checkpoints that its state names, checked to be there."""
    where = f"checkpoint {str(run.checkpoint)!r}"
    path = run.checkpoints / name
    if not name or path.parent != run.checkpoints:
        raise RLConfigError(f"{where} names no model file of its folder")
    if not (path.exists() or path.is_symlink()):
        raise RLConfigError(f"checkpoint file {str(path)!r} is missing")
    return path
