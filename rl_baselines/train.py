"""Training SB3 A2C/PPO agents in the paper's regimes: the RL trainer of the run lifecycle.

:class:`SB3Run` is the RL trainer of the shared run lifecycle
(:mod:`amaze.runs.lifecycle`: fresh start, resume, final report) for the
**direct** regime; the curriculum regimes (``interpolation``, ``edhucat``)
are handed to :class:`rl_baselines.curriculum.SB3CurriculumRun` (the
curriculum loop with an SB3 learner) by :meth:`SB3Run.run_class_for`, so
:func:`train`, :func:`resume` and ``amaze-train`` take every regime.
With ``framework`` ``jax`` the same regimes train with SB3's algorithms
compiled with JAX: :class:`rl_baselines.jax.run.JaxRun` (direct),
:class:`rl_baselines.curriculum.JaxCurriculumRun` and
:class:`rl_baselines.jax.coevolution.JaxCoevolutionRun`; what both direct runs
share is :class:`rl_baselines.direct.DirectRun`.

The **direct** regime (paper §4): the agent trains on ``mazes`` (default:
:data:`~amaze.evaluation.suite.PAPER_TRAINING_MAZE`) in their 4 rotations
(``n_envs`` is a multiple of 4; each environment cycles through the mazes'
rotations, episode after episode) and is evaluated every ``eval_every`` env
steps on the 4 rotations of each of ``eval_mazes`` (default:
:data:`~amaze.evaluation.suite.PAPER_EVALUATION_MAZE`). Training stops when
the budget is spent (``budget_steps`` env steps and/or ``budget_seconds``
seconds, whichever comes first) or when every evaluation episode is optimal
(paper reward R̄ = 1): the paper's protocol. The agent handed over is chosen
by ``agent_rule``: ``final`` (default: the model when training stopped),
``best-eval`` (the best evaluated model, by success rate then R̄ on the
evaluation mazes, the earliest on ties) or ``best-eval-reward`` (by R̄ alone,
never the untrained model: SB3's ``EvalCallback`` best model, what
``--protocol paper-code`` uses); ``summary.json`` says which, and at
how many steps it was found.

A steps budget is spent in whole rollouts (``n_steps x n_envs``), never past
it: a rollout the steps left cannot pay is not started. A seconds budget is the run's training
time over every resumed part (:meth:`~rl_baselines.direct.DirectRun.seconds`: model building,
rollouts, SB3's updates, evaluations and checkpoints); learning stops at the
first env step that finds it spent, and the rollout then in progress is not
learned from (nor is an evaluation due at a rollout start made then); the
final agent is evaluated as always. Where such a run stops depends on the
machine's speed, so it does not replay, nor resume, bit-identically.
``summary.json`` reports the steps and seconds actually spent.

Run folder (``out``):

* ``config.json``: the :class:`TrainConfig` (enough to resume);
* ``progress.csv``: one row per evaluation: ``steps, seconds, eval_success_rate,
  eval_normalized_reward``;
* ``checkpoints/latest/model.zip`` + ``state.json``: the latest model and the
  step counter, time spent and evaluation state, each written atomically;
* ``checkpoints/champion.zip`` + ``.json``: the best agent on the evaluation mazes so far;
* ``agent.zip`` + ``agent.json``: the agent the run hands over (``agent_rule``);
* ``summary.json``: that agent on the standard evaluation suite
  (``success_rate``, ``normalized_reward``, ``input_recognition``...) and the
  budget spent (``env_steps``, ``seconds``);
* ``trajectories/``: PNGs of the agent in the 4 rotations of the first evaluation maze;
* ``tensorboard/``: SB3's TensorBoard logs (losses, episode returns) and the
  evaluations (``eval/success_rate``, ``eval/normalized_reward``), in ``direct_0``;
  ``tensorboard --logdir OUT/tensorboard``.

Evaluations (and checkpoints) happen at the first rollout boundary at least
``eval_every`` steps after the previous one, and once more at the end.
Checkpoints are taken at the start of a rollout (after the previous one has
been trained on), so a resumed run continues with exactly the steps already
learned from; the unfinished rollout of a killed run is redone. SB3 does not
save its random generators' states nor the rollout in progress, so a resumed
run is a faithful continuation, not a bit-identical replay.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback

from amaze.evaluation.protocol import Evaluator
from amaze.maze import rotations
from amaze.runs.config import RunConfig
from amaze.runs.folder import settled_folder, write_folder, write_json
from amaze.runs.lifecycle import Run, RunResult
from amaze.runs.progress import Progress
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent, load_sb3_model
from rl_baselines.config import TrainConfig, check_rollout_fits
from rl_baselines.direct import LATEST_FOLDER, PROGRESS_FIELDS, DirectRun
from rl_baselines.learner import UNLIMITED_STEPS, new_sb3_model
from rl_baselines.vec_env import SB3VecEnv

__all__ = ["LATEST_FOLDER", "PROGRESS_FIELDS", "SB3Run", "TrainConfig", "resume", "train"]


class _EvaluationCallback(BaseCallback):
    """Every ``eval_every`` steps, at the start of a rollout: evaluate, log, checkpoint.

    Stops training (at the next step) once every evaluation episode is
    optimal, and at the first step that finds the seconds budget spent.
    ``shown``, when given, shows the run's progress at every rollout start.
    """

    def __init__(self, run: SB3Run, shown: Progress | None = None) -> None:
        super().__init__(verbose=0)
        self.run = run
        self.shown = shown
        self.evaluator: Evaluator | None = None

    def evaluate_now(self) -> None:
        """Evaluate the current model, update the champion, log and checkpoint."""
        run = self.run
        agent = run.current_model_agent()
        assert self.evaluator is not None
        score = run.record_evaluation(agent, self.evaluator.evaluate(agent))
        self.logger.record("eval/success_rate", score[0])
        self.logger.record("eval/normalized_reward", score[1])
        self.logger.dump(run.steps)
        run.save_checkpoint()

    def show(self) -> None:
        """Show the run's progress: its steps (a steps budget) or its seconds."""
        if self.shown is not None:
            run = self.run
            steps = int(self.model.num_timesteps)
            done = steps if run.config.budget_steps is not None else run.seconds()
            self.shown.update(done, steps=f"{steps:,}", **run.best_shown())

    def _on_rollout_start(self) -> None:
        self.show()
        if self.run.out_of_time():
            return  # learning stops at the next step; the final evaluation follows
        self.run.started += self.run.evaluate_anytime()  # its seconds are not the budget's
        steps = int(self.model.num_timesteps)
        if steps == 0 or steps - self.run.last_eval_steps >= self.run.config.eval_every:
            self.evaluate_now()

    def _on_step(self) -> bool:
        return not self.run.converged and not self.run.out_of_time()


