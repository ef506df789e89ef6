"""The direct regime with ``--framework jax``: SB3's A2C/PPO compiled with JAX, same run folder.

:class:`JaxRun` trains a :class:`~rl_baselines.jax.trainer.JaxTrainer` where
:class:`~rl_baselines.train.SB3Run` trains an SB3 model, and writes the same
folder (:mod:`rl_baselines.train`): ``progress.csv`` (the evaluations every
``eval_every`` steps), ``evaluations.csv`` (the anytime evaluations),
``checkpoints/latest/`` (``trainer/``, the whole training state, and
``state.json``, written together by :func:`~amaze.runs.folder.write_folder`),
``checkpoints/champion.zip``, ``agent.zip`` + ``agent.json`` (SB3's format:
:class:`~rl_baselines.jax.agent.JaxAgent`, chosen by the same ``agent_rule``)
and ``summary.json``. No ``tensorboard/`` (the config refuses ``--tensorboard``).
With a ``network`` spec the champion and the agent are evolved agents' files
(``checkpoints/champion.npz``, ``agent.npz``:
:class:`~rl_baselines.jax.agent.NetworkAgent`), and ``summary.json`` records
the network's architecture.

**The loop.** The trainer runs whole rollouts in compiled blocks; a block
ends at every rollout boundary where the SB3 run acts: an evaluation due
(``eval_every``), an anytime evaluation point, the steps budget (whole
rollouts, never past it). So evaluations, checkpoints and anytime points fall
at the same env steps as in an SB3 run of the same config. Two differences:
a run that converges stops at that rollout boundary (SB3 takes one more env
step before it stops), and a seconds budget is checked between blocks of at
most :attr:`~rl_baselines.jax.trainer.JaxTrainer.chunk` rollouts (SB3: at
every env step), so such a run may go past it by one block.

**Resume.** A checkpoint holds the whole training state (parameters,
optimizer, random key, environments), and training is the same bit for bit
however it is cut into blocks: on one machine (CPU), a run killed and
resumed ends with the same agent, bit for bit, as one never interrupted
(SB3 saves neither its random generators nor its environments: there a
resumed run is a faithful continuation, not a replay).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from amaze.agents.robot import as_robot
from amaze.evaluation.protocol import Evaluator
from amaze.maze import rotations
from amaze.maze.maze import as_mazes
from amaze.runs.anytime import Spent
from amaze.runs.folder import settled_folder, write_folder, write_json
from amaze.runs.progress import Progress
from rl_baselines import RLConfigError
from rl_baselines.config import TrainConfig, check_rollout_fits
from rl_baselines.direct import LATEST_FOLDER, DirectRun
from rl_baselines.jax.agent import JaxAgent, NetworkRunFiles
from rl_baselines.jax.hyperparameters import checked_hyperparameters
from rl_baselines.jax.storage import save_trainer
from rl_baselines.jax.trainer import JaxTrainer

__all__ = ["TRAINER_FOLDER", "JaxRun"]

#: The folder of ``checkpoints/latest/`` that holds the saved trainer.
TRAINER_FOLDER = "trainer"


class JaxRun(NetworkRunFiles, DirectRun):
    """The direct regime trained by the JAX learners (see the module docstring)."""

    checkpoint_files = ("latest/trainer/", "latest/state.json")
    #: The files a run may write (those it wrote are listed): an SB3 agent or a network's.
    outputs = ("agent.zip", "agent.npz", "summary.json", "progress.csv")

    def __init__(self, out: str | os.PathLike, config: TrainConfig) -> None:
        super().__init__(out, config)
        self.trainer: JaxTrainer | None = None

    def agent_figures(self) -> dict[str, Any]:
        """The base figures, and the network's architecture when a spec gave it."""
        return {**super().agent_figures(), **self.network_figures()}

    # -- what the framework says ------------------------------------------------------

    @property
    def steps(self) -> int:
        assert self.trainer is not None
        return self.trainer.num_timesteps

    @property
    def rollout(self) -> int:
        assert self.trainer is not None
        return self.trainer.hyperparameters.rollout_size

    def current_model_agent(self) -> JaxAgent:
        assert self.trainer is not None
        return JaxAgent(self.trainer)

    def _mazes(self) -> list[str]:
        """The training mazes' rotations (environment ``k`` plays ``k % len``, as SB3's)."""
        return [rotated for maze in self.config.mazes for rotated in rotations(maze)]

    # -- the lifecycle's hooks ------------------------------------------------------------

    def start(self) -> None:
        """A fresh trainer of the config's algorithm, hyperparameters and seed."""
        c = self.config
        self.trainer = JaxTrainer(
            c.algo,
            c.robot,
            self._mazes(),
            c.hyperparameters,
            seed=c.seed,
            n_envs=c.n_envs,
            network=c.network,
            progress_reward=c.progress_reward,
        )
        check_rollout_fits(c, self.rollout, "learns in whole rollouts")

    def restore(self) -> int | None:
        """The trainer and the evaluation state of the last checkpoint, each checked."""
        latest = settled_folder(self.checkpoints / LATEST_FOLDER)
        trainer_folder, state_file = latest / TRAINER_FOLDER, latest / "state.json"
        present = [f for f in (trainer_folder, state_file) if f.exists() or f.is_symlink()]
        if not present:
            return None
        if len(present) == 1:
            missing = state_file if present[0] == trainer_folder else trainer_folder
            raise RLConfigError(f"checkpoint file {str(missing)!r} is missing")
        steps = self.restore_state(state_file)
        trainer = JaxTrainer.load(trainer_folder)
        c = self.config
        hp = checked_hyperparameters(
            c.algo, c.hyperparameters, robot_images=not as_robot(c.robot).discrete_inputs,
            n_envs=c.n_envs,
        )  # fmt: skip
        expected = {
            "algo": c.algo,
            "robot": c.robot,
            "seed": c.seed,
            "n_envs": c.n_envs,
            "mazes": [maze.to_string() for maze in as_mazes(self._mazes())],
            "hyperparameters": hp.sb3_kwargs(policy=c.network is None),
            "network": c.network,
            "progress_reward": c.progress_reward,
        }
        trainer.check_settings(expected, f"checkpoint {str(trainer_folder)!r}")
        if trainer.num_timesteps != steps:
            raise RLConfigError(
                f"checkpoint file {str(state_file)!r}: num_timesteps {steps} is not the"
                f" {trainer.num_timesteps} of {str(trainer_folder)!r} (of different saves)"
            )
        self.trainer = trainer
        return steps

    def train(self, progress: str) -> None:
        """Train until a budget is spent or the evaluation episodes are all optimal.

        At every block boundary (see the module docstring), as an SB3 run at a
        rollout's start: show the progress, stop if the seconds are spent,
        take the anytime evaluations due, evaluate (and checkpoint) when due.
        """
        c = self.config
        assert self.trainer is not None
        total, unit = (c.budget_steps, "steps")
        if c.budget_steps is None:
            total, unit = c.budget_seconds, "s"
        desc = f"{c.algo} direct seed {c.seed} (jax)"
        evaluator = self.evaluator()
        with Progress(total, unit, desc, mode=progress) as shown:
            while not self.converged and self._budget_rollouts() > 0:
                self._show(shown)
                if self.out_of_time():
                    break
                self.started += self.evaluate_anytime()  # its seconds are not the budget's
                if self.steps == 0 or self.steps - self.last_eval_steps >= c.eval_every:
                    self._evaluate(evaluator)
                if self.converged:
                    break
                self.trainer.run(self._block())
            if self.last_eval_steps != self.steps and not self.converged:
                self._evaluate(evaluator)
            self._show(shown)

    # -- the loop's own -------------------------------------------------------------------

    def _budget_rollouts(self) -> int:
        """Whole rollouts the steps budget still pays (a large number without one)."""
        budget = self.config.budget_steps
        if budget is None:
            return 2**31
        return (budget - self.steps) // self.rollout

    def _block(self) -> int:
        """Rollouts to run now: up to the next boundary where the run acts (>= 1)."""
        assert self.trainer is not None
        c, rollout, steps = self.config, self.rollout, self.steps
        limit = self._budget_rollouts()
        if c.budget_seconds is not None:
            limit = min(limit, self.trainer.chunk)
        due = self.last_eval_steps + c.eval_every
        limit = min(limit, max(1, -(-(due - steps) // rollout)))
        for k in range(1, limit):
            after = steps + k * rollout
            if self.anytime.due(Spent(after, after, 0.0)):
                return k
        return max(1, limit)

    def _evaluate(self, evaluator: Evaluator) -> None:
        """Evaluate the model now, keep it (champion, ``progress.csv``) and checkpoint."""
        agent = self.current_model_agent()
        self.record_evaluation(agent, evaluator.evaluate(agent))
        self.save_checkpoint()

    def _show(self, shown: Progress) -> None:
        steps = self.steps
        done = steps if self.config.budget_steps is not None else self.seconds()
        shown.update(done, steps=f"{steps:,}", **self.best_shown())

    def save_checkpoint(self) -> None:
        """The trainer and the evaluation state, together in ``checkpoints/latest/``, atomically."""
        trainer, state = self.trainer, self.checkpoint_state()
        assert trainer is not None

        def fill(folder: Path) -> None:
            save_trainer(trainer, folder / TRAINER_FOLDER)
            write_json(folder / "state.json", state)

        write_folder(self.checkpoints / LATEST_FOLDER, fill)
