"""Training SB3 A2C/PPO agents in the paper's regimes: the RL trainer of the run lifecycle.

:class:`SB3Run` is the RL trainer of the shared run lifecycle
(:mod:`amaze.runs.lifecycle`: fresh start, resume, final report) for the
**direct** regime; the curriculum regimes (``interpolation``, ``edhucat``)
are handed to :class:`rl_baselines.curriculum.SB3CurriculumRun` (the
curriculum loop with an SB3 learner) by :meth:`SB3Run.run_class_for`, so
:func:`train`, :func:`resume` and ``amaze-train`` take every regime.

The **direct** regime (paper §4): the agent trains on ``mazes`` (default:
:data:`~amaze.evaluation.suite.PAPER_TRAINING_MAZE`) in their 4 rotations
(``n_envs`` is a multiple of 4; each environment cycles through the mazes'
rotations, episode after episode) and is evaluated every ``eval_every`` env
steps on the 4 rotations of each of ``eval_mazes`` (default:
:data:`~amaze.evaluation.suite.PAPER_EVALUATION_MAZE`). Training stops when
the budget is spent (``budget_steps`` env steps and/or ``budget_seconds``
seconds, whichever comes first) or when every evaluation episode is optimal
(paper reward R̄ = 1): the paper's protocol. The agent handed over is chosen
by ``agent_rule``: ``final`` (default: the model when training stopped) or
``best-eval`` (the best evaluated model, by success rate then R̄ on the
evaluation mazes, the earliest on ties); ``summary.json`` says which, and at
how many steps it was found.

A steps budget is spent in whole rollouts (``n_steps x n_envs``), never past
it: a rollout the steps left cannot pay is not started. A seconds budget is the run's training
time over every resumed part (:meth:`SB3Run.seconds`: model building,
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
* ``checkpoints/model.zip`` + ``checkpoints/state.json``: the latest model and the
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
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback

from amaze.evaluation.protocol import Evaluator
from amaze.maze import rotations
from amaze.runs.anytime import Spent
from amaze.runs.config import RunConfig, read_json_object
from amaze.runs.folder import write_json
from amaze.runs.lifecycle import Run, RunResult
from amaze.runs.progress import Progress
from amaze.validation import check_integer, check_number
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent, load_sb3_model
from rl_baselines.config import TrainConfig, check_rollout_fits
from rl_baselines.learner import OPTIMAL, UNLIMITED_STEPS, new_sb3_model
from rl_baselines.vec_env import SB3VecEnv

__all__ = ["SB3Run", "TrainConfig", "resume", "train"]

PROGRESS_FIELDS = ("steps", "seconds", "eval_success_rate", "eval_normalized_reward")


def _checked_state(state: dict[str, Any]) -> dict[str, Any]:
    """``checkpoints/state.json``'s content with every field checked (types and ranges)."""

    def integer(name: str, minimum: int) -> int:
        return check_integer(
            f"checkpoint state {name}", state.get(name), minimum=minimum, error=RLConfigError
        )

    best = state.get("best")
    if best is not None and not (
        isinstance(best, list)
        and len(best) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in best)
    ):
        raise RLConfigError(f"checkpoint state best {best!r} is not null or two numbers")
    if not isinstance(state.get("converged"), bool):
        raise RLConfigError(f"checkpoint state converged {state.get('converged')!r} is not a bool")
    seconds = check_number(
        "checkpoint state seconds", state.get("seconds"), minimum=0, error=RLConfigError
    )
    return {
        "num_timesteps": integer("num_timesteps", 0),
        "seconds": seconds,
        "best": best,
        "converged": state["converged"],
        "last_eval_steps": integer("last_eval_steps", -1),
        # absent in run folders written before agent rules: the evaluation at step 0 is unknown
        "best_steps": integer("best_steps", 0) if "best_steps" in state else 0,
    }


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
        run, model = self.run, self.model
        steps = int(model.num_timesteps)
        agent = SB3Agent(model, run.config.robot, run.config.algo)
        assert self.evaluator is not None
        report = self.evaluator.evaluate(agent)
        summary = report.summary()
        score = (float(summary["success_rate"]), float(summary["normalized_reward"]))
        if run.best is None or score > run.best:
            run.best, run.best_steps = score, steps
            agent.save(run.champion_file)
        run.converged = all(e.normalized_reward >= OPTIMAL for e in report.episodes)
        run.last_eval_steps = steps
        self.logger.record("eval/success_rate", score[0])
        self.logger.record("eval/normalized_reward", score[1])
        self.logger.dump(steps)
        run.progress.append(
            {
                "steps": steps,
                "seconds": round(run.seconds(), 3),
                "eval_success_rate": score[0],
                "eval_normalized_reward": score[1],
            }
        )
        run.save_checkpoint()

    def show(self) -> None:
        """Show the run's progress: its steps (a steps budget) or its seconds."""
        if self.shown is not None:
            run = self.run
            steps = int(self.model.num_timesteps)
            done = steps if run.config.budget_steps is not None else run.seconds()
            best = "n/a" if run.best is None else f"{run.best[0]:.2f}"
            self.shown.update(done, steps=f"{steps:,}", best_eval_success=best)

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