class SB3Run(DirectRun):
    """The RL trainer of the direct regime: SB3 learns, evaluated every ``eval_every`` steps.

    The curriculum regimes run as :class:`~rl_baselines.curriculum.SB3CurriculumRun`,
    a ``--framework jax`` run as :class:`~rl_baselines.jax.run.JaxRun`
    (:meth:`run_class_for`).
    """

    checkpoint_files = ("latest/model.zip", "latest/state.json")
    outputs = ("agent.zip", "summary.json", "progress.csv", "tensorboard/")

    def __init__(self, out: str | os.PathLike, config: TrainConfig) -> None:
        super().__init__(out, config)
        torch.set_num_threads(1)
        self.model: BaseAlgorithm | None = None

    @property
    def steps(self) -> int:
        assert self.model is not None
        return int(self.model.num_timesteps)

    def current_model_agent(self) -> SB3Agent:
        assert self.model is not None
        return SB3Agent(self.model, self.config.robot, self.config.algo)

    def _env(self) -> SB3VecEnv:
        """The training environments: the mazes' rotations, cycled through by the environments."""
        c = self.config
        mazes = [rotated for maze in c.mazes for rotated in rotations(maze)]
        return SB3VecEnv(mazes, c.robot, c.n_envs, c.seed)

    def _tensorboard_dir(self) -> str | None:
        return str(self.out / "tensorboard") if self.config.tensorboard else None

    # -- the lifecycle's hooks --------------------------------------------------

    @classmethod
    def run_class_for(cls, config: RunConfig) -> type[Run]:
        """The run of the config's framework and regime.

        SB3: :class:`SB3CurriculumRun` for the curriculum regimes,
        :class:`SB3CoevolutionRun` for coevolution, this class for direct.
        JAX (``framework`` jax): :class:`~rl_baselines.curriculum.JaxCurriculumRun`,
        :class:`~rl_baselines.jax.coevolution.JaxCoevolutionRun`,
        :class:`~rl_baselines.jax.edens_populations.JaxEdensPopulationsRun` (the only
        framework of edens-populations) or :class:`~rl_baselines.jax.run.JaxRun`.
        """
        jax = getattr(config, "framework", "sb3") == "jax"
        if getattr(config, "is_curriculum", False):
            from rl_baselines.curriculum import JaxCurriculumRun, SB3CurriculumRun

            return JaxCurriculumRun if jax else SB3CurriculumRun
        if getattr(config, "regime", None) == "edens-populations":
            from rl_baselines.jax.edens_populations import JaxEdensPopulationsRun

            return JaxEdensPopulationsRun  # the config refuses SB3 here
        if getattr(config, "regime", None) == "coevolution":
            if jax:
                from rl_baselines.jax.coevolution import JaxCoevolutionRun

                return JaxCoevolutionRun
            from rl_baselines.coevolution import SB3CoevolutionRun

            return SB3CoevolutionRun
        if jax:
            from rl_baselines.jax.run import JaxRun

            return JaxRun
        return cls

    def start(self) -> None:
        """A fresh SB3 model: SB3's default hyperparameters unless the config overrides them."""
        c = self.config
        self.model = new_sb3_model(
            c.algo, c.robot, self._env(), c.seed, c.hyperparameters, self._tensorboard_dir()
        )
        check_rollout_fits(c, self.rollout, "learns in whole rollouts")

    @property
    def rollout(self) -> int:
        """Env steps of one rollout (``n_steps x n_envs``): the smallest unit of training."""
        assert self.model is not None
        return int(self.model.n_steps) * self.config.n_envs

    def restore(self) -> int | None:
        """The SB3 model and the evaluation state of the last checkpoint, checked."""
        latest = settled_folder(self.checkpoints / LATEST_FOLDER)
        if not latest.exists() and (self.checkpoints / "model.zip").exists():
            latest = self.checkpoints  # a run folder written before checkpoints were one folder
        model_file, state_file = latest / "model.zip", latest / "state.json"
        present = [f for f in (model_file, state_file) if f.exists() or f.is_symlink()]
        if not present:
            return None
        if len(present) == 1:
            missing = state_file if present[0] == model_file else model_file
            raise RLConfigError(f"checkpoint file {str(missing)!r} is missing")
        steps = self.restore_state(state_file)
        self.model = load_sb3_model(
            model_file,
            self.config.algo,
            self.config.robot,
            env=self._env(),
            tensorboard_log=self._tensorboard_dir(),
        )
        self.model.num_timesteps = steps
        return steps

    def train(self, progress: str) -> None:
        """Train until a budget is spent or the evaluation episodes are all optimal.

        The progress shown counts steps; a run without a step limit shows the
        seconds spent instead.
        """
        config, model = self.config, self.model
        assert model is not None
        total, unit = (config.budget_steps, "steps")
        if config.budget_steps is None:
            total, unit = config.budget_seconds, "s"
        desc = f"{config.algo} direct seed {config.seed}"
        with Progress(total, unit, desc, mode=progress) as shown:
            callback = _EvaluationCallback(self, shown)
            callback.evaluator = self.evaluator()
            remaining = UNLIMITED_STEPS
            if config.budget_steps is not None:  # whole rollouts, never past the budget
                left = config.budget_steps - int(model.num_timesteps)
                remaining = left // self.rollout * self.rollout
            if remaining > 0 and not self.converged and not self.out_of_time():
                model.learn(
                    total_timesteps=remaining,
                    callback=callback,
                    reset_num_timesteps=False,
                    tb_log_name="direct",
                )
            # A converged run stopped one step after its last evaluation, before any
            # training on it: the model evaluated is the final one, so no second row.
            if self.last_eval_steps != int(model.num_timesteps) and not self.converged:
                callback.init_callback(model)
                callback.evaluate_now()
            callback.init_callback(model)
            callback.show()

    # -- RL's own -------------------------------------------------------------------

    def save_checkpoint(self) -> None:
        """The model and the evaluation state, together in ``checkpoints/latest/``, atomically.

        One folder written whole (:func:`~amaze.runs.folder.write_folder`): a
        kill between the two files cannot leave a model without its state or
        with another checkpoint's.
        """
        assert self.model is not None
        model = self.model
        state = self.checkpoint_state()

        def fill(folder: Path) -> None:
            model.save(folder / "model.zip")
            write_json(folder / "state.json", state)

        write_folder(self.checkpoints / LATEST_FOLDER, fill)
        for legacy in ("model.zip", "state.json"):  # what a run of an older version left
            (self.checkpoints / legacy).unlink(missing_ok=True)


def train(
    config: TrainConfig | Mapping[str, Any], out: str | os.PathLike, *, progress: str = "off"
) -> RunResult:
    """Train a fresh agent as ``config`` says and write the run folder ``out``.

    Every regime: the curriculum ones run as
    :class:`~rl_baselines.curriculum.SB3CurriculumRun`.

    Args:
        config: the run's config (the keys of ``amaze-train``'s ``config.json``).
        out: the run folder to create (new or empty).
        progress: ``bar``, ``lines`` or ``off``.

    Returns:
        The run's result (its folder, summary, headline and outputs).
    """
    return SB3Run.fresh(config, out, progress=progress)


def resume(out: str | os.PathLike, *, progress: str = "off") -> RunResult:
    """Continue the run in ``out`` from its latest checkpoint (same config, remaining budget)."""
    return SB3Run.resume(out, progress=progress)