class SB3Run(Run):
    """The RL trainer of the direct regime: SB3 learns, evaluated every ``eval_every`` steps.

    The curriculum regimes run as :class:`~rl_baselines.curriculum.SB3CurriculumRun`
    (:meth:`run_class_for`).
    """

    config_class = TrainConfig
    progress_fields = PROGRESS_FIELDS
    position_field = "steps"
    checkpoint_files = ("model.zip", "state.json")
    outputs = ("agent.zip", "summary.json", "progress.csv", "tensorboard/")
    agent_file = "agent.zip"
    config: TrainConfig

    def __init__(self, out: str | os.PathLike, config: TrainConfig) -> None:
        super().__init__(out, config)
        torch.set_num_threads(1)
        self.model: BaseAlgorithm | None = None
        self.seconds_before = 0.0
        self.best: tuple[float, float] | None = None
        #: Env steps at which the best evaluated model was evaluated.
        self.best_steps = 0
        self.converged = False
        self.last_eval_steps = -1
        self.started = time.monotonic()

    def seconds(self) -> float:
        """Wall-clock seconds of training, over every resumed part of the run."""
        return self.seconds_before + (time.monotonic() - self.started)

    def out_of_time(self) -> bool:
        """True once the run's seconds reach ``budget_seconds`` (never without one)."""
        budget = self.config.budget_seconds
        return budget is not None and self.seconds() >= budget

    def _env(self) -> SB3VecEnv:
        """The training environments: the mazes' rotations, cycled through by the environments."""
        c = self.config
        mazes = [rotated for maze in c.mazes for rotated in rotations(maze)]
        return SB3VecEnv(mazes, c.robot, c.n_envs, c.seed)

    @property
    def champion_file(self) -> Path:
        """The best evaluated model so far (``champion.zip`` at the top in older run folders)."""
        legacy = self.out / "champion.zip"
        return legacy if legacy.exists() else self.checkpoints / "champion.zip"

    def _tensorboard_dir(self) -> str | None:
        return str(self.out / "tensorboard") if self.config.tensorboard else None

    # -- the lifecycle's hooks --------------------------------------------------

    @classmethod
    def run_class_for(cls, config: RunConfig) -> type[Run]:
        """:class:`SB3CurriculumRun` for the curriculum regimes, :class:`SB3CoevolutionRun`
        for coevolution, this class for direct."""
        if getattr(config, "is_curriculum", False):
            from rl_baselines.curriculum import SB3CurriculumRun

            return SB3CurriculumRun
        if getattr(config, "regime", None) == "coevolution":
            from rl_baselines.coevolution import SB3CoevolutionRun

            return SB3CoevolutionRun
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
        model_file, state_file = self.checkpoints / "model.zip", self.checkpoints / "state.json"
        present = [f for f in (model_file, state_file) if f.exists() or f.is_symlink()]
        if not present:
            return None
        if len(present) == 1:
            missing = state_file if present[0] == model_file else model_file
            raise RLConfigError(f"checkpoint file {str(missing)!r} is missing")
        data = read_json_object(state_file, RLConfigError, "checkpoint file")
        try:
            state = _checked_state(data)
        except RLConfigError as problem:
            raise RLConfigError(f"checkpoint file {str(state_file)!r}: {problem}") from None
        self.check_config_digest(data.get("config_sha256"), f"checkpoint file {str(state_file)!r}")
        self.model = load_sb3_model(
            model_file,
            self.config.algo,
            self.config.robot,
            env=self._env(),
            tensorboard_log=self._tensorboard_dir(),
        )
        champion = [self.champion_file, self.champion_file.with_suffix(".json")]
        if any(f.exists() or f.is_symlink() for f in champion):
            SB3Agent.load(champion[0])  # a damaged champion is refused here, by name
        self.seconds_before = state["seconds"]
        self.best = tuple(state["best"]) if state["best"] is not None else None
        self.best_steps = state["best_steps"]
        self.converged = state["converged"]
        self.last_eval_steps = state["last_eval_steps"]
        self.started = time.monotonic()
        self.model.num_timesteps = state["num_timesteps"]
        return self.model.num_timesteps

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
            mazes = [rotated for maze in config.eval_mazes for rotated in rotations(maze)]
            callback.evaluator = Evaluator(config.robot, mazes=mazes, inputs=False)
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

    def spent(self) -> Spent:
        assert self.model is not None
        steps = int(self.model.num_timesteps)
        return Spent(steps, steps, self.seconds())

    def final_agent(self) -> SB3Agent:
        """The model when training stopped, or the best evaluated one (``agent_rule``)."""
        assert self.model is not None
        if self.config.agent_rule == "best-eval":
            return SB3Agent.load(self.champion_file)
        return SB3Agent(self.model, self.config.robot, self.config.algo)

    def save_agent(self, agent: SB3Agent, path: Path) -> None:
        agent.save(path)

    def agent_figures(self) -> dict[str, Any]:
        assert self.model is not None
        c = self.config
        steps = self.best_steps if c.agent_rule == "best-eval" else int(self.model.num_timesteps)
        return {"agent_rule": c.agent_rule, "agent_steps": steps, "agent_untrained": steps == 0}

    def stop_reason(self) -> str:
        assert self.model is not None
        c, steps = self.config, int(self.model.num_timesteps)
        if self.converged:
            return f"converged: every evaluation episode optimal (R̄ = 1) at {steps:,} env steps"
        if c.budget_steps is not None and c.budget_steps - steps < self.rollout:
            return (
                f"the {c.budget_steps - steps:,} steps left cannot pay another rollout"
                f" ({self.rollout:,} steps)"
            )
        return ""

    def figures(self) -> dict[str, Any]:
        assert self.model is not None
        c = self.config
        return {
            "env_steps": int(self.model.num_timesteps),
            "seconds": round(self.seconds(), 3),
            "budget_steps": c.budget_steps,
            "budget_seconds": c.budget_seconds,
            "converged": self.converged,
            "algo": c.algo,
            "regime": c.regime,
            "robot": c.robot,
            "seed": c.seed,
        }

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        """The agent in the 4 rotations of the first evaluation maze."""
        mazes = rotations(self.config.eval_mazes[0])
        return [(f"evaluation-rotation-{index}", maze) for index, maze in enumerate(mazes)]

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        regime = f"{summary['algo']} {summary['regime']}"
        return f"{regime}, converged {summary['converged']}: {super().headline(summary)}"

    # -- RL's own -------------------------------------------------------------------

    def save_checkpoint(self) -> None:
        """The model and the evaluation state, each written atomically."""
        assert self.model is not None
        self.checkpoints.mkdir(parents=True, exist_ok=True)
        tmp = self.checkpoints / ".model.tmp.zip"
        self.model.save(tmp)
        os.replace(tmp, self.checkpoints / "model.zip")
        write_json(
            self.checkpoints / "state.json",
            {
                "num_timesteps": int(self.model.num_timesteps),
                "seconds": self.seconds(),
                "best": list(self.best) if self.best is not None else None,
                "best_steps": self.best_steps,
                "converged": self.converged,
                "last_eval_steps": self.last_eval_steps,
                "config_sha256": self.config_digest,
            },
        )


def train(
    config: TrainConfig | Mapping[str, Any], out: str | os.PathLike, *, progress: str = "off"
) -> RunResult:
    """Train a fresh agent as ``config`` says and write the run folder ``out``.

    ``progress`` shows it (``bar``, ``lines`` or ``off``). Every regime: the curriculum ones
    run as :class:`~rl_baselines.curriculum.SB3CurriculumRun`.
    """
    return SB3Run.fresh(config, out, progress=progress)


def resume(out: str | os.PathLike, *, progress: str = "off") -> RunResult:
    """Continue the run in ``out`` from its latest checkpoint (same config, remaining budget)."""
    return SB3Run.resume(out, progress=progress)
